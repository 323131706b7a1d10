// Where illumination is not smooth, found from the geometry (flatland discontinuity meshing, after
// Heckbert 1992): a receiver sees an emitter's end point appear or vanish behind an occluder's
// vertex along the line through the two. Along that line, past the occluder vertex, the irradiance
// on the first surface hit has a kink (a C0 node: value continuous, slope not).
#pragma once

#include <cstdint>
#include <vector>

#include "flatland/bvh.hpp"
#include "flatland/scene.hpp"

namespace flatland {

// Which nodes the storage mesh gets: none (every joint C1, the smooth baseline), the joints as the
// scene file sets them (by default C-1 at corners, C1 at tangent joints), or those joints plus C0
// nodes at the visibility events found below.
enum class DiscontinuityMode { None, Scene, Auto };
const char* to_string(DiscontinuityMode mode);

struct DiscontinuityNode {
  std::uint32_t curve = 0;
  double u = 0.0;  // curve parameter: segment index + t
  Continuity continuity = Continuity::C0;
};

// For every end point or corner E of an emitting curve and every end point or corner O of any
// curve that E sees unoccluded, the first surface hit by the ray from O away from E gets a C0 node
// there. Sorted by curve, then u.
std::vector<DiscontinuityNode> find_visibility_events(const Scene& scene,
                                                      const SegmentAccelerator& accelerator);

}  // namespace flatland
