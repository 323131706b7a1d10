#include "flatland/discontinuity.hpp"

#include <vector>

#include <gtest/gtest.h>

#include "test_support.hpp"

namespace flatland {
namespace {

std::vector<SegmentGeometry> geometry_of(const Scene& scene) {
  std::vector<SegmentGeometry> geometry;
  for (const SceneSegment& segment : scene.segments) geometry.push_back(segment.geometry);
  return geometry;
}

TEST(Discontinuity, PenumbraEventsSitWhereEmitterAndOccluderEndsLineUp) {
  // Emitter ends (+-0.5, 2), occluder ends (-0.1, 1) and (0.7, 1), floor y = 0 from -3 to 3: the
  // line through E and O meets the floor at x = E.x + 2 (O.x - E.x).
  const Scene scene = testing::scene_from_file("scenes2d/penumbra.json");
  const SegmentAccelerator accelerator(geometry_of(scene));
  const std::vector<DiscontinuityNode> nodes = find_visibility_events(scene, accelerator);
  std::vector<double> floor_x;
  for (const DiscontinuityNode& node : nodes) {
    ASSERT_EQ(scene.curves[node.curve].id, "receiver");
    EXPECT_EQ(node.continuity, Continuity::C0);
    floor_x.push_back(-3.0 + 6.0 * node.u);
  }
  const std::vector<double> expected = {0.5 + 2 * (-0.1 - 0.5), -0.5 + 2 * (-0.1 + 0.5),
                                        0.5 + 2 * (0.7 - 0.5), -0.5 + 2 * (0.7 + 0.5)};
  ASSERT_EQ(floor_x.size(), 4u);
  std::vector<double> sorted = expected;
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t i = 0; i < 4; ++i) EXPECT_NEAR(floor_x[i], sorted[i], 1e-12);
}

TEST(Discontinuity, HiddenVerticesMakeNoEvents) {
  // A wall between the lamp and the occluder's left end hides it from the lamp's right end only.
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 1,
    "materials": {"lamp": {"emittance": 1}, "black": {}, "floor": {"reflectivity": 0.5}},
    "curves": [
      {"id": "lamp", "material": "lamp", "line": [[0.5,2],[-0.5,2]]},
      {"id": "occluder", "material": "black", "line": [[-0.1,1],[0.7,1]]},
      {"id": "wall", "material": "black", "line": [[0.2,1.6],[0.2,1.4]]},
      {"id": "floor", "material": "floor", "line": [[-3,0],[3,0]]}]})");
  const SegmentAccelerator accelerator(geometry_of(scene));
  // The ray from (0.5, 2) to (-0.1, 1) passes x = 0.2 at y = 1.5: blocked.
  for (const DiscontinuityNode& node : find_visibility_events(scene, accelerator)) {
    if (scene.curves[node.curve].id != "floor") continue;
    EXPECT_GT(std::fabs(-3.0 + 6.0 * node.u - (-0.7)), 1e-6) << "event of a hidden vertex";
  }
}

TEST(Discontinuity, ConvexEnclosureHasNoEvents) {
  const Scene scene = testing::scene_from_file("scenes2d/enclosure.json");
  const SegmentAccelerator accelerator(geometry_of(scene));
  EXPECT_TRUE(find_visibility_events(scene, accelerator).empty());
}

}  // namespace
}  // namespace flatland
