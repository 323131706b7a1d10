// Random scenes and rays for the casters' tests (accelerator_test, line_space_test): chains,
// closed loops and loose segments, rays from free space and from points of segments.
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/geometry/bezier.hpp"
#include "flatland/geometry/segments.hpp"

namespace flatland::test {

inline SegmentGeometry line(Vec2 a, Vec2 b) { return {SegmentKind::Line, line_as_cubic(a, b)}; }
inline SegmentGeometry cubic(Vec2 p0, Vec2 p1, Vec2 p2, Vec2 p3) {
  return {SegmentKind::Cubic, Cubic{{p0, p1, p2, p3}}};
}

// A random scene of about `count` segments inside [-1,1]^2 (then scaled and moved): chains of
// lines and cubics that share their joints, closed loops, and loose segments.
inline std::vector<SegmentGeometry> random_scene(std::mt19937_64& rng, int count, double scale = 1.0,
                                                 Vec2 offset = {0, 0}) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  auto near = [&](Vec2 p, double r) { return p + Vec2{r * u(rng), r * u(rng)}; };
  std::vector<SegmentGeometry> out;
  while (static_cast<int>(out.size()) < count) {
    const int kind = static_cast<int>(unit(rng) * 3);
    Vec2 start{u(rng), u(rng)};
    if (kind == 0) {  // an open chain
      const int n = 2 + static_cast<int>(unit(rng) * 6);
      for (int i = 0; i < n; ++i) {
        const Vec2 end = near(start, 0.3);
        if (unit(rng) < 0.5) {
          out.push_back(line(start, end));
        } else {
          out.push_back(cubic(start, near(start, 0.3), near(end, 0.3), end));
        }
        start = end;
      }
    } else if (kind == 1) {  // a closed loop of cubics around a centre (some concave)
      const int n = 3 + static_cast<int>(unit(rng) * 4);
      const double r = 0.05 + 0.2 * unit(rng);
      std::vector<Vec2> corners;
      for (int i = 0; i < n; ++i) {
        const double a = 2.0 * std::numbers::pi * i / n;
        corners.push_back(start + Vec2{r * std::cos(a), r * std::sin(a)});
      }
      for (int i = 0; i < n; ++i) {
        const Vec2 a = corners[i];
        const Vec2 b = corners[(i + 1) % n];
        out.push_back(cubic(a, near(lerp(a, b, 0.3), r), near(lerp(a, b, 0.7), r), b));
      }
    } else {  // loose segments, some with coincident control points
      const Vec2 end = near(start, 0.5);
      const double which = unit(rng);
      if (which < 0.3) {
        out.push_back(line(start, end));
      } else if (which < 0.5) {
        out.push_back(cubic(start, start, near(end, 0.3), end));
      } else {
        out.push_back(cubic(start, near(start, 0.5), near(end, 0.5), end));
      }
    }
  }
  for (SegmentGeometry& g : out) {
    for (Vec2& p : g.shape.p) p = scale * p + offset;
  }
  return out;
}

inline Vec2 point_on(const SegmentGeometry& g, double t) {
  return g.kind == SegmentKind::Line ? lerp(g.shape.p[0], g.shape.p[3], t) : evaluate(g.shape, t);
}

struct Query {
  Ray ray;
  RayOrigin from;
};

inline Query random_query(std::mt19937_64& rng, const std::vector<SegmentGeometry>& scene, double scale, Vec2 offset) {
  std::uniform_real_distribution<double> u(-1.2, 1.2);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Query q;
  const double angle = 2.0 * std::numbers::pi * unit(rng);
  q.ray.direction = {std::cos(angle), std::sin(angle)};
  const double kind = unit(rng);
  if (kind < 0.1) {  // axis-aligned directions: zero components in the slab test
    const int axis = static_cast<int>(unit(rng) * 4);
    q.ray.direction = Vec2{axis == 0 ? 1.0 : axis == 1 ? -1.0 : 0.0, axis == 2 ? 1.0 : axis == 3 ? -1.0 : 0.0};
  }
  if (unit(rng) < 0.5) {  // from free space
    q.ray.origin = scale * Vec2{u(rng), u(rng)} + offset;
  } else {  // from a segment, sometimes exactly at its end (a joint)
    const auto index = static_cast<std::uint32_t>(unit(rng) * static_cast<double>(scene.size()));
    const double which = unit(rng);
    const double t = which < 0.05 ? 0.0 : which < 0.1 ? 1.0 : unit(rng);
    q.from = {index, t};
    q.ray.origin = point_on(scene[index], t);
  }
  return q;
}

inline void expect_same(const SceneHit& a, const SceneHit& b, int query) {
  ASSERT_EQ(a.segment, b.segment) << "query " << query;
  if (a.segment == kNoSegment) return;
  ASSERT_EQ(a.t, b.t) << "query " << query;
  ASSERT_EQ(a.distance, b.distance) << "query " << query;
}

}  // namespace flatland::test
