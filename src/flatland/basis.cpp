#include "flatland/basis.hpp"

#include "flatland/quadrature.hpp"

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

std::size_t SplineBasis::find_span(double u) const {
  // The span i with knots[i] <= u < knots[i+1], among i in [first_span, end_span); u at the very
  // end of a clamped basis belongs to the last non-empty span.
  const std::size_t p = static_cast<std::size_t>(degree_);
  const std::size_t last = end_span();
  if (u >= knots_[last]) return last - 1;
  // Clamped, the first span is never empty; periodic, the closing knot's copies may follow it.
  if (u <= knots_[p] && !periodic_) return p;
  // upper_bound gives the first knot > u; the span starts one before it.
  const auto it = std::upper_bound(knots_.begin() + static_cast<std::ptrdiff_t>(p),
                                   knots_.begin() + static_cast<std::ptrdiff_t>(last) + 1, u);
  return static_cast<std::size_t>(it - knots_.begin()) - 1;
}

std::size_t SplineBasis::evaluate(double u, double* values) const {
  if (periodic_) u = wrap(u);
  const std::size_t span = find_span(u);
  evaluate_in_span(span, u, values);
  return span - static_cast<std::size_t>(degree_);
}

void SplineBasis::evaluate_in_span(std::size_t span, double u, double* values) const {
  assert(span >= static_cast<std::size_t>(degree_) && span + static_cast<std::size_t>(degree_) < knots_.size());
  // Cox-de Boor recursion in the triangular form of Piegl and Tiller (The NURBS Book, A2.2):
  // builds the nonzero functions of degree j from those of degree j-1 without division by zero,
  // since only non-empty spans are visited.
  const int p = degree_;
  std::array<double, kMaxDegree + 1> left{};
  std::array<double, kMaxDegree + 1> right{};
  values[0] = 1.0;
  for (int j = 1; j <= p; ++j) {
    left[j] = u - knots_[span + 1 - static_cast<std::size_t>(j)];
    right[j] = knots_[span + static_cast<std::size_t>(j)] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      const double temp = values[r] / (right[r + 1] + left[j - r]);
      values[r] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    values[j] = saved;
  }
}

namespace {

// Visits every quadrature point of the curve's storage mesh: four 8-point Gauss-Legendre panels
// per non-empty knot span of [u_begin, u_end) (each span lies in one segment), with the arc-length
// weight w = GL weight x |C'(u)| du and the basis functions alive there (values[j] for function
// index[j], j = 0..degree; distinct, as a periodic basis has at least degree + 1 functions). Integrals of phi_k times smooth functions along arc length are
// sums over these points.
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
        visit(u, weight, index, values);
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
  std::array<double, SplineBasis::kMaxDegree + 1> values{};
  first_piece_.assign(basis.size() + 1, 0);
  periodic_ = basis.is_periodic();
  u_begin_ = basis.u_begin();
  u_end_ = basis.u_end();
  for (std::size_t k = 0; k < basis.size(); ++k) {
    first_piece_[k] = static_cast<std::uint32_t>(pieces_.size());
    double cumulative = 0.0;
    for (std::size_t span = k; span <= k + static_cast<std::size_t>(p); ++span) {
      const double u0 = knots[span];
      const double width = knots[span + 1] - u0;
      if (!(width > 0.0)) continue;
      // Values at the nodes, then the power form by solving the 4x4 Vandermonde system.
      std::array<std::array<double, 5>, 4> system{};
      for (std::size_t row = 0; row < 4; ++row) {
        const double x = kNodes[row];
        // Function k is function k - (span - p) of this span (spans k .. k + p carry it). On a
        // periodic basis the first p spans (before u_begin) are evaluated a period later, as
        // span + K, where the recursion has the p knots it reads on the left.
        if (span < static_cast<std::size_t>(p))
          basis.evaluate_in_span(span + basis.size(), u0 + x * width + (basis.u_end() - basis.u_begin()),
                                 values.data());
        else
          basis.evaluate_in_span(span, u0 + x * width, values.data());
        const double phi = values[k + static_cast<std::size_t>(p) - span];
        double power = 1.0;
        for (std::size_t col = 0; col < 4; ++col, power *= x) system[row][col] = power;
        system[row][4] = phi;
      }
      for (std::size_t col = 0; col < 4; ++col) {  // Gaussian elimination with partial pivoting
        std::size_t pivot = col;
        for (std::size_t row = col + 1; row < 4; ++row)
          if (std::fabs(system[row][col]) > std::fabs(system[pivot][col])) pivot = row;
        std::swap(system[col], system[pivot]);
        for (std::size_t row = col + 1; row < 4; ++row) {
          const double factor = system[row][col] / system[col][col];
          for (std::size_t c = col; c < 5; ++c) system[row][c] -= factor * system[col][c];
        }
      }
      Piece piece;
      piece.u0 = u0;
      piece.width = width;
      for (std::size_t row = 4; row-- > 0;) {
        double sum = system[row][4];
        for (std::size_t c = row + 1; c < 4; ++c) sum -= system[row][c] * piece.power[c];
        piece.power[row] = sum / system[row][row];
      }
      const auto& a = piece.power;
      for (int j = 0; j <= kTable; ++j) {
        const double x = static_cast<double>(j) / kTable;
        piece.table[static_cast<std::size_t>(j)] = x * (a[0] + x * (a[1] / 2 + x * (a[2] / 3 + x * (a[3] / 4))));
      }
      cumulative += width * (a[0] + a[1] / 2 + a[2] / 3 + a[3] / 4);
      piece.cumulative = cumulative;
      pieces_.push_back(piece);
    }
  }
  first_piece_[basis.size()] = static_cast<std::uint32_t>(pieces_.size());
}

double BasisSampler::mass(std::size_t k) const { return pieces_[first_piece_[k + 1] - 1].cumulative; }

double BasisSampler::sample(std::size_t k, double u1, double u2) const {
  const std::uint32_t begin = first_piece_[k];
  const std::uint32_t end = first_piece_[k + 1];
  const double total = pieces_[end - 1].cumulative;
  const double target = u1 * total;
  std::uint32_t i = begin;
  while (i + 1 < end && pieces_[i].cumulative <= target) ++i;
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

namespace {

// The storage nodes of a curve for about `wanted` elements: joints, element boundaries, then the
// extra nodes merged in. Returns the closing continuity (Jump on an open curve).
Continuity place_nodes(const Scene& scene, const Curve& curve, int wanted, bool smooth_joints,
                       std::span<const MeshNode> extra, std::vector<MeshNode>& nodes) {
  const std::uint32_t segment_count = curve.segment_count;
  nodes.clear();
  for (std::uint32_t i = 0; i < segment_count; ++i) {
    const SceneSegment& segment = scene.segments[curve.first_segment + i];
    if (i > 0)
      nodes.push_back({static_cast<double>(i), smooth_joints ? Continuity::C1 : curve.joints[i - 1]});
    const double share = wanted * segment.length / curve.length;
    const int pieces = std::max(1, static_cast<int>(std::lround(share)));
    for (int j = 1; j < pieces; ++j) {
      const double s = segment.length * j / pieces;
      const double t = segment.arc_length.parameter_at(segment.geometry.shape, s);
      nodes.push_back({i + t, Continuity::C1});
    }
  }
  Continuity closing = !curve.closed ? Continuity::Jump
                       : smooth_joints ? Continuity::C1
                                       : curve.joints.back();
  for (const MeshNode& node : extra) {
    // A node at the closing point of a closed curve lowers the closing joint's continuity.
    if (curve.closed && (std::fabs(node.u) <= 1e-9 || std::fabs(node.u - segment_count) <= 1e-9)) {
      closing = std::min(closing, node.continuity);
      continue;
    }
    if (!(node.u > 0.0 && node.u < segment_count)) continue;
    const auto at = std::lower_bound(nodes.begin(), nodes.end(), node.u,
                                     [](const MeshNode& a, double u) { return a.u < u; });
    auto merge = [&](std::vector<MeshNode>::iterator existing) {
      if (existing == nodes.end() || std::fabs(existing->u - node.u) > 1e-9) return false;
      existing->continuity = std::min(existing->continuity, node.continuity);
      return true;
    };
    if (merge(at) || (at != nodes.begin() && merge(at - 1))) continue;
    nodes.insert(at, node);
  }
  return closing;
}

}  // namespace

CurveStorage build_curve_storage(const Scene& scene, const Curve& curve, BasisKind kind,
                                 int elements, bool smooth_joints, std::span<const MeshNode> extra) {
  CurveStorage storage;
  const std::uint32_t segment_count = curve.segment_count;
  const int degree = degree_of(kind);
  int wanted = std::max(elements, 1);
  storage.closing = place_nodes(scene, curve, wanted, smooth_joints, extra, storage.nodes);
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
      wanted *= 2;
      storage.closing = place_nodes(scene, curve, wanted, smooth_joints, extra, storage.nodes);
    }
    storage.basis = SplineBasis::periodic(degree, 0.0, static_cast<double>(segment_count),
                                          storage.nodes, storage.closing);
  }

  // Integrals of phi_k |C'(u)| du: four 8-point Gauss-Legendre panels per span integrate the
  // polynomial-times-speed product to far below Monte Carlo noise.
  const int p = storage.basis.degree();
  const std::size_t n = storage.basis.size();
  storage.basis_length.assign(n, 0.0);
  for_each_quadrature_point(scene, curve, storage.basis,
                            [&](double, double weight, const auto& index, const auto& values) {
                              for (std::size_t j = 0; j <= static_cast<std::size_t>(p); ++j)
                                storage.basis_length[index[j]] += weight * values[j];
                            });
  storage.sampler = BasisSampler(storage.basis);

  // The mass matrix by the same quadrature, in envelope storage (row k from column
  // mass_first[k]), then its Cholesky factor in place: L has the same envelope as M. B-splines
  // more than p apart have disjoint supports, so a clamped basis is banded; on a periodic one the
  // functions straddling the closing point (the first p) meet the last p, whose rows then reach
  // back to column 0.
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
  for_each_quadrature_point(scene, curve, storage.basis,
                            [&](double, double weight, const auto& index, const auto& values) {
                              for (std::size_t i = 0; i <= pu; ++i)
                                for (std::size_t j = 0; j <= pu; ++j)
                                  if (index[j] <= index[i])
                                    entry(index[i], index[j]) += weight * values[i] * values[j];
                            });
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
  // Speed bound over each basis function's support: the largest bound of the segments it touches
  // (on a periodic basis the support may reach a period before or after [0, segment_count)).
  storage.speed_bound.assign(n, 0.0);
  const std::vector<double>& knots = storage.basis.knots();
  const double period = static_cast<double>(segment_count);
  for (std::size_t k = 0; k < n; ++k) {
    const double begin = knots[k];
    const double end = knots[k + pu + 1];
    for (std::uint32_t i = 0; i < segment_count; ++i)
      for (const double shift : {0.0, -period, period})
        if ((shift == 0.0 || storage.basis.is_periodic()) && i + 1.0 + shift > begin && i + shift < end)
          storage.speed_bound[k] = std::max(storage.speed_bound[k],
                                            scene.segments[curve.first_segment + i].speed_bound);
  }
  return storage;
}

std::vector<double> project_emittance_profile(const Scene& scene, const Curve& curve,
                                              const CurveStorage& storage) {
  if (curve.emittance_profile.empty()) return storage.basis_length;
  // The same quadrature as basis_length, with the profile (a cubic in t) in the integrand.
  std::vector<double> result(storage.basis.size(), 0.0);
  for_each_quadrature_point(scene, curve, storage.basis,
                            [&](double u, double weight, const auto& index, const auto& values) {
                              const double emitted = weight * emittance_factor(curve, u);
                              for (std::size_t j = 0; j <= static_cast<std::size_t>(storage.basis.degree()); ++j)
                                result[index[j]] += emitted * values[j];
                            });
  return result;
}

void galerkin_estimate(const CurveStorage& storage, const double* deposits, double* coefficients,
                       std::size_t stride) {
  const std::size_t n = storage.basis.size();
  auto factor = [&](std::size_t row, std::size_t col) {  // mass_first[row] <= col <= row
    return storage.mass_cholesky[storage.mass_offset[row] + col - storage.mass_first[row]];
  };
  // Forward substitution L y = d by rows, then back substitution L^T b = y by columns of L.
  std::vector<double> x(n);
  for (std::size_t row = 0; row < n; ++row) {
    double sum = deposits[row * stride];
    for (std::size_t col = storage.mass_first[row]; col < row; ++col) sum -= factor(row, col) * x[col];
    x[row] = sum / factor(row, row);
  }
  for (std::size_t row = n; row-- > 0;) {
    x[row] /= factor(row, row);
    for (std::size_t col = storage.mass_first[row]; col < row; ++col) x[col] -= factor(row, col) * x[row];
  }
  // Clamp and renormalise so the power in the function equals the power deposited.
  double deposited = 0.0;
  double kept = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    deposited += deposits[k * stride];
    x[k] = std::max(x[k], 0.0);
    kept += x[k] * storage.basis_length[k];
  }
  const double rescale = kept > 0.0 ? deposited / kept : 0.0;
  for (std::size_t k = 0; k < n; ++k) coefficients[k * stride] = x[k] * rescale;
}

}  // namespace flatland
