// The footprint deposit of a single centre ray of width W (docs/method.md): its weights on a
// curve's storage basis, and the per-span table that serves the polynomial profiles.
//
// Footprint mode traces the centre ray only. At a hit with incidence cosine |cos theta_in| the
// beam covers arc length s_hit +- a on the receiver, a = W / (2 |cos theta_in|), with density
// k((s - s_hit) / a) / a; the photon's power goes to the storage coefficients with the weights
// w_k = integral of that spread times phi_k(u(s)) ds, normalised to sum to 1.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "flatland/base/status.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/storage/curve_storage.hpp"
#include "flatland/transport/ray_profiles.hpp"

namespace flatland {

// Below this incidence cosine (87.1 degrees from the normal) the footprint stops growing: the
// half-length a = W / (2 |cos theta_in|) is capped at W / (2 kGrazingCosine) = 10 W. At grazing
// incidence the centre ray's footprint is a poor model anyway (the beam's edges hit elsewhere on a
// curved or finite receiver), and the cap bounds the number of knot spans one deposit visits.
inline constexpr double kGrazingCosine = 0.05;
// a = W / (2 max(|cos theta_in|, kGrazingCosine)); a NaN cosine counts as grazing.
double footprint_half_length(double width, double cos_incidence);

struct FootprintWeight {
  std::size_t coefficient = 0;  // index into the curve's basis
  double weight = 0.0;
};

// The powers of y a polynomial profile needs on one side of its centre: box 1 (constant), tent 2
// (linear), Epanechnikov 3 (quadratic); 0 for the others.
int profile_powers(RayProfile profile);

// Per knot span of a storage basis, what a footprint needs to deposit a polynomial profile (box,
// tent, Epanechnikov) without quadrature or arc-length inversions.
//
// Whole spans: the span's arc length 2h and the moments M_j[r] = integral over the span of
// y^j phi_r(u) ds, j = 0, 1, 2, with y = (s - s_mid) / h in [-1, 1] and phi_r the span's degree + 1
// basis functions (r = 0 is function span - degree). On such a span the profile is
// c0 + c1 y + c2 y^2, so its weights are c0 M_0 + c1 M_1 + c2 M_2: a footprint covering many spans
// costs a few multiply-adds per span instead of Gauss points with a Cox-de Boor recursion each.
// The moments are integrated once, on the same Gauss-Legendre panels as the footprint's own
// quadrature (finer on cubics), so weights agree with it to rounding.
//
// Partial spans (where a footprint begins, ends or has its centre): on each span the table keeps
// the arc length from the curve's start to the span's start, and Chebyshev series of
//   K_j,r(y) = h * integral from -1 to y of t^j phi_r(u(t)) dt,   j < powers,
// the running moments in the arc-length coordinate, so a part [ya, yb] of a span weighs
// sum_j c_j (K_j,r(yb) - K_j,r(ya)): no square roots, no Newton steps. On a cubic the series come
// from interpolating phi_r(u(y)) at Chebyshev-Lobatto points (7 to 33, the fewest whose
// coefficients have decayed below 1e-14 of the span, checked again between the points), on a line they are
// exact. A span where 33 points do not suffice (a near-cusp) keeps no series, and footprints fall
// back to quadrature there. A further series gives s(u) on the span, for the hit's own arc length.
class FootprintTable {
 public:
  FootprintTable() = default;
  // `powers` (1 to 3): the running moments kept for partial spans, profile_powers of the profile
  // the table will serve (box 1, tent 2, Epanechnikov 3).
  FootprintTable(const Scene& scene, const Curve& curve, const SplineBasis& basis, int powers = 3);

  bool empty() const { return length_.empty(); }
  // Span `span` (first_span() <= span < end_span() of the basis it was built for).
  double length(std::size_t span) const { return length_[span - first_]; }
  const double* moments(std::size_t span) const { return moments_.data() + (span - first_) * 3 * stride_; }
  std::size_t stride() const { return stride_; }  // degree + 1: M_j[r] is moments(span)[j * stride + r]
  // Whether it was built for a basis of this shape (its spans and degree).
  bool matches(const SplineBasis& basis) const {
    return first_ == basis.first_span() && length_.size() == basis.end_span() - first_ &&
           stride_ == static_cast<std::size_t>(basis.degree()) + 1;
  }
  int powers() const { return powers_; }

  // Arc length from the curve's start to the start of span `span` (end_span() gives the curve's
  // length): nondecreasing, equal across an empty span.
  double start(std::size_t span) const { return start_[span - first_]; }
  // The span holding arc length s: the last non-empty span with start(span) <= s (clamped to
  // the curve).
  std::size_t span_at(double s) const;

  // The running-moment series of a span: nullptr when it has none, else `terms` coefficients per
  // (j, r), laid out [term][j][r] (powers() * stride() values per term).
  bool has_series(std::size_t span) const { return series_[span - first_].terms != 0; }
  const double* running(std::size_t span, std::size_t& terms) const {
    const Series& series = series_[span - first_];
    terms = series.terms;
    return series.terms == 0 ? nullptr : coefficients_.data() + series.offset;
  }
  // The arc length from the curve's start at u in span `span` (knots[span] <= u <=
  // knots[span + 1]), from the span's series; NaN when the span has none.
  double arc_length_in_span(std::size_t span, double u) const;
  // is_tangent_continuous(scene, curve, joint), kept per joint (the closing one last).
  bool smooth_joint(std::uint32_t joint) const { return smooth_joints_[joint]; }

 private:
  struct Series {
    std::size_t offset = 0;   // into coefficients_: the running moments, then s(v)
    std::uint32_t terms = 0;  // per running moment; 0: no series
    std::uint32_t length_terms = 0;
    double u_mid = 0.0;
    double inverse_half_u = 0.0;
  };

  void build_series(const Scene& scene, const Curve& curve, const SplineBasis& basis);

  std::size_t first_ = 0;
  std::size_t stride_ = 1;
  int powers_ = 3;
  std::vector<double> length_;
  std::vector<double> moments_;
  std::vector<double> start_;
  std::vector<Series> series_;
  std::vector<double> coefficients_;
  std::vector<bool> smooth_joints_;
};

// Appends to `out` the weights of the spread of half-length `half_length` (arc length) centred at
// curve parameter u_hit (segment index + t) on `curve`, deposited on `basis` (the curve's storage
// basis in u). The appended weights are > 0, sum to 1 (to the last bit or two: the rounding
// residual goes to the largest weight) and name each coefficient once, in increasing order.
//
// The spread continues into a neighbouring segment only across a tangent-continuous joint (unit
// tangents within 1e-9 radians, from the geometry, whatever continuity the storage mesh chose),
// on a closed curve across its closing point too, all round a loop that is smooth everywhere. At
// a corner or at the curve's ends the part that would fall beyond is reflected back about that
// end: energy stays exact, a uniform incident flux is deposited uniformly right up to the end,
// and a linear one with an error O(W^2) in every coefficient. A hit exactly on a joint belongs to
// the segment that starts there. half_length = +infinity spreads uniformly over the
// tangent-continuous run; half_length <= 0 or NaN, or a footprint too small to resolve in u,
// deposits at the point (weights phi_k(u_hit)), the limit a -> 0.
//
// Allocation-free apart from growing `out` (the caller clears and reuses it).
//
// `walls` (arc lengths from the curve's start, increasing) end the spread like corners do: the
// solver passes the contacts, where another curve stands on this one and the light on the two
// sides is unrelated.
//
// `table` (optional; built for `basis`) serves the polynomial profiles whose powers it keeps
// (profile_powers): whole and partial knot spans then cost no quadrature. Other profiles, or a
// table with too few powers, take the quadrature everywhere.
void footprint_weights(const Scene& scene, const Curve& curve, const SplineBasis& basis, double u_hit,
                       double half_length, RayProfile profile, std::vector<FootprintWeight>& out,
                       std::span<const double> walls = {}, const FootprintTable* table = nullptr);

}  // namespace flatland
