#include "flatland/discontinuity.hpp"

#include <algorithm>

namespace flatland {

const char* to_string(DiscontinuityMode mode) {
  switch (mode) {
    case DiscontinuityMode::None: return "none";
    case DiscontinuityMode::Scene: return "scene";
    case DiscontinuityMode::Auto: return "auto";
  }
  return "?";
}

namespace {

// A vertex of the scene: a curve end or a corner joint, with a segment it lies on.
struct Vertex {
  Vec2 position;
  std::uint32_t curve = 0;
  std::uint32_t segment = 0;  // index into Scene::segments
  double t = 0.0;             // 0 or 1 on that segment
};

std::vector<Vertex> vertices_of(const Scene& scene, std::uint32_t c) {
  const Curve& curve = scene.curves[c];
  std::vector<Vertex> out;
  const std::uint32_t first = curve.first_segment;
  const std::uint32_t last = first + curve.segment_count - 1;
  out.push_back({scene.segments[first].geometry.shape.p[0], c, first, 0.0});
  for (std::uint32_t j = 0; j + 1 < curve.segment_count; ++j)
    if (!is_tangent_continuous(scene, curve, j))
      out.push_back({scene.segments[first + j].geometry.shape.p[3], c, first + j, 1.0});
  if (!(scene.segments[last].geometry.shape.p[3] == out.front().position))  // open curve
    out.push_back({scene.segments[last].geometry.shape.p[3], c, last, 1.0});
  return out;
}

}  // namespace

std::vector<DiscontinuityNode> find_visibility_events(const Scene& scene,
                                                      const SegmentAccelerator& accelerator) {
  std::vector<Vertex> emitters;
  std::vector<Vertex> all;
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    std::vector<Vertex> vertices = vertices_of(scene, c);
    if (scene.is_emitter(scene.curves[c])) emitters.insert(emitters.end(), vertices.begin(), vertices.end());
    all.insert(all.end(), vertices.begin(), vertices.end());
  }
  // Points closer than this count as the same (relative to the scene's size).
  const double same = 1e-12 * scene.scale;
  std::vector<DiscontinuityNode> nodes;
  for (const Vertex& e : emitters) {
    for (const Vertex& o : all) {
      const Vec2 offset = o.position - e.position;
      const double distance = length(offset);
      if (distance <= same) continue;
      const Vec2 direction = (1.0 / distance) * offset;
      // Does E see O? Nothing may be hit before O (a hit at O itself is O's own curve).
      const SceneHit blocker = accelerator.closest_hit(Ray{e.position, direction},
                                                       RayOrigin{e.segment, e.t});
      if (blocker.segment != kNoSegment && blocker.distance < distance - same) continue;
      // Past O, the first surface hit gets a kink.
      const SceneHit hit =
          accelerator.closest_hit(Ray{o.position, direction}, RayOrigin{o.segment, o.t});
      if (hit.segment == kNoSegment) continue;
      const SceneSegment& segment = scene.segments[hit.segment];
      nodes.push_back({segment.curve, segment.index_in_curve + hit.t, Continuity::C0});
    }
  }
  std::sort(nodes.begin(), nodes.end(), [](const DiscontinuityNode& a, const DiscontinuityNode& b) {
    return a.curve < b.curve || (a.curve == b.curve && a.u < b.u);
  });
  return nodes;
}

}  // namespace flatland
