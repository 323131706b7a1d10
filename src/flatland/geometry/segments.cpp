#include "flatland/geometry/segments.hpp"

namespace flatland {

Box segment_box(const SegmentGeometry& g) {
  if (g.kind == SegmentKind::Line) {
    Box box;
    box.extend(g.shape.p[0]);
    box.extend(g.shape.p[3]);
    return box;
  }
  // The curve's own extent, not its control points' (a bulging cubic's hull box can be twice as
  // tall as the curve): fewer rays reach its test. Rounding of the extrema is a few ulps, far
  // inside the tree's padding.
  return tight_bounds(g.shape);
}

}  // namespace flatland
