// Ray queries against single segments. A ray is o + sigma d with d of unit length and sigma > 0.
//
// Cubic: with m = perp(d), f(t) = m . (C(t) - o) is a cubic in Bernstein form whose coefficients
// are the control points' signed distances to the ray's line. Roots of f in [0,1] where f changes
// sign are crossings; a double root without a sign change (tangency) is a miss everywhere. The hit
// distance is sigma = d . (C(t) - o).
#pragma once

#include <cstdint>

#include "flatland/base/vec2.hpp"
#include "flatland/geometry/bezier.hpp"

namespace flatland {

struct Ray {
  Vec2 origin;
  Vec2 direction;  // unit length
};

struct SegmentHit {
  double distance = 0.0;  // sigma > 0 along the ray
  double t = 0.0;         // parameter on the segment, in [0,1]
};

// Nearest crossing of the straight segment a-b with distance in (0, max_distance); closed form.
// A ray through an end point hits (t is 0 or 1), so rays through joints are never lost.
bool intersect_line(Vec2 a, Vec2 b, const Ray& ray, double max_distance, SegmentHit* hit);

// Nearest crossing of the cubic with distance in (0, max_distance). As for lines, an end point on
// the ray's line is a hit, judged by the same arithmetic as in the neighbouring segment.
bool intersect_cubic(const Cubic& c, const Ray& ray, double max_distance, SegmentHit* hit);

// As intersect_cubic, for a ray that leaves the cubic itself at parameter t_origin (the ray's
// origin is C(t_origin)): the root at t_origin is deflated away exactly, f(t) = (t - t_origin) g(t),
// and only the roots of the quadratic g count, so a concave cubic can light itself without any
// fixed epsilon.
bool intersect_cubic_from(const Cubic& c, double t_origin, const Ray& ray, double max_distance, SegmentHit* hit);

}  // namespace flatland
