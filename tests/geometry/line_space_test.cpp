#include "flatland/geometry/line_space.hpp"

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/geometry/accelerator.hpp"
#include "geometry/random_segments.hpp"

namespace flatland {
namespace {

using namespace flatland::test;

// Against the brute force (every segment tested): the same segment, parameter and distance, bit
// for bit, on random scenes at four scales and offsets and for grids from one cell to many.
TEST(LineSpace, ClosestHitEqualsBruteForceOnRandomScenes) {
  struct Setting {
    double scale;
    Vec2 offset;
  };
  const Setting settings[] = {{1.0, {0, 0}}, {1e-6, {0, 0}}, {1e6, {0, 0}}, {1.0, {1e6, -1e6}}};
  // No cell limit: the grid answers every ray itself.
  constexpr int kAll = 1 << 30;
  const LineSpaceCaster::Shape shapes[] = {{1, 1, kAll}, {3, 7, kAll}, {64, 32, kAll}, {512, 128, kAll}};
  std::uint64_t seed = 500;
  for (const Setting& setting : settings) {
    for (const LineSpaceCaster::Shape& shape : shapes) {
      std::mt19937_64 rng(seed++);
      const std::vector<SegmentGeometry> scene = random_scene(rng, 200, setting.scale, setting.offset);
      const SegmentAccelerator brute(scene);
      const LineSpaceCaster grid(scene, shape);
      ASSERT_EQ(grid.cells_left(), 0u);
      int hits = 0;
      int self_hits = 0;
      for (int i = 0; i < 4000; ++i) {
        const Query q = random_query(rng, scene, setting.scale, setting.offset);
        const SceneHit fast = grid.closest_hit_or_scan(q.ray, q.from);
        expect_same(fast, brute.closest_hit_brute_force(q.ray, q.from), i);
        if (fast.segment != kNoSegment) {
          ++hits;
          self_hits += fast.segment == q.from.segment;
        }
      }
      EXPECT_GT(hits, 2000);
      EXPECT_GT(self_hits, 4);  // concave loops light themselves through the grid as well
    }
  }
}

// Rays from far outside (1e3 scene sizes: most lines miss the scene's disc and are answered
// without a test), axis-parallel rays, and rays along straight segments and through their joints.
TEST(LineSpace, FarAxisAndGrazingRaysEqualBruteForce) {
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<SegmentGeometry> scene = random_scene(rng, 200, 1.0, {0, 0});
  // A grid of lines whose joints lie on axis-parallel and diagonal rays.
  for (int k = 0; k < 5; ++k)
    for (int m = 0; m < 5; ++m) {
      scene.push_back(line({2.0 + k, 2.0 + m}, {3.0 + k, 2.0 + m}));
      scene.push_back(line({2.0 + k, 2.0 + m}, {2.0 + k, 3.0 + m}));
    }
  const SegmentAccelerator brute(scene);
  const LineSpaceCaster grid(scene, {128, 128, 1 << 30});
  int hits = 0;
  for (int i = 0; i < 20000; ++i) {
    Ray ray;
    if (i % 2 == 0) {
      const double distance = i % 4 == 0 ? 4.0 : 1e3;
      const double angle = 2.0 * std::numbers::pi * unit(rng);
      const Vec2 target{unit(rng), unit(rng)};
      ray.origin = target + distance * Vec2{std::cos(angle), std::sin(angle)};
      ray.direction = normalized(target - ray.origin);
    } else {  // from a grid point along an axis or a diagonal, through joints
      const Vec2 at{1.0 + static_cast<int>(unit(rng) * 7), 1.0 + static_cast<int>(unit(rng) * 7)};
      const int way = static_cast<int>(unit(rng) * 8);
      const Vec2 ways[] = {{1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}, {-1, 1}, {1, -1}, {-1, -1}};
      ray = Ray{at, normalized(ways[way])};
    }
    const SceneHit fast = grid.closest_hit_or_scan(ray, RayOrigin{});
    expect_same(fast, brute.closest_hit_brute_force(ray, RayOrigin{}), i);
    hits += fast.segment != kNoSegment;
  }
  EXPECT_GT(hits, 5000);
}

// From one segment to 65,536 (against the BVH, itself checked against the brute force in
// accelerator_test): the grid's answers do not depend on the scene's size. Without a cell limit
// (up to 4,096 segments) the grid answers every ray; with the default limit, dense cells are left to
// another caster (the rays it does not answer) and its memory stays within its bound: angle_bins x
// offset_cells x (cell_limit x 12 + 8) bytes, and the segments.
TEST(LineSpace, ScenesFromOneTo65536SegmentsWithBoundedMemory) {
  std::uint64_t seed = 900;
  for (const int n : {1, 2, 9, 100, 4096, 65536}) {
    std::mt19937_64 rng(seed++);
    std::vector<SegmentGeometry> scene = random_scene(rng, n);
    scene.resize(static_cast<std::size_t>(n));
    const SegmentAccelerator tree(scene);
    const LineSpaceCaster::Shape shape{};
    const LineSpaceCaster limited(scene, shape);
    const auto cells = static_cast<std::size_t>(shape.angle_bins) * static_cast<std::size_t>(shape.offset_cells);
    EXPECT_LE(limited.memory_bytes(), cells * (static_cast<std::size_t>(shape.cell_limit) * 12 + 8) +
                                          scene.size() * sizeof(SegmentGeometry) + 8);
    if (n >= 4096) {
      EXPECT_GT(limited.cells_left(), 0u);
    }
    const LineSpaceCaster unlimited = n <= 4096 ? LineSpaceCaster(scene, {64, 256, 1 << 30}) : LineSpaceCaster();
    const int rays = n > 4096 ? 2000 : 4000;
    int answered = 0;
    for (int i = 0; i < rays; ++i) {
      const Query q = random_query(rng, scene, 1.0, {0, 0});
      const SceneHit expected = tree.closest_hit_tree(q.ray, q.from);
      SceneHit hit;
      if (limited.closest_hit(q.ray, q.from, &hit)) {
        ++answered;
        expect_same(hit, expected, i);
      }
      if (n <= 4096) {
        ASSERT_TRUE(unlimited.closest_hit(q.ray, q.from, &hit));
        expect_same(hit, expected, i);
      }
    }
    if (n <= 100) {
      EXPECT_EQ(answered, rays);
    }
  }
}

TEST(LineSpace, TiesAtJointsAndLinesThatCannotSeeThemselves) {
  // Two cubics meeting at (3,1), hit exactly at the joint by a vertical ray: the smaller index.
  const std::vector<SegmentGeometry> joint = {cubic({3, 1}, {4, 0}, {5, 0}, {6, 1}),
                                              cubic({0, 0}, {1, 2}, {2, 2}, {3, 1})};
  const SceneHit hit = LineSpaceCaster(joint, {}).closest_hit_or_scan(Ray{{3.0, -5.0}, {0.0, 1.0}}, RayOrigin{});
  EXPECT_EQ(hit.segment, 0u);
  EXPECT_EQ(hit.t, 0.0);
  EXPECT_EQ(hit.distance, 6.0);
  // A lone line: rays from it in any direction (also along it) hit nothing.
  const std::vector<SegmentGeometry> single = {line({0, 0}, {1, 0})};
  const LineSpaceCaster lone(single, {});
  for (Vec2 d : {Vec2{0, 1}, Vec2{0, -1}, Vec2{1, 0}, Vec2{-1, 0}, normalized(Vec2{1, 1})})
    EXPECT_EQ(lone.closest_hit_or_scan(Ray{{0.5, 0.0}, d}, RayOrigin{0, 0.5}).segment, kNoSegment);
}

// No extent (every control point the same), no segments, and a ray with no direction: answered
// by testing every segment, as the brute force does.
TEST(LineSpace, DegenerateScenesAndRays) {
  const LineSpaceCaster empty(std::vector<SegmentGeometry>{}, {});
  EXPECT_EQ(empty.closest_hit_or_scan(Ray{{0, 0}, {1, 0}}, RayOrigin{}).segment, kNoSegment);
  const std::vector<SegmentGeometry> points = {line({1, 1}, {1, 1}), cubic({1, 1}, {1, 1}, {1, 1}, {1, 1})};
  const SegmentAccelerator brute(points);
  const LineSpaceCaster grid(points, {});
  EXPECT_EQ(grid.entries(), 0u);
  for (const Ray& ray : {Ray{{0, 1}, {1, 0}}, Ray{{0, 0}, normalized(Vec2{1, 1})}, Ray{{0, 0}, {0, 0}}})
    expect_same(grid.closest_hit_or_scan(ray, RayOrigin{}), brute.closest_hit_brute_force(ray, RayOrigin{}), 0);
  std::mt19937_64 rng(3);
  const std::vector<SegmentGeometry> scene = random_scene(rng, 20);
  const SegmentAccelerator scene_brute(scene);
  const LineSpaceCaster scene_grid(scene, {});
  for (const Vec2 d : {Vec2{0, 0}, Vec2{NAN, 0}, Vec2{INFINITY, 0}})
    expect_same(scene_grid.closest_hit_or_scan(Ray{{0, 0}, d}, RayOrigin{}),
                scene_brute.closest_hit_brute_force(Ray{{0, 0}, d}, RayOrigin{}), 0);
}

}  // namespace
}  // namespace flatland
