// The running answer of a nearest-hit query, shared by every caster (accelerator.cpp,
// line_space.cpp) so that they agree bit for bit with the brute force.
#pragma once

#include <cstdint>
#include <limits>

#include "flatland/base/bits.hpp"
#include "flatland/geometry/intersect.hpp"
#include "flatland/geometry/segments.hpp"

namespace flatland::detail {

// One segment against the ray. The origin segment is special: a straight line cannot see itself,
// and a cubic deflates the root at the origin's parameter (a concave cubic lights itself).
inline bool test_geometry(const SegmentGeometry& g, bool is_origin, double t_origin, const Ray& ray,
                          double max_distance, SegmentHit* hit) {
  if (g.kind == SegmentKind::Line) {
    return !is_origin && intersect_line(g.shape.p[0], g.shape.p[3], ray, max_distance, hit);
  }
  return is_origin ? intersect_cubic_from(g.shape, t_origin, ray, max_distance, hit)
                   : intersect_cubic(g.shape, ray, max_distance, hit);
}

// Segments are tested with the limit just above the best distance so that an equal distance (a ray
// through a joint hits both segments there) is still reported, and ties go to the smaller index:
// the answer is then the same whatever order the segments are visited in, so every caster and the
// linear scan agree bit for bit.
struct Nearest {
  SceneHit hit{kNoSegment, 0.0, std::numeric_limits<double>::infinity()};
  double limit = std::numeric_limits<double>::infinity();

  void consider(std::uint32_t index, const SegmentGeometry& g, const Ray& ray, const RayOrigin& from) {
    SegmentHit h;
    if (!test_geometry(g, index == from.segment, from.t, ray, limit, &h)) return;
    if (h.distance < hit.distance || (h.distance == hit.distance && index < hit.segment)) {
      hit.segment = index;
      hit.t = h.t;
      hit.distance = h.distance;
      // The next double up: h.distance is positive and finite, so that is its bits plus one
      // (std::nextafter is a library call, once per accepted hit).
      limit = bit_cast<double>(bit_cast<std::uint64_t>(h.distance) + 1);
    }
  }

  SceneHit answer() const { return hit.segment == kNoSegment ? SceneHit{} : hit; }
};

}  // namespace flatland::detail
