#include "flatland/storage/spline_basis.hpp"

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

SplineBasis::SplineBasis(int degree, double u_begin, double u_end, std::span<const MeshNode> nodes) : degree_(degree) {
  assert(degree >= 0 && degree <= kMaxDegree && u_begin < u_end);
  knots_.assign(static_cast<std::size_t>(degree + 1), u_begin);
  for (const MeshNode& node : nodes) {
    assert(node.u > u_begin && node.u < u_end);
    knots_.insert(knots_.end(), static_cast<std::size_t>(multiplicity(degree, node.continuity)), node.u);
  }
  knots_.insert(knots_.end(), static_cast<std::size_t>(degree + 1), u_end);
  size_ = knots_.size() - static_cast<std::size_t>(degree) - 1;
  build_span_grid();
}

SplineBasis SplineBasis::periodic(int degree, double u_begin, double u_end, std::span<const MeshNode> nodes,
                                  Continuity closing) {
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
  // The span holding x by bisection over the knots; the grid caches its answers.
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
      cell_spans_.push_back(
          static_cast<std::uint32_t>(bisect(lo + static_cast<double>(c) / static_cast<double>(cells))));
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

}  // namespace flatland
