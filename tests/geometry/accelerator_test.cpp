#include "flatland/geometry/accelerator.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "geometry/random_segments.hpp"

namespace flatland {
namespace {

using namespace flatland::test;

TEST(Bvh, ClosestHitEqualsBruteForceOnRandomScenes) {
  struct Setting {
    double scale;
    Vec2 offset;
  };
  const Setting settings[] = {{1.0, {0, 0}}, {1e-6, {0, 0}}, {1e6, {0, 0}}, {1.0, {1e6, -1e6}}};
  std::uint64_t seed = 200;
  for (const Setting& setting : settings) {
    for (int scene_index = 0; scene_index < 3; ++scene_index) {
      std::mt19937_64 rng(seed++);
      const std::vector<SegmentGeometry> scene = random_scene(rng, 200, setting.scale, setting.offset);
      const SegmentAccelerator accelerator(scene);
      ASSERT_TRUE(accelerator.uses_hierarchy());
      ASSERT_TRUE(accelerator.uses_line_space());
      ASSERT_TRUE(accelerator.has_cubics());
      ASSERT_EQ(accelerator.segments().size(), scene.size());
      int hits = 0;
      int self_hits = 0;
      for (int i = 0; i < 10000; ++i) {
        const Query q = random_query(rng, scene, setting.scale, setting.offset);
        const SceneHit fast = accelerator.closest_hit(q.ray, q.from);
        const SceneHit slow = accelerator.closest_hit_brute_force(q.ray, q.from);
        expect_same(fast, slow, i);
        expect_same(accelerator.closest_hit_tree(q.ray, q.from), slow, i);
        if (fast.segment != kNoSegment) {
          ++hits;
          self_hits += fast.segment == q.from.segment;
          ASSERT_GT(fast.distance, 0.0);
        }
      }
      EXPECT_GT(hits, 5000);
      EXPECT_GT(self_hits, 10);  // concave loops light themselves through the tree as well
    }
  }
}

// Rays from far outside the scene (beyond the wide tree's float reach, 4 extents from its centre,
// and just inside it) and grazing rays along the axes: the same answers as the brute force.
TEST(Bvh, FarAndAxisParallelRaysEqualBruteForce) {
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const std::vector<SegmentGeometry> scene = random_scene(rng, 200, 1.0, {0, 0});
  const SegmentAccelerator accelerator(scene);
  ASSERT_TRUE(accelerator.uses_hierarchy());
  int hits = 0;
  for (int i = 0; i < 20000; ++i) {
    const double distance = i % 3 == 0 ? 3.9 : i % 3 == 1 ? 4.1 : 1e3;  // in scene sizes
    const double angle = 2.0 * std::numbers::pi * unit(rng);
    const Vec2 target{unit(rng), unit(rng)};
    const Vec2 origin = target + distance * Vec2{std::cos(angle), std::sin(angle)};
    Vec2 direction = normalized(target - origin);
    if (i % 7 == 0)
      direction = std::fabs(direction.x) > std::fabs(direction.y) ? Vec2{direction.x > 0 ? 1.0 : -1.0, 0.0}
                                                                  : Vec2{0.0, direction.y > 0 ? 1.0 : -1.0};
    const Ray ray{origin, direction};
    const SceneHit fast = accelerator.closest_hit(ray, RayOrigin{});
    expect_same(fast, accelerator.closest_hit_brute_force(ray, RayOrigin{}), i);
    expect_same(accelerator.closest_hit_tree(ray, RayOrigin{}), accelerator.closest_hit_brute_force(ray, RayOrigin{}),
                i);
    hits += fast.segment != kNoSegment;
  }
  EXPECT_GT(hits, 5000);
}

TEST(Bvh, BruteForceIsTheNearestOfAllSegmentTests) {
  // The reference itself, against the segment tests one by one.
  std::mt19937_64 rng(300);
  const std::vector<SegmentGeometry> scene = random_scene(rng, 60);
  const SegmentAccelerator accelerator(scene);
  for (int i = 0; i < 2000; ++i) {
    const Query q = random_query(rng, scene, 1.0, {0, 0});
    double best = std::numeric_limits<double>::infinity();
    std::uint32_t best_index = kNoSegment;
    for (std::uint32_t k = 0; k < scene.size(); ++k) {
      SegmentHit h;
      bool hit = false;
      if (scene[k].kind == SegmentKind::Line) {
        hit = k != q.from.segment && intersect_line(scene[k].shape.p[0], scene[k].shape.p[3], q.ray, best * 2 + 1, &h);
      } else if (k == q.from.segment) {
        hit = intersect_cubic_from(scene[k].shape, q.from.t, q.ray, best * 2 + 1, &h);
      } else {
        hit = intersect_cubic(scene[k].shape, q.ray, best * 2 + 1, &h);
      }
      if (hit && h.distance < best) {
        best = h.distance;
        best_index = k;
      }
    }
    const SceneHit slow = accelerator.closest_hit_brute_force(q.ray, q.from);
    ASSERT_EQ(slow.segment == kNoSegment, best_index == kNoSegment) << i;
    if (best_index != kNoSegment) {
      EXPECT_EQ(slow.distance, best) << i;
    }
  }
}

TEST(Bvh, ClosedRoomGivesAnalyticDistances) {
  // The square [0,4] x [0,2] as four lines, subdivided so that the tree is used (12 segments).
  std::vector<SegmentGeometry> room;
  const Vec2 corners[] = {{0, 0}, {4, 0}, {4, 2}, {0, 2}};
  for (int side = 0; side < 4; ++side) {
    const Vec2 a = corners[side];
    const Vec2 b = corners[(side + 1) % 4];
    for (int k = 0; k < 3; ++k) room.push_back(line(lerp(a, b, k / 3.0), lerp(a, b, (k + 1) / 3.0)));
  }
  const SegmentAccelerator accelerator(room);
  ASSERT_TRUE(accelerator.uses_hierarchy());
  EXPECT_FALSE(accelerator.has_cubics());
  std::mt19937_64 rng(301);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i < 10000; ++i) {
    const Vec2 o{0.1 + 3.8 * unit(rng), 0.1 + 1.8 * unit(rng)};
    const double angle = 2.0 * std::numbers::pi * unit(rng);
    const Vec2 d{std::cos(angle), std::sin(angle)};
    // Exit distance from the box: the smallest positive slab distance.
    double expected = std::numeric_limits<double>::infinity();
    if (d.x > 0) expected = std::min(expected, (4.0 - o.x) / d.x);
    if (d.x < 0) expected = std::min(expected, -o.x / d.x);
    if (d.y > 0) expected = std::min(expected, (2.0 - o.y) / d.y);
    if (d.y < 0) expected = std::min(expected, -o.y / d.y);
    const SceneHit hit = accelerator.closest_hit(Ray{o, d}, RayOrigin{});
    ASSERT_NE(hit.segment, kNoSegment);
    EXPECT_NEAR(hit.distance, expected, 1e-12 * expected);
  }
  // Exactly through the corner (0,0), the joint of segments 11 and 0 (the diagonal direction has
  // equal components, so the side value there is exactly 0): a tie that the smaller index wins.
  const Ray diagonal{{1.0, 1.0}, normalized(Vec2{-1.0, -1.0})};
  const SceneHit corner = accelerator.closest_hit(diagonal, RayOrigin{});
  EXPECT_EQ(corner.segment, 0u);
  EXPECT_EQ(corner.t, 0.0);
  EXPECT_NEAR(corner.distance, std::sqrt(2.0), 1e-15);
  expect_same(corner, accelerator.closest_hit_brute_force(diagonal, RayOrigin{}), 0);
}

TEST(Bvh, TiesAtJointsGoToTheSmallerIndex) {
  // Two segments meeting at (3,1), hit exactly at the joint by a vertical ray (side value 0).
  std::vector<SegmentGeometry> scene = {
      cubic({3, 1}, {4, 0}, {5, 0}, {6, 1}),  // 0: starts at the joint
      cubic({0, 0}, {1, 2}, {2, 2}, {3, 1}),  // 1: ends at the joint
  };
  // Padding far away so that the tree is built, then the same with the scan.
  for (int k = 0; k < 10; ++k) scene.push_back(line({100.0 + k, 100}, {100.0 + k, 101}));
  const Ray up{{3.0, -5.0}, {0.0, 1.0}};
  const SegmentAccelerator tree(scene);
  ASSERT_TRUE(tree.uses_hierarchy());
  const SceneHit hit = tree.closest_hit(up, RayOrigin{});
  EXPECT_EQ(hit.segment, 0u);
  EXPECT_EQ(hit.t, 0.0);
  EXPECT_EQ(hit.distance, 6.0);
  const SegmentAccelerator scan(std::vector<SegmentGeometry>(scene.begin(), scene.begin() + 2));
  ASSERT_FALSE(scan.uses_hierarchy());
  EXPECT_EQ(scan.closest_hit(up, RayOrigin{}).segment, 0u);
}

TEST(Bvh, LineOriginNeverSeesItselfCubicOriginDoes) {
  // A lone line: rays from it in any direction (also along it) hit nothing.
  const SegmentAccelerator single({line({0, 0}, {1, 0})});
  for (Vec2 d : {Vec2{0, 1}, Vec2{0, -1}, Vec2{1, 0}, Vec2{-1, 0}, normalized(Vec2{1, 1})}) {
    EXPECT_EQ(single.closest_hit(Ray{{0.5, 0.0}, d}, RayOrigin{0, 0.5}).segment, kNoSegment);
  }
  // A concave arch among other segments: a ray from its inside hits the arch itself.
  std::vector<SegmentGeometry> scene;
  for (int k = 0; k < 12; ++k) scene.push_back(line({10.0 + k, 10}, {10.0 + k, 11}));
  scene.push_back(cubic({0, 0}, {0, 4.0 / 3.0}, {1, 4.0 / 3.0}, {1, 0}));
  const auto arch = static_cast<std::uint32_t>(scene.size() - 1);
  const SegmentAccelerator accelerator(scene);
  ASSERT_TRUE(accelerator.uses_hierarchy());
  const Vec2 from = evaluate(scene[arch].shape, 0.2);
  const Vec2 to = evaluate(scene[arch].shape, 0.7);
  const SceneHit hit = accelerator.closest_hit(Ray{from, normalized(to - from)}, RayOrigin{arch, 0.2});
  ASSERT_EQ(hit.segment, arch);
  EXPECT_NEAR(hit.t, 0.7, 1e-14);
  EXPECT_NEAR(hit.distance, length(to - from), 1e-14);
}

TEST(Bvh, SmallScenesUseTheLinearScan) {
  std::mt19937_64 rng(302);
  for (int n : {0, 1, 5, 8, 9, 17, 64, 1000}) {
    const std::vector<SegmentGeometry> scene = n ? random_scene(rng, n) : std::vector<SegmentGeometry>{};
    const SegmentAccelerator accelerator(scene);
    EXPECT_EQ(accelerator.uses_hierarchy(), scene.size() > 8) << n;
    // The line-space grid answers first from 9 segments to kLineSpaceLimit, and never for an
    // accelerator asked only for overlaps.
    EXPECT_EQ(accelerator.uses_line_space(), scene.size() > 8 && scene.size() <= SegmentAccelerator::kLineSpaceLimit)
        << n;
    EXPECT_FALSE(SegmentAccelerator(scene, SegmentAccelerator::Queries::Overlaps).uses_line_space()) << n;
    for (int i = 0; i < 1000 && !scene.empty(); ++i) {
      const Query q = random_query(rng, scene, 1.0, {0, 0});
      expect_same(accelerator.closest_hit(q.ray, q.from), accelerator.closest_hit_brute_force(q.ray, q.from), i);
      expect_same(accelerator.closest_hit_tree(q.ray, q.from), accelerator.closest_hit_brute_force(q.ray, q.from), i);
    }
  }
  const SegmentAccelerator empty;
  EXPECT_EQ(empty.closest_hit(Ray{{0, 0}, {1, 0}}, RayOrigin{}).segment, kNoSegment);
}

TEST(Bvh, DegenerateLayouts) {
  // Many identical segments (all centroids equal) and axis-aligned lines (flat boxes).
  std::vector<SegmentGeometry> scene;
  for (int k = 0; k < 40; ++k) scene.push_back(cubic({0, 0}, {0, 1}, {1, 1}, {1, 0}));
  for (int k = 0; k < 40; ++k) scene.push_back(line({-2.0, 0.05 * k}, {-1.0, 0.05 * k}));
  for (int k = 0; k < 40; ++k) scene.push_back(line({2.0 + 0.05 * k, 0}, {2.0 + 0.05 * k, 1}));
  const SegmentAccelerator accelerator(scene);
  ASSERT_TRUE(accelerator.uses_hierarchy());
  // Identical segments tie: the smallest index wins.
  const SceneHit hit = accelerator.closest_hit(Ray{{0.5, -1.0}, {0.0, 1.0}}, RayOrigin{});
  EXPECT_EQ(hit.segment, 0u);
  std::mt19937_64 rng(303);
  std::uniform_real_distribution<double> u(-3.0, 5.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i < 10000; ++i) {
    Ray ray{{u(rng), u(rng)}, {0, 0}};
    const double which = unit(rng);
    if (which < 0.25) {
      ray.direction = {1, 0};
      ray.origin.y = 0.05 * static_cast<int>(unit(rng) * 40);  // exactly along a flat line's y
    } else if (which < 0.5) {
      ray.direction = {0, unit(rng) < 0.5 ? 1.0 : -1.0};
    } else {
      const double angle = 2.0 * std::numbers::pi * unit(rng);
      ray.direction = {std::cos(angle), std::sin(angle)};
    }
    expect_same(accelerator.closest_hit(ray, RayOrigin{}), accelerator.closest_hit_brute_force(ray, RayOrigin{}), i);
    expect_same(accelerator.closest_hit_tree(ray, RayOrigin{}), accelerator.closest_hit_brute_force(ray, RayOrigin{}),
                i);
  }
}

}  // namespace
}  // namespace flatland

namespace flatland {
namespace {

// The tree's second query: the segments whose boxes meet a box are exactly those a scan finds,
// with and without the hierarchy (8 segments or fewer are scanned).
TEST(Accelerator, OverlapQueryFindsWhatAScanFinds) {
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> u(-1.2, 1.2);
  for (const int count : {5, 300}) {
    const std::vector<SegmentGeometry> segments = random_scene(rng, count);
    const SegmentAccelerator accelerator(segments);
    EXPECT_EQ(accelerator.uses_hierarchy(), count > 8);
    for (int trial = 0; trial < 200; ++trial) {
      Box box;
      box.extend(Vec2{u(rng), u(rng)});
      box = box.padded(0.3 * std::abs(u(rng)));
      std::vector<std::uint32_t> found;
      accelerator.for_each_overlapping(box, [&](std::uint32_t i) { found.push_back(i); });
      std::sort(found.begin(), found.end());
      std::vector<std::uint32_t> scanned;
      for (std::uint32_t i = 0; i < segments.size(); ++i)
        if (segment_box(segments[i]).overlaps(box)) scanned.push_back(i);
      EXPECT_EQ(found, scanned) << "trial " << trial;
    }
  }
}

}  // namespace
}  // namespace flatland
