#include "flatland/storage/curve_storage.hpp"

#include "flatland/base/quadrature.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>

namespace flatland {

const char* to_string(BasisKind kind) {
  switch (kind) {
    case BasisKind::Constant: return "constant";
    case BasisKind::Linear: return "linear";
    case BasisKind::Cubic: return "cubic";
    case BasisKind::Hermite: return "hermite";
  }
  return "?";
}

std::optional<BasisKind> basis_from_string(std::string_view name) {
  for (BasisKind kind : {BasisKind::Constant, BasisKind::Linear, BasisKind::Cubic, BasisKind::Hermite})
    if (name == to_string(kind)) return kind;
  return std::nullopt;
}

int SplineBasis::multiplicity(int degree, Continuity continuity) {
  // Multiplicity m at a knot leaves C^(degree - m) continuity: m = degree - c, clamped to what a
  // spline of this degree can express (a constant spline jumps at every knot).
  const int c = static_cast<int>(continuity);
  return std::clamp(degree - c, 1, degree + 1);
}

SplineBasis::SplineBasis(int degree, double u_begin, double u_end, std::span<const MeshNode> nodes)
    : degree_(degree) {
  assert(degree >= 0 && degree <= kMaxDegree && u_begin < u_end);
  knots_.assign(static_cast<std::size_t>(degree + 1), u_begin);
  for (const MeshNode& node : nodes) {
    assert(node.u > u_begin && node.u < u_end);
    knots_.insert(knots_.end(), static_cast<std::size_t>(multiplicity(degree, node.continuity)),
                  node.u);
  }
  knots_.insert(knots_.end(), static_cast<std::size_t>(degree + 1), u_end);
  size_ = knots_.size() - static_cast<std::size_t>(degree) - 1;
  build_span_grid();
}

SplineBasis SplineBasis::periodic(int degree, double u_begin, double u_end,
                                  std::span<const MeshNode> nodes, Continuity closing) {
  assert(degree >= 0 && degree <= kMaxDegree && u_begin < u_end && closing != Continuity::Jump);
  // One period of knots: the closing knot u_begin with its multiplicity, then the nodes.
  std::vector<double> period(static_cast<std::size_t>(multiplicity(degree, closing)), u_begin);
  for (const MeshNode& node : nodes) {
    assert(node.u > u_begin && node.u < u_end);
    period.insert(period.end(), static_cast<std::size_t>(multiplicity(degree, node.continuity)), node.u);
  }
  const auto count = static_cast<std::ptrdiff_t>(period.size());
  assert(count >= degree + 1);
  const double length = u_end - u_begin;
  // Extended: knots[e] = period[(e - p) mod K] shifted by whole periods, e = 0 .. K + 2p, with
  // knots[K + p] set to u_end exactly.
  SplineBasis basis;
  basis.degree_ = degree;
  basis.periodic_ = true;
  basis.size_ = period.size();
  for (std::ptrdiff_t e = 0; e <= count + 2 * degree; ++e) {
    const std::ptrdiff_t i = e - degree;
    const std::ptrdiff_t lap = i < 0 ? -1 : i / count;
    const double knot = period[static_cast<std::size_t>(i - lap * count)];
    basis.knots_.push_back(knot + static_cast<double>(lap) * length);
  }
  for (std::size_t e = static_cast<std::size_t>(count + degree); e < basis.knots_.size(); ++e)
    if (basis.knots_[e] <= u_end) basis.knots_[e] = u_end;  // the closing knot's copies
  basis.build_span_grid();
  return basis;
}

double wrap_into_period(double u, double begin, double end) {
  if (u >= begin && u < end) return u;
  const double length = end - begin;
  const double wrapped = u - std::floor((u - begin) / length) * length;
  return wrapped >= begin && wrapped < end ? wrapped : begin;  // rounding at the seam, or NaN
}

double SplineBasis::wrap(double u) const {
  return periodic_ ? wrap_into_period(u, u_begin(), u_end()) : std::clamp(u, u_begin(), u_end());
}

void SplineBasis::build_span_grid() {
  // The span holding x by bisection, as find_span did before the grid.
  const std::size_t p = static_cast<std::size_t>(degree_);
  const std::size_t last = end_span();
  auto bisect = [&](double x) {
    if (x >= knots_[last]) return last - 1;
    if (x <= knots_[p] && !periodic_) return p;
    const auto it = std::upper_bound(knots_.begin() + static_cast<std::ptrdiff_t>(p),
                                     knots_.begin() + static_cast<std::ptrdiff_t>(last) + 1, x);
    return static_cast<std::size_t>(it - knots_.begin()) - 1;
  };
  const double begin = u_begin();
  const double extent = u_end() - begin;
  const auto units = static_cast<std::size_t>(std::max(1.0, std::ceil(extent)));
  unit_cells_.assign(units + 1, 0);
  cell_spans_.clear();
  for (std::size_t m = 0; m < units; ++m) {
    const double lo = begin + static_cast<double>(m);
    const double hi = std::min(lo + 1.0, u_end());
    const std::size_t spans = bisect(std::nextafter(hi, lo)) - bisect(lo) + 1;
    const std::size_t cells = 2 * spans;
    unit_cells_[m] = static_cast<std::uint32_t>(cell_spans_.size());
    for (std::size_t c = 0; c < cells; ++c)
      cell_spans_.push_back(static_cast<std::uint32_t>(
          bisect(lo + static_cast<double>(c) / static_cast<double>(cells))));
  }
  unit_cells_[units] = static_cast<std::uint32_t>(cell_spans_.size());
}

std::size_t SplineBasis::find_span(double u) const {
  // The span i with knots[i] <= u < knots[i+1], among i in [first_span, end_span); u at the very
  // end of a clamped basis belongs to the last non-empty span.
  const std::size_t p = static_cast<std::size_t>(degree_);
  const std::size_t last = end_span();
  if (u >= knots_[last]) return last - 1;
  // Clamped, the first span is never empty; periodic, the closing knot's copies may follow it.
  if (u <= knots_[p] && !periodic_) return p;
  // The grid's cell holding u gives the span at the cell's lower edge (<= u); the span holding u
  // is the last one from there whose start is <= u (a NaN stays at the first cell).
  const double x = u - u_begin();
  const std::size_t units = unit_cells_.size() - 1;
  const std::size_t m = x >= 1.0 ? std::min(static_cast<std::size_t>(x), units - 1) : 0;
  const std::size_t first_cell = unit_cells_[m];
  const std::size_t cells = unit_cells_[m + 1] - first_cell;
  const double f = (x - static_cast<double>(m)) * static_cast<double>(cells);
  const std::size_t cell = f > 0.0 ? std::min(static_cast<std::size_t>(f), cells - 1) : 0;
  std::size_t span = cell_spans_[first_cell + cell];
  while (span > p && knots_[span] > u) --span;  // u rounded into the cell below its edge
  // A few steps forward; a cell crowded with knots (nodes graded towards a point) bisects the rest.
  for (int step = 0; step < 8 && span + 1 < last && knots_[span + 1] <= u; ++step) ++span;
  if (span + 1 < last && knots_[span + 1] <= u) {
    const auto it = std::upper_bound(knots_.begin() + static_cast<std::ptrdiff_t>(span) + 1,
                                     knots_.begin() + static_cast<std::ptrdiff_t>(last), u);
    span = static_cast<std::size_t>(it - knots_.begin()) - 1;
  }
  return span;
}

std::size_t SplineBasis::evaluate(double u, double* values) const {
  if (periodic_) u = wrap(u);
  const std::size_t span = find_span(u);
  evaluate_in_span(span, u, values);
  return span - static_cast<std::size_t>(degree_);
}

namespace {

// The recursion for a known degree: unrolled, on locals (kept in registers rather than behind
// the caller's pointer); the same operations in the same order as a loop over the degree.
template <int P>
void cox_de_boor(const double* knots, std::size_t span, double u, double* values) {
  std::array<double, P + 1> phi{};
  std::array<double, P + 1> left{};
  std::array<double, P + 1> right{};
  phi[0] = 1.0;
  for (int j = 1; j <= P; ++j) {
    left[j] = u - knots[span + 1 - static_cast<std::size_t>(j)];
    right[j] = knots[span + static_cast<std::size_t>(j)] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      const double temp = phi[r] / (right[r + 1] + left[j - r]);
      phi[r] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    phi[j] = saved;
  }
  for (int r = 0; r <= P; ++r) values[r] = phi[r];
}

}  // namespace

void SplineBasis::evaluate_in_span(std::size_t span, double u, double* values) const {
  assert(span >= static_cast<std::size_t>(degree_) && span + static_cast<std::size_t>(degree_) < knots_.size());
  // Cox-de Boor recursion in the triangular form of Piegl and Tiller (The NURBS Book, A2.2):
  // builds the nonzero functions of degree j from those of degree j-1 without division by zero,
  // since only non-empty spans are visited.
  static_assert(kMaxDegree == 3);
  switch (degree_) {
    case 0: values[0] = 1.0; return;
    case 1: return cox_de_boor<1>(knots_.data(), span, u, values);
    case 2: return cox_de_boor<2>(knots_.data(), span, u, values);
    default: return cox_de_boor<3>(knots_.data(), span, u, values);
  }
}

namespace {

// Visits every quadrature point of the curve's storage mesh: four 8-point Gauss-Legendre panels
// per non-empty knot span of [u_begin, u_end) (each span lies in one segment), with the arc-length
// weight w = GL weight x |C'(u)| du and the basis functions alive there (values[j] for function
// index[j], j = 0..degree; distinct, as a periodic basis has at least degree + 1 functions), and
// the span k (function index[j] is function k - degree + j of the extended numbering, whose
// support starts at knots[k - degree + j]). Integrals of phi_k times smooth functions along arc
// length are sums over these points.
template <typename Visit>
void for_each_quadrature_point(const Scene& scene, const Curve& curve, const SplineBasis& basis,
                               Visit visit) {
  constexpr int kPanels = 4;
  const std::vector<double>& knots = basis.knots();
  const int p = basis.degree();
  std::array<double, SplineBasis::kMaxDegree + 1> values{};
  std::array<std::size_t, SplineBasis::kMaxDegree + 1> index{};
  for (std::size_t k = basis.first_span(); k < basis.end_span(); ++k) {
    const double a = knots[k];
    const double b = knots[k + 1];
    if (!(b > a)) continue;
    const auto segment_index = static_cast<std::uint32_t>(
        std::min<double>(std::floor(0.5 * (a + b)), curve.segment_count - 1));
    const SceneSegment& segment = scene.segments[curve.first_segment + segment_index];
    for (int j = 0; j <= p; ++j)
      index[static_cast<std::size_t>(j)] = basis.index(k - static_cast<std::size_t>(p) + static_cast<std::size_t>(j));
    for (int panel = 0; panel < kPanels; ++panel) {
      const double pa = a + (b - a) * panel / kPanels;
      const double pb = a + (b - a) * (panel + 1) / kPanels;
      const double half = 0.5 * (pb - pa);
      for (std::size_t g = 0; g < gauss::kNodes8.size(); ++g) {
        const double u = 0.5 * (pa + pb) + half * gauss::kNodes8[g];
        const double weight =
            gauss::kWeights8[g] * half * length(derivative(segment.geometry.shape, u - segment_index));
        basis.evaluate_in_span(k, u, values.data());
        visit(u, weight, index, values, k);
      }
    }
  }
}

}  // namespace

BasisSampler::BasisSampler(const SplineBasis& basis) {
  // phi_k on each span is a polynomial of degree <= 3 in x = (u - u0) / width; interpolating it at
  // four interior points recovers it exactly (up to rounding), also at spans that end in a jump.
  constexpr std::array<double, 4> kNodes = {0.125, 0.375, 0.625, 0.875};
  const std::vector<double>& knots = basis.knots();
  const int p = basis.degree();
  const auto pu = static_cast<std::size_t>(p);
  first_piece_.assign(basis.size() + 1, 0);
  periodic_ = basis.is_periodic();
  degree_ = p;
  knots_ = knots;
  u_begin_ = basis.u_begin();
  u_end_ = basis.u_end();

  // The power form solves the 4x4 Vandermonde system of the nodes, the same matrix for every
  // piece: its elimination (partial pivoting) is done once here, and each piece's values go
  // through the same row exchanges and the same multipliers.
  std::array<std::array<double, 4>, 4> matrix{};
  for (std::size_t row = 0; row < 4; ++row) {
    double power = 1.0;
    for (std::size_t col = 0; col < 4; ++col, power *= kNodes[row]) matrix[row][col] = power;
  }
  std::array<std::size_t, 4> pivots{};
  std::array<std::array<double, 4>, 4> factors{};  // factors[col][row], row > col
  for (std::size_t col = 0; col < 4; ++col) {
    std::size_t pivot = col;
    for (std::size_t row = col + 1; row < 4; ++row)
      if (std::fabs(matrix[row][col]) > std::fabs(matrix[pivot][col])) pivot = row;
    pivots[col] = pivot;
    std::swap(matrix[col], matrix[pivot]);
    for (std::size_t row = col + 1; row < 4; ++row) {
      const double factor = matrix[row][col] / matrix[col][col];
      factors[col][row] = factor;
      for (std::size_t c = col; c < 4; ++c) matrix[row][c] -= factor * matrix[col][c];
    }
  }

  // The values of every function alive on a span at the four nodes, once per span (each span
  // carries p + 1 functions). On a periodic basis the first p spans (before u_begin) are
  // evaluated a period later, as span + K, where the recursion has the p knots it reads on the left.
  const std::size_t spans = basis.size() + pu;
  // Scratch kept by each thread: a scene of many short curves builds a sampler per curve.
  thread_local std::vector<std::array<std::array<double, SplineBasis::kMaxDegree + 1>, 4>> at_nodes;
  at_nodes.resize(spans);
  for (std::size_t span = 0; span < spans; ++span) {
    const double u0 = knots[span];
    const double width = knots[span + 1] - u0;
    if (!(width > 0.0)) continue;
    for (std::size_t row = 0; row < 4; ++row) {
      const double x = kNodes[row];
      if (span < pu)
        basis.evaluate_in_span(span + basis.size(), u0 + x * width + (basis.u_end() - basis.u_begin()),
                               at_nodes[span][row].data());
      else
        basis.evaluate_in_span(span, u0 + x * width, at_nodes[span][row].data());
    }
  }

  std::size_t count = 0;  // the pieces, to allocate them once
  for (std::size_t k = 0; k < basis.size(); ++k)
    for (std::size_t span = k; span <= k + pu; ++span) count += knots[span + 1] > knots[span] ? 1 : 0;
  pieces_.reserve(count);
  cumulative_.reserve(count);
  for (std::size_t k = 0; k < basis.size(); ++k) {
    first_piece_[k] = static_cast<std::uint32_t>(pieces_.size());
    double cumulative = 0.0;
    for (std::size_t span = k; span <= k + pu; ++span) {
      const double u0 = knots[span];
      const double width = knots[span + 1] - u0;
      if (!(width > 0.0)) continue;
      // Function k is function k - (span - p) of this span (spans k .. k + p carry it).
      std::array<double, 4> rhs{};
      for (std::size_t row = 0; row < 4; ++row) rhs[row] = at_nodes[span][row][k + pu - span];
      for (std::size_t col = 0; col < 4; ++col) {
        std::swap(rhs[col], rhs[pivots[col]]);
        for (std::size_t row = col + 1; row < 4; ++row) rhs[row] -= factors[col][row] * rhs[col];
      }
      Piece piece;
      piece.u0 = u0;
      piece.width = width;
      for (std::size_t row = 4; row-- > 0;) {
        double sum = rhs[row];
        for (std::size_t c = row + 1; c < 4; ++c) sum -= matrix[row][c] * piece.power[c];
        piece.power[row] = sum / matrix[row][row];
      }
      const auto& a = piece.power;
      for (int j = 0; j <= kTable; ++j) {
        const double x = static_cast<double>(j) / kTable;
        piece.table[static_cast<std::size_t>(j)] = x * (a[0] + x * (a[1] / 2 + x * (a[2] / 3 + x * (a[3] / 4))));
      }
      cumulative += width * (a[0] + a[1] / 2 + a[2] / 3 + a[3] / 4);
      cumulative_.push_back(cumulative);
      pieces_.push_back(piece);
    }
  }
  first_piece_[basis.size()] = static_cast<std::uint32_t>(pieces_.size());
}

double BasisSampler::mass(std::size_t k) const { return cumulative_[first_piece_[k + 1] - 1]; }

double BasisSampler::sample(std::size_t k, double u1, double u2) const {
  const std::uint32_t begin = first_piece_[k];
  const std::uint32_t end = first_piece_[k + 1];
  const double total = cumulative_[end - 1];
  const double target = u1 * total;
  std::uint32_t i = begin;
  while (i + 1 < end && cumulative_[i] <= target) ++i;
  const Piece& piece = pieces_[i];
  const auto& a = piece.power;
  // Solve G(x) = u2 G(1) on [0,1] with G(x) = a0 x + a1 x^2/2 + a2 x^3/3 + a3 x^4/4, increasing
  // since G' = phi_k >= 0. The table brackets the root in an interval of width 1/8 and a linear
  // interpolation starts Newton there; a step leaving the bracket bisects instead. It stops when G
  // is within rounding of the goal or the bracket is down to a few ulps.
  const auto& table = piece.table;
  if (a[2] == 0.0 && a[3] == 0.0) {
    // Constant or linear phi: a0 x + a1 x^2 / 2 = goal in closed form, written without
    // cancellation as x = 2 goal / (a0 + sqrt(a0^2 + 2 a1 goal)).
    const double goal = u2 * table[kTable];
    const double root = std::sqrt(std::max(0.0, a[0] * a[0] + 2.0 * a[1] * goal));
    const double x = a[0] + root > 0.0 ? 2.0 * goal / (a[0] + root) : u2;
    return wrap(piece.u0 + std::clamp(x, 0.0, 1.0) * piece.width);
  }
  auto cdf = [&a](double x) { return x * (a[0] + x * (a[1] / 2 + x * (a[2] / 3 + x * (a[3] / 4)))); };
  auto density = [&a](double x) { return a[0] + x * (a[1] + x * (a[2] + x * a[3])); };
  const double goal = u2 * table[kTable];
  int j = 0;
  while (j + 1 < kTable && table[static_cast<std::size_t>(j + 1)] <= goal) ++j;
  double lo = static_cast<double>(j) / kTable;
  double hi = static_cast<double>(j + 1) / kTable;
  const double g_lo = table[static_cast<std::size_t>(j)];
  const double g_hi = table[static_cast<std::size_t>(j + 1)];
  double x = g_hi > g_lo ? lo + (hi - lo) * (goal - g_lo) / (g_hi - g_lo) : 0.5 * (lo + hi);
  const double resolution = 4e-16 * table[kTable];
  for (int iteration = 0; iteration < 60; ++iteration) {
    const double g = cdf(x) - goal;
    if (std::fabs(g) <= resolution) break;
    if (g < 0.0) lo = x; else hi = x;
    if (hi - lo <= 4e-16) break;
    const double d = density(x);
    double next = d > 0.0 ? x - g / d : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    x = next;
  }
  return wrap(piece.u0 + std::clamp(x, 0.0, 1.0) * piece.width);
}

void BasisSampler::prefetch(std::size_t k, bool inversion) const {
#if defined(__GNUC__)
  if (inversion) {
    const std::uint32_t begin = first_piece_[k];
    const std::uint32_t end = first_piece_[k + 1];
    __builtin_prefetch(cumulative_.data() + begin);
    const char* piece = reinterpret_cast<const char*>(pieces_.data() + begin);
    const char* last = reinterpret_cast<const char*>(pieces_.data() + end);
    for (; piece < last; piece += 64) __builtin_prefetch(piece);
  } else {
    __builtin_prefetch(knots_.data() + k);
    __builtin_prefetch(knots_.data() + k + static_cast<std::size_t>(degree_) + 1);
  }
#else
  (void)k;
  (void)inversion;
#endif
}

double BasisSampler::sample_simplex(std::size_t k, const std::array<double, 4>& uniforms) const {
  // With v_(1) <= .. <= v_(p+1) the sorted uniforms, lambda_0 = v_(1), lambda_i = v_(i+1) - v_(i),
  // lambda_(p+1) = 1 - v_(p+1), and sum lambda_i t_i = t_(p+1) - sum v_(i) (t_i - t_(i-1)): every
  // term is >= 0 and they sum to at most t_(p+1) - t_0, so u stays on the support.
  const double* t = knots_.data() + k;
  auto sorted = [](double& a, double& b) {
    const double low = std::min(a, b);
    b = std::max(a, b);
    a = low;
  };
  std::array<double, 4> v = uniforms;
  // Each degree's sum written out: the same sum as one loop over i <= p (the same roundings) made
  // random-sampler photons 8-12 % slower (docs/performance.md, "The simplex draw written out").
  double u = 0.0;
  switch (degree_) {  // sorting networks of the p + 1 uniforms, then the sum
    case 0: u = t[1] - v[0] * (t[1] - t[0]); break;
    case 1:
      sorted(v[0], v[1]);
      u = t[2] - v[0] * (t[1] - t[0]) - v[1] * (t[2] - t[1]);
      break;
    case 2:
      sorted(v[0], v[1]);
      sorted(v[1], v[2]);
      sorted(v[0], v[1]);
      u = t[3] - v[0] * (t[1] - t[0]) - v[1] * (t[2] - t[1]) - v[2] * (t[3] - t[2]);
      break;
    default:  // a sorting network of five exchanges
      sorted(v[0], v[1]);
      sorted(v[2], v[3]);
      sorted(v[0], v[2]);
      sorted(v[1], v[3]);
      sorted(v[1], v[2]);
      u = t[4] - v[0] * (t[1] - t[0]) - v[1] * (t[2] - t[1]) - v[2] * (t[3] - t[2]) - v[3] * (t[4] - t[3]);
      break;
  }
  return wrap(std::clamp(u, t[0], t[degree_ + 1]));
}

double BasisSampler::wrap(double u) const {
  // A periodic function's pieces may lie a period before u_begin or past u_end.
  return periodic_ ? wrap_into_period(u, u_begin_, u_end_) : u;
}

double BasisSampler::pdf(std::size_t k, double u) const {
  const double length = u_end_ - u_begin_;
  for (std::uint32_t i = first_piece_[k]; i < first_piece_[k + 1]; ++i) {
    const Piece& piece = pieces_[i];
    // On a periodic basis a piece may lie a period away from u.
    for (const double shift : {0.0, -length, length}) {
      if (shift != 0.0 && !periodic_) break;
      const double v = u + shift;
      if (v >= piece.u0 && v < piece.u0 + piece.width) {
        const double x = (v - piece.u0) / piece.width;
        const auto& a = piece.power;
        return std::max(0.0, a[0] + x * (a[1] + x * (a[2] + x * a[3]))) / mass(k);
      }
    }
  }
  return 0.0;
}

int segment_elements(int elements, double segment_length, double curve_length) {
  return std::max(1, static_cast<int>(std::lround(elements * segment_length / curve_length)));
}

namespace {

// The storage nodes of a curve for about `wanted` elements. The fixed nodes (joints, and the extra
// nodes: events, contacts) cut each segment into regions; each region is split into elements of
// equal arc length, as many as keep them no longer than the segment's (below), times
// 2^subdivisions. Returns the closing continuity (Jump on an open curve).
//
// Splitting regions rather than the segment keeps every element between half and all of the
// segment's element length at its level, unless it is a whole region shorter than that: an extra
// node merged into a mesh split evenly over the segment could land a hair from an element
// boundary and leave a sliver (an event 0.0009 from a boundary of elements 0.0156 long on the
// round-occluder floor), whose short secants steer the Hermite reconstruction's slopes and whose
// short supports catch few photons. A region's count doubles with each subdivision (or stays the
// same while a short region waits), and s = start + length j / pieces is the same double for
// (j, pieces) and (2 j, 2 pieces), so the meshes nest. A segment without extra nodes is one
// region, split exactly as an even split of the segment.
Continuity place_nodes(const Scene& scene, const Curve& curve, int wanted, int subdivisions,
                       bool smooth_joints, std::span<const MeshNode> extra,
                       std::vector<MeshNode>& nodes) {
  const std::uint32_t segment_count = curve.segment_count;
  Continuity closing = !curve.closed ? Continuity::Jump
                       : smooth_joints ? Continuity::C1
                                       : curve.joints.back();
  // The fixed nodes: joints, then the extra nodes merged in (one within 1e-9 of a fixed node
  // lowers its continuity; one at the closing point of a closed curve lowers the closing joint's).
  std::vector<MeshNode> fixed;
  for (std::uint32_t i = 1; i < segment_count; ++i)
    fixed.push_back({static_cast<double>(i), smooth_joints ? Continuity::C1 : curve.joints[i - 1]});
  for (const MeshNode& node : extra) {
    if (curve.closed && (std::fabs(node.u) <= 1e-9 || std::fabs(node.u - segment_count) <= 1e-9)) {
      closing = std::min(closing, node.continuity);
      continue;
    }
    if (!(node.u > 0.0 && node.u < segment_count)) continue;
    const auto at = std::lower_bound(fixed.begin(), fixed.end(), node.u,
                                     [](const MeshNode& a, double u) { return a.u < u; });
    auto merge = [&](std::vector<MeshNode>::iterator existing) {
      if (existing == fixed.end() || std::fabs(existing->u - node.u) > 1e-9) return false;
      existing->continuity = std::min(existing->continuity, node.continuity);
      return true;
    };
    if (merge(at) || (at != fixed.begin() && merge(at - 1))) continue;
    fixed.insert(at, node);
  }
  // Each region between consecutive fixed nodes (and the curve's ends), split evenly in arc length.
  nodes.clear();
  std::size_t next_fixed = 0;
  for (std::uint32_t i = 0; i < segment_count; ++i) {
    const SceneSegment& segment = scene.segments[curve.first_segment + i];
    const Cubic& shape = segment.geometry.shape;
    const double segment_pieces = segment_elements(wanted, segment.length, curve.length);
    const double element = segment.length / segment_pieces;  // at subdivision 0
    if (i > 0) nodes.push_back(fixed[next_fixed++]);  // the joint
    double region_start = 0.0;  // arc length from the segment's start
    for (;;) {
      const bool inside = next_fixed < fixed.size() && fixed[next_fixed].u < i + 1.0;
      const double region_end =
          inside ? std::clamp(segment.arc_length.length_at(shape, fixed[next_fixed].u - i), region_start, segment.length)
                 : segment.length;
      const double region = region_end - region_start;
      // As many elements as keep them no longer than the segment's (its share of the segment's
      // elements, rounded up), and the levels that pass before a region shorter than half an
      // element is split at all: its elements are then between half and all of the level's
      // element length, never a sliver of it. (The tolerances keep a region that is the whole
      // segment at exactly the segment's elements.)
      const int share =
          std::max(1, static_cast<int>(std::ceil(segment_pieces * region / segment.length - 1e-9)));
      int delay = 0;
      while (delay < subdivisions && region / share * std::ldexp(1.0, delay + 1) <= element * (1.0 + 1e-9))
        ++delay;
      const int pieces = share << (subdivisions - delay);
      for (int j = 1; j < pieces; ++j) {
        const double s = region_start + region * j / pieces;
        nodes.push_back({i + segment.arc_length.parameter_at(shape, s), Continuity::C1});
      }
      if (!inside) break;
      nodes.push_back(fixed[next_fixed++]);
      region_start = region_end;
    }
  }
  return closing;
}

}  // namespace

double longest_element(const Scene& scene, const Curve& curve, int elements, bool smooth_joints,
                       std::span<const MeshNode> extra, int subdivisions) {
  std::vector<MeshNode> nodes;
  place_nodes(scene, curve, std::max(elements, 1), subdivisions, smooth_joints, extra, nodes);
  double longest = 0.0;
  double previous = 0.0;
  for (const MeshNode& node : nodes) {
    const double s = arc_length_at(scene, curve, node.u);
    longest = std::max(longest, s - previous);
    previous = s;
  }
  return std::max(longest, curve.length - previous);
}

CurveStorage build_curve_storage(const Scene& scene, const Curve& curve, BasisKind kind,
                                 int elements, bool smooth_joints, std::span<const MeshNode> extra,
                                 int subdivisions) {
  CurveStorage storage;
  const std::uint32_t segment_count = curve.segment_count;
  const int degree = degree_of(kind);
  const int wanted = std::max(elements, 1);
  storage.closing = place_nodes(scene, curve, wanted, subdivisions, smooth_joints, extra, storage.nodes);
  if (storage.closing == Continuity::Jump) {
    storage.basis = SplineBasis(degree, 0.0, static_cast<double>(segment_count), storage.nodes);
  } else {
    // Periodic: K knots in the period (with multiplicity). At least 2 degree + 2 of them keep
    // every function distinct from its neighbours around the loop (a function never meets its
    // own other end, and the mass matrix keeps its envelope): refine until there are.
    auto knots_in_period = [&] {
      int count = SplineBasis::multiplicity(degree, storage.closing);
      for (const MeshNode& node : storage.nodes) count += SplineBasis::multiplicity(degree, node.continuity);
      return count;
    };
    while (knots_in_period() < 2 * degree + 2) {
      ++subdivisions;
      storage.closing = place_nodes(scene, curve, wanted, subdivisions, smooth_joints, extra, storage.nodes);
    }
    storage.basis = SplineBasis::periodic(degree, 0.0, static_cast<double>(segment_count),
                                          storage.nodes, storage.closing);
  }

  // Integrals of phi_k |C'(u)| du and the mass matrix, in one pass of the quadrature: four
  // 8-point Gauss-Legendre panels per span integrate the polynomial-times-speed products to far
  // below Monte Carlo noise. The mass matrix is kept in envelope storage (row k from column
  // mass_first[k]), then factored in place: L has the same envelope as M. B-splines more than p
  // apart have disjoint supports, so a clamped basis is banded; on a periodic one the functions
  // straddling the closing point (the first p) meet the last p, whose rows then reach back to
  // column 0.
  const int p = storage.basis.degree();
  const std::size_t n = storage.basis.size();
  const auto pu = static_cast<std::size_t>(p);
  storage.mass_first.assign(n, 0);
  storage.mass_offset.assign(n + 1, 0);
  for (std::size_t row = 0; row < n; ++row) {
    const bool wraps = storage.basis.is_periodic() && row + pu >= n;
    storage.mass_first[row] = wraps || row < pu ? 0 : row - pu;
    storage.mass_offset[row + 1] = storage.mass_offset[row] + (row - storage.mass_first[row] + 1);
  }
  std::vector<double>& envelope = storage.mass_cholesky;
  envelope.assign(storage.mass_offset[n], 0.0);
  auto entry = [&](std::size_t row, std::size_t col) -> double& {  // mass_first[row] <= col <= row
    return envelope[storage.mass_offset[row] + col - storage.mass_first[row]];
  };
  storage.basis_length.assign(n, 0.0);
  for_each_quadrature_point(scene, curve, storage.basis,
                            [&](double, double weight, const auto& index, const auto& values, std::size_t) {
                              for (std::size_t j = 0; j <= pu; ++j) storage.basis_length[index[j]] += weight * values[j];
                              for (std::size_t i = 0; i <= pu; ++i)
                                for (std::size_t j = 0; j <= pu; ++j)
                                  if (index[j] <= index[i])
                                    entry(index[i], index[j]) += weight * values[i] * values[j];
                            });
  storage.sampler = BasisSampler(storage.basis);
  // Envelope Cholesky: L_kk = sqrt(M_kk - sum L_kj^2), L_ik = (M_ik - sum L_ij L_kj) / L_kk, the
  // sums over the columns both rows hold.
  for (std::size_t row = 0; row < n; ++row) {
    for (std::size_t col = storage.mass_first[row]; col <= row; ++col) {
      double sum = entry(row, col);
      const std::size_t inner = std::max(storage.mass_first[row], storage.mass_first[col]);
      for (std::size_t j = inner; j < col; ++j) sum -= entry(row, j) * entry(col, j);
      entry(row, col) = col == row ? std::sqrt(std::max(sum, 0.0)) : sum / entry(col, col);
    }
  }
  // Speed bound over each basis function's support: on each segment it touches, the bound over
  // the part it touches (on a periodic basis the support may reach a period before or after
  // [0, segment_count)). A bound local to a fine mesh's short support is nearly the speed itself,
  // so the origins' rejection on speed seldom draws again.
  storage.speed_bound.assign(n, 0.0);
  const std::vector<double>& knots = storage.basis.knots();
  const double period = static_cast<double>(segment_count);
  // Only the segments under a support (a few, with one more on each side against rounding), not
  // all of the curve's: that was quadratic in the segments of a long curve.
  const auto near = [&](double at) {
    return static_cast<std::uint32_t>(std::clamp(at, 0.0, period));
  };
  for (std::size_t k = 0; k < n; ++k) {
    const double begin = knots[k];
    const double end = knots[k + pu + 1];
    for (const double shift : {0.0, -period, period}) {
      if (shift != 0.0 && !storage.basis.is_periodic()) continue;
      for (std::uint32_t i = near(std::floor(begin - shift) - 1.0); i < near(std::ceil(end - shift) + 1.0); ++i)
        if (i + 1.0 + shift > begin && i + shift < end) {
          const SceneSegment& segment = scene.segments[curve.first_segment + i];
          const double t0 = std::clamp(begin - i - shift, 0.0, 1.0);
          const double t1 = std::clamp(end - i - shift, 0.0, 1.0);
          // Both are upper bounds there; over a long part the segment's may be the lower.
          const double bound = segment.geometry.kind == SegmentKind::Line
                                   ? segment.speed_bound
                                   : std::min(segment.speed_bound, speed_bound(segment.geometry.shape, t0, t1));
          storage.speed_bound[k] = std::max(storage.speed_bound[k], bound);
        }
    }
  }
  return storage;
}

std::vector<double> project_emittance_profile(const Scene& scene, const Curve& curve,
                                              const CurveStorage& storage) {
  if (curve.emittance_profile.empty()) return storage.basis_length;
  // The same quadrature as basis_length, with the profile (a cubic in t) in the integrand.
  std::vector<double> result(storage.basis.size(), 0.0);
  for_each_quadrature_point(scene, curve, storage.basis,
                            [&](double u, double weight, const auto& index, const auto& values, std::size_t) {
                              const double emitted = weight * emittance_factor(curve, u);
                              for (std::size_t j = 0; j <= static_cast<std::size_t>(storage.basis.degree()); ++j)
                                result[index[j]] += emitted * values[j];
                            });
  return result;
}

void galerkin_estimate(const CurveStorage& storage, const double* deposits, double* coefficients,
                       std::size_t stride) {
  const std::size_t n = storage.basis.size();
  // Forward substitution L y = d by rows, then back substitution L^T b = y by columns of L, both
  // in the output (a scratch vector of the storage's size was allocated, and its pages faulted
  // in, on every call). Row k reads deposit k before writing coefficient k, so the two may be
  // the same array.
  double* x = coefficients;
  for (std::size_t row = 0; row < n; ++row) {
    const std::size_t first = storage.mass_first[row];
    const double* l = storage.mass_cholesky.data() + storage.mass_offset[row];  // L_(row, first) ..
    double sum = deposits[row * stride];
    for (std::size_t col = first; col < row; ++col) sum -= l[col - first] * x[col * stride];
    x[row * stride] = sum / l[row - first];
  }
  for (std::size_t row = n; row-- > 0;) {
    const std::size_t first = storage.mass_first[row];
    const double* l = storage.mass_cholesky.data() + storage.mass_offset[row];
    const double value = x[row * stride] / l[row - first];
    x[row * stride] = value;
    for (std::size_t col = first; col < row; ++col) x[col * stride] -= l[col - first] * value;
  }
}

bool clamp_keeping_power(const CurveStorage& storage, double* coefficients, std::size_t stride,
                         double power) {
  double kept = 0.0;
  const std::size_t n = storage.basis.size();
  for (std::size_t k = 0; k < n; ++k) {
    double& b = coefficients[k * stride];
    b = b > 0.0 ? b : 0.0;  // a NaN too
    kept += b * storage.basis_length[k];
  }
  const bool positive = kept > 0.0 && std::isfinite(kept);
  const double rescale = positive ? power / kept : 0.0;
  for (std::size_t k = 0; k < n; ++k) coefficients[k * stride] *= rescale;
  return positive;
}

namespace {

// Cholesky factorisation in place of a small symmetric positive definite matrix (row-major, n x n,
// lower triangle used). False when a pivot is not positive (relative to the diagonal's size).
bool cholesky_in_place(std::vector<double>& a, std::size_t n) {
  for (std::size_t j = 0; j < n; ++j) {
    const double diagonal = a[j * n + j];
    double sum = diagonal;
    for (std::size_t k = 0; k < j; ++k) sum -= a[j * n + k] * a[j * n + k];
    if (!(sum > 1e-13 * diagonal)) return false;
    a[j * n + j] = std::sqrt(sum);
    for (std::size_t i = j + 1; i < n; ++i) {
      double t = a[i * n + j];
      for (std::size_t k = 0; k < j; ++k) t -= a[i * n + k] * a[j * n + k];
      a[i * n + j] = t / a[j * n + j];
    }
  }
  return true;
}

// x := A^-1 x for the factor L of A = L L^T from cholesky_in_place.
void cholesky_solve(const std::vector<double>& l, std::size_t n, double* x) {
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t k = 0; k < i; ++k) x[i] -= l[i * n + k] * x[k];
    x[i] /= l[i * n + i];
  }
  for (std::size_t i = n; i-- > 0;) {
    for (std::size_t k = i + 1; k < n; ++k) x[i] -= l[k * n + i] * x[k];
    x[i] /= l[i * n + i];
  }
}

// The local window of one coefficient: functions of the extended numbering (e = j + lap n on a
// periodic basis) and their weights, with the weights' variance factor w^T G w.
struct LocalWindow {
  std::vector<std::ptrdiff_t> functions;  // increasing
  std::vector<double> weights;
  double variance = 0.0;
  int degree = -1;  // polynomial degree reproduced; -1: no window
};

}  // namespace

void build_local_estimator(const Scene& scene, const Curve& curve, CurveStorage& storage,
                           bool nodal_values) {
  const SplineBasis& basis = storage.basis;
  const int p = basis.degree();
  const auto pu = static_cast<std::size_t>(p);
  const std::size_t n = basis.size();
  const auto count = static_cast<std::ptrdiff_t>(n);
  const std::vector<double>& knots = basis.knots();
  const bool periodic = basis.is_periodic();
  const double period = basis.u_end() - basis.u_begin();
  const double tolerance = 1e-12 * period;
  const int wanted_degree = nodal_values ? 3 : p;
  const std::size_t half = nodal_values ? 2 : pu;

  // Per function j: raw moments integral(phi_j (u - a_j)^r ds), r = 0..3, about the start a_j of
  // the support (the aliases a period away see the same numbers), and the band of the Gram matrix
  // integral(phi_j phi_(j+d) ds), d = 0..p, d counted round the loop on a periodic basis.
  std::vector<std::array<double, 4>> moment(n, std::array<double, 4>{});
  std::vector<std::array<double, SplineBasis::kMaxDegree + 1>> gram(n, std::array<double, SplineBasis::kMaxDegree + 1>{});
  for_each_quadrature_point(
      scene, curve, basis,
      [&](double u, double weight, const auto& index, const auto& values, std::size_t span) {
        for (std::size_t j = 0; j <= pu; ++j) {
          const double x = u - knots[span - pu + j];
          double term = weight * values[j];
          for (double& m : moment[index[j]]) {
            m += term;
            term *= x;
          }
          for (std::size_t i = j; i <= pu; ++i) gram[index[j]][i - j] += weight * values[j] * values[i];
        }
      });

  // Function e of the extended numbering: function e mod n, a whole number of laps away.
  auto lap_of = [&](std::ptrdiff_t e) { return e >= 0 ? e / count : -((-e + count - 1) / count); };
  auto local = [&](std::ptrdiff_t e) { return static_cast<std::size_t>(e - lap_of(e) * count); };
  auto start = [&](std::ptrdiff_t e) { return knots[local(e)] + static_cast<double>(lap_of(e)) * period; };
  auto end = [&](std::ptrdiff_t e) {
    return knots[local(e) + pu + 1] + static_cast<double>(lap_of(e)) * period;
  };
  auto exists = [&](std::ptrdiff_t e) { return periodic || (e >= 0 && e < count); };
  // Where R(u) may stop being smooth: the C0 and C-1 nodes, and every joint between segments
  // (R is smooth in arc length, but at a joint the parametrisation's speed changes its slope, so
  // R(u) is only as smooth as the knots the spline has there; the ring of cubic arcs is C1 in u
  // at its joints, not C2). A function whose support holds one strictly inside straddles it: its
  // coefficient, the blossom of the spline's polynomial piece on any span of its support, is
  // estimated from the pieces on either side.
  //
  // A mesh with about one element per segment has no function inside a segment, so no window
  // stands on one side of every joint; the windows are then grown across the joints (`across`),
  // where R(u) is C1 and only its second derivative jumps, by the change of the speed's slope:
  // far less error than the lumped estimate's, and far less than extrapolating from a window
  // several functions away (which once gave weights in the hundreds and 10-30 % errors on a ring
  // of 32 arcs at 32 elements). The C0 and C-1 nodes stay breaks either way.
  std::vector<double> breaks;
  std::vector<double> hard_breaks;
  for (const MeshNode& node : storage.nodes) {
    if (node.continuity != Continuity::C1 || node.u == std::round(node.u)) breaks.push_back(node.u);
    if (node.continuity != Continuity::C1) hard_breaks.push_back(node.u);
  }
  if (periodic) {
    breaks.push_back(basis.u_begin());
    if (storage.closing != Continuity::C1) hard_breaks.push_back(basis.u_begin());
  }
  bool across = false;  // whether joints (C1 nodes at whole u) are crossed
  auto straddles = [&](std::ptrdiff_t e) {
    const double a = start(e) + tolerance;
    const double b = end(e) - tolerance;
    for (double d : across ? hard_breaks : breaks)
      for (double shift : {-period, 0.0, period}) {
        const double at = d + shift + static_cast<double>(lap_of(e)) * period;
        if (at > a && at < b) return true;
      }
    return false;
  };
  // Consecutive functions with supports that only touch are split by a C-1 node (p + 1 knots).
  auto separated = [&](std::ptrdiff_t left, std::ptrdiff_t right) {
    return end(left) <= start(right) + tolerance;
  };
  auto usable = [&](std::ptrdiff_t e) { return exists(e) && !straddles(e); };

  // The window grown from `seed` one function at a time, alternating sides (the side with fewer
  // first), never across a straddling function or a C-1 node, never holding a function twice.
  auto grow = [&](std::ptrdiff_t seed, bool leftwards, bool rightwards) {
    std::vector<std::ptrdiff_t> window;
    if (!usable(seed)) return window;
    window.push_back(seed);
    std::ptrdiff_t left = seed;
    std::ptrdiff_t right = seed;
    const std::size_t limit = std::min(2 * half + 1, n);
    while (window.size() < limit) {
      const bool can_left = leftwards && usable(left - 1) && !separated(left - 1, left);
      const bool can_right = rightwards && usable(right + 1) && !separated(right, right + 1);
      if (!can_left && !can_right) break;
      if (can_left && (!can_right || seed - left <= right - seed)) {
        window.insert(window.begin(), --left);
      } else {
        window.push_back(++right);
      }
    }
    return window;
  };

  // Least-variance weights on a window for the target of function k (extended e = k).
  auto solve = [&](std::size_t k, std::vector<std::ptrdiff_t> functions) {
    LocalWindow result;
    const std::size_t size = functions.size();
    if (size == 0) return result;
    const int degree = std::min(wanted_degree, static_cast<int>(size) - 1);
    const auto terms = static_cast<std::size_t>(degree) + 1;
    // Scaled coordinate x = (u - centre) / scale over the window's extent.
    const double lo = start(functions.front());
    const double hi = end(functions.back());
    const double centre = 0.5 * (lo + hi);
    const double scale = std::max(0.5 * (hi - lo), tolerance);
    // Target functional of x^m: the blossom of x^m at the interior knots of function k (the
    // B-spline coefficient of x^m: the elementary symmetric polynomial over the binomial), or x^m
    // at the hat's peak.
    std::array<double, 4> target{};
    if (nodal_values) {
      const double x = (knots[k + 1] - centre) / scale;
      for (std::size_t m = 0; m < terms; ++m) target[m] = std::pow(x, static_cast<double>(m));
    } else {
      std::array<double, 4> symmetric{1.0, 0.0, 0.0, 0.0};  // e_m of the knots so far
      for (std::size_t i = 1; i <= pu; ++i) {
        const double x = (knots[k + i] - centre) / scale;
        for (std::size_t m = i; m >= 1; --m) symmetric[m] += x * symmetric[m - 1];
      }
      for (std::size_t m = 0; m < terms; ++m) {
        double binomial = 1.0;
        for (std::size_t r = 1; r <= m; ++r) binomial = binomial * static_cast<double>(pu - r + 1) / static_cast<double>(r);
        target[m] = symmetric[m] / binomial;
      }
    }
    // V_am = integral(phi_a x^m ds) from the raw moments by the binomial theorem.
    std::vector<double> v(size * terms);
    for (std::size_t a = 0; a < size; ++a) {
      const std::array<double, 4>& raw = moment[local(functions[a])];
      const double offset = start(functions[a]) - centre;
      for (std::size_t m = 0; m < terms; ++m) {
        double sum = 0.0;
        double binomial = 1.0;  // C(m, r)
        for (std::size_t r = 0; r <= m; ++r) {
          sum += binomial * raw[r] * std::pow(offset, static_cast<double>(m - r));
          binomial = binomial * static_cast<double>(m - r) / static_cast<double>(r + 1);
        }
        v[a * terms + m] = sum / std::pow(scale, static_cast<double>(m));
      }
    }
    std::vector<double> g(size * size, 0.0);
    for (std::size_t a = 0; a < size; ++a)
      for (std::size_t b = a; b < size; ++b) {
        const std::ptrdiff_t gap = functions[b] - functions[a];
        if (gap <= p) g[b * size + a] = g[a * size + b] = gram[local(functions[a])][static_cast<std::size_t>(gap)];
      }
    if (!cholesky_in_place(g, size)) return result;
    // A = G^-1 V by columns, S = V^T A, then S y = c and w = A y; w^T G w = c . y.
    std::vector<double> a(size * terms);
    for (std::size_t m = 0; m < terms; ++m) {
      std::vector<double> column(size);
      for (std::size_t r = 0; r < size; ++r) column[r] = v[r * terms + m];
      cholesky_solve(g, size, column.data());
      for (std::size_t r = 0; r < size; ++r) a[r * terms + m] = column[r];
    }
    std::vector<double> s(terms * terms, 0.0);
    for (std::size_t i = 0; i < terms; ++i)
      for (std::size_t j = 0; j < terms; ++j)
        for (std::size_t r = 0; r < size; ++r) s[i * terms + j] += v[r * terms + i] * a[r * terms + j];
    std::array<double, 4> y = target;
    if (!cholesky_in_place(s, terms)) return result;
    cholesky_solve(s, terms, y.data());
    result.functions = std::move(functions);
    result.weights.assign(size, 0.0);
    for (std::size_t r = 0; r < size; ++r)
      for (std::size_t m = 0; m < terms; ++m) result.weights[r] += a[r * terms + m] * y[m];
    for (std::size_t m = 0; m < terms; ++m) result.variance += target[m] * y[m];
    result.degree = degree;
    return result;
  };

  // The window of function e with the current breaks. A straddling function's seeds are the
  // nearest functions that do not straddle, at most p + 1 functions away (its support's
  // neighbours); a seed further off would extrapolate over several elements.
  auto window_of = [&](std::size_t k) {
    const auto e = static_cast<std::ptrdiff_t>(k);
    if (!straddles(e)) return solve(k, grow(e, true, true));
    // Straddling a node: the value there from each side; the two sides' deposits are
    // independent, so inverse-variance weights give the combination of least variance.
    std::ptrdiff_t left_seed = e - 1;
    std::ptrdiff_t right_seed = e + 1;
    const auto reach = static_cast<std::ptrdiff_t>(pu) + 1;
    while (e - left_seed < reach && exists(left_seed) && straddles(left_seed)) --left_seed;
    while (right_seed - e < reach && exists(right_seed) && straddles(right_seed)) ++right_seed;
    LocalWindow left = solve(k, grow(left_seed, true, false));
    LocalWindow right = solve(k, grow(right_seed, false, true));
    if (left.degree < 0 || right.degree < 0) return left.degree >= 0 ? left : right;
    LocalWindow window;
    const double lambda = right.variance / (left.variance + right.variance);
    window.functions = left.functions;
    window.functions.insert(window.functions.end(), right.functions.begin(), right.functions.end());
    for (double w : left.weights) window.weights.push_back(lambda * w);
    for (double w : right.weights) window.weights.push_back((1.0 - lambda) * w);
    window.degree = std::min(left.degree, right.degree);
    return window;
  };

  storage.local_first.assign(n + 1, 0);
  storage.local_index.clear();
  storage.local_weight.clear();
  storage.local_degree.assign(n, 0);
  for (std::size_t k = 0; k < n; ++k) {
    const auto e = static_cast<std::ptrdiff_t>(k);
    across = false;
    LocalWindow window = window_of(k);
    if (window.degree < wanted_degree) {
      // Too few functions between the joints: across them, if that reproduces more.
      across = true;
      LocalWindow wide = window_of(k);
      if (wide.degree > window.degree) window = std::move(wide);
    }
    if (window.degree < 0) {  // nothing to stand on: the lumped estimate
      window.functions = {e};
      window.weights = {1.0 / storage.basis_length[k]};
      window.degree = 0;
    }
    for (std::size_t r = 0; r < window.functions.size(); ++r) {
      storage.local_index.push_back(static_cast<std::uint32_t>(local(window.functions[r])));
      storage.local_weight.push_back(window.weights[r]);
    }
    storage.local_first[k + 1] = storage.local_index.size();
    storage.local_degree[k] = static_cast<std::int8_t>(window.degree);
  }
}

Restriction restriction_between(const SplineBasis& coarse, const SplineBasis& fine) {
  const int p = fine.degree();
  const auto pu = static_cast<std::size_t>(p);
  const std::size_t terms = pu + 1;
  const std::vector<double>& knots = fine.knots();
  // Rows of R as (fine column, weight) lists, each pair set from the first fine span where both
  // functions are alive (nested bases make every span give the same numbers).
  std::vector<std::vector<std::pair<std::uint32_t, double>>> rows(coarse.size());
  std::array<double, SplineBasis::kMaxDegree + 1> values{};
  for (std::size_t span = fine.first_span(); span < fine.end_span(); ++span) {
    const double a = knots[span];
    const double b = knots[span + 1];
    if (!(b > a)) continue;
    // A[m][r] = phi_fine_(span - p + r)(x_m); right-hand sides: the coarse functions at x_m.
    std::array<std::array<double, SplineBasis::kMaxDegree + 1>, SplineBasis::kMaxDegree + 1> matrix{};
    std::array<std::array<double, SplineBasis::kMaxDegree + 1>, SplineBasis::kMaxDegree + 1> rhs{};
    std::array<std::size_t, SplineBasis::kMaxDegree + 1> coarse_index{};
    for (std::size_t m = 0; m < terms; ++m) {
      const double x = a + (b - a) * (static_cast<double>(m) + 0.5) / static_cast<double>(terms);
      fine.evaluate_in_span(span, x, values.data());
      for (std::size_t r = 0; r < terms; ++r) matrix[m][r] = values[r];
      const std::size_t first = coarse.evaluate(x, values.data());
      for (std::size_t r = 0; r < terms; ++r) {
        rhs[m][r] = values[r];
        coarse_index[r] = coarse.index(first + r);  // the same coarse span for every x_m
      }
    }
    // Gaussian elimination with partial pivoting, all right-hand sides at once.
    for (std::size_t col = 0; col < terms; ++col) {
      std::size_t pivot = col;
      for (std::size_t m = col + 1; m < terms; ++m)
        if (std::fabs(matrix[m][col]) > std::fabs(matrix[pivot][col])) pivot = m;
      std::swap(matrix[col], matrix[pivot]);
      std::swap(rhs[col], rhs[pivot]);
      for (std::size_t m = col + 1; m < terms; ++m) {
        const double factor = matrix[m][col] / matrix[col][col];
        for (std::size_t r = col; r < terms; ++r) matrix[m][r] -= factor * matrix[col][r];
        for (std::size_t r = 0; r < terms; ++r) rhs[m][r] -= factor * rhs[col][r];
      }
    }
    for (std::size_t col = terms; col-- > 0;) {
      for (std::size_t r = 0; r < terms; ++r) {
        double sum = rhs[col][r];
        for (std::size_t m = col + 1; m < terms; ++m) sum -= matrix[col][m] * rhs[m][r];
        rhs[col][r] = sum / matrix[col][col];
      }
    }
    // rhs[f][r]: the weight of fine function span - p + f in coarse function coarse_index[r].
    for (std::size_t r = 0; r < terms; ++r) {
      auto& row = rows[coarse_index[r]];
      for (std::size_t f = 0; f < terms; ++f) {
        const auto column = static_cast<std::uint32_t>(fine.index(span - pu + f));
        // Spans come in order, so a pair seen before was added within the last few entries (the
        // functions of the previous spans), or, round a periodic basis's closing point, within the
        // first few: two short searches keep this linear.
        const auto reach = static_cast<std::ptrdiff_t>(std::min(row.size(), 2 * terms));
        auto same = [&](const auto& e) { return e.first == column; };
        const bool known = std::any_of(row.end() - reach, row.end(), same) ||
                           std::any_of(row.begin(), row.begin() + reach, same);
        if (!known) row.emplace_back(column, rhs[f][r]);
      }
    }
  }
  Restriction result;
  result.fine_size = fine.size();
  result.first.assign(coarse.size() + 1, 0);
  for (std::size_t i = 0; i < coarse.size(); ++i) {
    std::sort(rows[i].begin(), rows[i].end());
    for (const auto& [column, weight] : rows[i]) {
      if (!(std::fabs(weight) > 1e-14)) continue;
      result.column.push_back(column);
      result.weight.push_back(weight);
    }
    result.first[i + 1] = result.column.size();
  }
  return result;
}

void restrict_deposits(const Restriction& r, const double* fine, std::size_t stride, double* coarse) {
  for (std::size_t i = 0; i + 1 < r.first.size(); ++i) {
    double sum = 0.0;
    for (std::size_t e = r.first[i]; e < r.first[i + 1]; ++e) sum += r.weight[e] * fine[r.column[e] * stride];
    coarse[i] = sum;
  }
}

void prolong_coefficients(const Restriction& r, const double* coarse, double* fine, std::size_t stride) {
  for (std::size_t j = 0; j < r.fine_size; ++j) fine[j * stride] = 0.0;
  for (std::size_t i = 0; i + 1 < r.first.size(); ++i)
    for (std::size_t e = r.first[i]; e < r.first[i + 1]; ++e) fine[r.column[e] * stride] += r.weight[e] * coarse[i];
}

void local_estimate(const CurveStorage& storage, const double* deposits, double* coefficients,
                    std::size_t stride) {
  const std::size_t n = storage.basis.size();
  for (std::size_t k = 0; k < n; ++k) {
    double sum = 0.0;
    for (std::size_t i = storage.local_first[k]; i < storage.local_first[k + 1]; ++i)
      sum += storage.local_weight[i] * deposits[storage.local_index[i] * stride];
    coefficients[k * stride] = sum;
  }
}

}  // namespace flatland
