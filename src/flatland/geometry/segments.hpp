// The scene's segments as the ray caster sees them: a line or a cubic, a hit on one, and where a
// ray starts.
#pragma once

#include <cstdint>

#include "flatland/geometry/bezier.hpp"

namespace flatland {

enum class SegmentKind : std::uint8_t { Line, Cubic };

// What the ray caster needs of a segment. Lines keep their end points in shape.p[0] and p[3].
struct SegmentGeometry {
  SegmentKind kind = SegmentKind::Line;
  Cubic shape;
};

constexpr std::uint32_t kNoSegment = 0xffffffffu;

struct SceneHit {
  std::uint32_t segment = kNoSegment;
  double t = 0.0;
  double distance = 0.0;
};

// Where a ray starts: on a segment (so that segment is tested with the deflated query, and a line
// never hits itself) or in free space (segment = kNoSegment).
struct RayOrigin {
  std::uint32_t segment = kNoSegment;
  double t = 0.0;
};

// The segment's bounding box: its two ends for a line, the curve's tight box (end points and the
// extrema of x(t) and y(t)) for a cubic.
Box segment_box(const SegmentGeometry& g);

}  // namespace flatland
