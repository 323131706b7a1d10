// Cubic Bezier segments: evaluation, derivatives, subdivision, bounds, arc length and its inverse.
// Small free functions over a Cubic, each handling its degenerate cases (coincident control points,
// collinear "cubics" that are really lines). A straight segment is stored as the cubic with its
// inner control points at the thirds, so every generic routine applies to it too; the fast paths
// for lines live in the callers.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <utility>

#include "flatland/base/vec2.hpp"

namespace flatland {

struct Cubic {
  std::array<Vec2, 4> p;
};

// The cubic that traces the straight segment a-b at constant speed.
Cubic line_as_cubic(Vec2 a, Vec2 b);

// C(t) = sum_i B_i^3(t) P_i by de Casteljau (stable for t in [0,1]).
Vec2 evaluate(const Cubic& c, double t);
// C'(t) = 3 sum_i B_i^2(t) (P_(i+1) - P_i).
Vec2 derivative(const Cubic& c, double t);
// C''(t) = 6 sum_i B_i^1(t) (P_(i+2) - 2 P_(i+1) + P_i).
Vec2 second_derivative(const Cubic& c, double t);

// Unit tangent at t. Where C'(t) vanishes (coincident end control points) it takes the direction
// of the first non-vanishing derivative, which is the limit of C'(t)/|C'(t)| from inside (0,1).
// `scale` is the scene's size (Scene::scale); a derivative of norm <= 1e-12 scale counts as zero.
Vec2 unit_tangent(const Cubic& c, double t, double scale);
// The front normal: the tangent rotated +90 degrees (left of the direction of travel).
Vec2 unit_normal(const Cubic& c, double t, double scale);

// The two halves of c split at t (de Casteljau).
std::pair<Cubic, Cubic> split(const Cubic& c, double t);
// The piece of c between parameters t0 < t1, reparametrised to [0,1].
Cubic subsegment(const Cubic& c, double t0, double t1);

// Bounding box of the control points (contains the curve: convex hull property).
Box hull_bounds(const Cubic& c);
// Tight bounding box: end points and the interior extrema of x(t) and y(t).
Box tight_bounds(const Cubic& c);

// An upper bound of |C'(t)| on [0,1] that is within a few percent of the true maximum
// (hull bounds of the derivative's quadratic Bezier over a few subintervals).
double speed_bound(const Cubic& c);
// The same on [t0, t1] (0 <= t0 <= t1 <= 1): the hull bounds of the derivative's restriction to
// each of a few subintervals (the same as speed_bound(c) on [0, 1]).
double speed_bound(const Cubic& c, double t0, double t1);

// Arc length of c between t0 and t1 (t0 <= t1), adaptive Gauss-Legendre on |C'(t)| to a relative
// accuracy of about 1e-13.
double arc_length(const Cubic& c, double t0 = 0.0, double t1 = 1.0);

// The point of c (t in [0,1]) nearest to p: the nearest of 32 uniform samples, refined by Newton on
// g(t) = C'(t) . (C(t) - p), half the derivative of the squared distance, kept inside the samples'
// bracket (a few steps reach rounding: g is smooth and the start is close); an end of the curve
// wins when it is nearer.
struct CubicPoint {
  double t = 0.0;
  double distance = 0.0;
};
CubicPoint closest_point_on_cubic(const Cubic& c, Vec2 p);
// closest_point_on_cubic(c, p).distance.
double distance_to_cubic(const Cubic& c, Vec2 p);

// An interior parameter t in (0,1) where C'(t) = 0 (a cusp, where the normal flips), if any.
// `scale` is the scene's size; |C'| <= 1e-12 scale counts as zero (the threshold of unit_tangent).
std::optional<double> find_cusp(const Cubic& c, double scale);

// Arc length as a function of t and its inverse, for one segment. A table of cumulative lengths
// at uniform parameters brackets the answer; Newton with bisection fallback refines it.
class ArcLengthTable {
 public:
  ArcLengthTable() = default;
  explicit ArcLengthTable(const Cubic& c);

  double total() const { return lengths_.back(); }
  // s(t): arc length from 0 to t.
  double length_at(const Cubic& c, double t) const;
  // t(s): the parameter where the arc length from 0 equals s (clamped to [0, total]).
  double parameter_at(const Cubic& c, double s) const;

 private:
  static constexpr int kIntervals = 16;
  // Arc length from the knot k/16 to t (t in that interval).
  double length_from_knot(const Cubic& c, int k, double t) const;

  std::array<double, kIntervals + 1> lengths_{};
  std::array<double, kIntervals + 1> speeds_{};  // |C'| at the knots: parameter_at's first guess
  // Bit k set: |C'| is smooth enough on interval k that one 8-point Gauss-Legendre rule gives the
  // length of any part of it to full accuracy (checked when the table is built).
  std::uint32_t smooth_ = 0;
};

}  // namespace flatland
