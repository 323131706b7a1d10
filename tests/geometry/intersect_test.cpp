#include "flatland/geometry/intersect.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "test_support.hpp"

#include "flatland/geometry/bezier.hpp"

namespace flatland {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

Cubic bezier(Vec2 p0, Vec2 p1, Vec2 p2, Vec2 p3) { return Cubic{{p0, p1, p2, p3}}; }

// ---- Independent reference: the curve as a dense polyline, in long double ----------------------

using testing::bernstein_point;
using testing::LongVec;

// A crossing the polyline proves: the curve's values at t_i and t_(i+1) lie strictly on opposite
// sides of the ray's line, so by continuity the curve crosses it in between, at a distance along
// the ray within [lower, upper]. Every point of the curve on [t_i, t_(i+1)] lies within the
// interpolation error h^2/8 max|C''| of the chord, which widens the chord's range of d.(p - o).
struct Crossing {
  long double lower, upper;
  double t_lower, t_upper;
};

class Polyline {
 public:
  Polyline(const Cubic& c, int chords) : t_(chords + 1), points_(chords + 1) {
    for (int i = 0; i <= chords; ++i) {
      t_[i] = static_cast<double>(i) / chords;
      points_[i] = bernstein_point(c, t_[i]);
    }
    // C'' is linear in t, so its largest norm is at an end: 6 |P2 - 2P1 + P0| or 6 |P3 - 2P2 + P1|.
    const Vec2 a = c.p[2] - 2.0 * c.p[1] + c.p[0];
    const Vec2 b = c.p[3] - 2.0 * c.p[2] + c.p[1];
    const double h = 1.0 / chords;
    sagitta_ = h * h / 8.0 * 6.0 * std::max(length(a), length(b)) * (1.0 + 1e-9);
  }

  std::vector<Crossing> crossings(const Ray& ray) const {
    std::vector<Crossing> out;
    const long double dx = ray.direction.x;
    const long double dy = ray.direction.y;
    long double previous_side = 0.0L;
    long double previous_along = 0.0L;
    for (std::size_t i = 0; i < points_.size(); ++i) {
      const long double x = points_[i].x - ray.origin.x;
      const long double y = points_[i].y - ray.origin.y;
      const long double side = dx * y - dy * x;
      const long double along = dx * x + dy * y;
      if (i > 0 && ((side > 0 && previous_side < 0) || (side < 0 && previous_side > 0))) {
        out.push_back(
            {std::min(along, previous_along) - sagitta_, std::max(along, previous_along) + sagitta_, t_[i - 1], t_[i]});
      }
      previous_side = side;
      previous_along = along;
    }
    return out;
  }

 private:
  std::vector<double> t_;
  std::vector<LongVec> points_;
  long double sagitta_ = 0.0L;
};

double control_size(const Cubic& c) { return hull_bounds(c).diagonal(); }

// The size that measures rounding for this ray and cubic: coordinates relative to the origin.
double query_size(const Cubic& c, const Ray& ray) {
  double size = 0.0;
  for (const Vec2& p : c.p) size = std::max(size, length(p - ray.origin));
  return size;
}

// Checks one answer of intersect_cubic (or _from) against the polyline. `exclude_below` drops
// proven crossings that may lie closer than that (used for rays that leave the curve itself).
// Returns whether the reference proves a crossing, for statistics.
bool check_against_polyline(const Cubic& c, const Ray& ray, const Polyline& poly, bool hit, const SegmentHit& h,
                            double exclude_below = 0.0) {
  const double size = query_size(c, ray);
  const std::vector<Crossing> proven = poly.crossings(ray);
  long double nearest_upper = kInfinity;
  bool any = false;
  for (const Crossing& x : proven) {
    if (x.lower > exclude_below) {
      nearest_upper = std::min(nearest_upper, x.upper);
      any = true;
    }
  }
  if (!hit) {
    EXPECT_FALSE(any) << "missed a crossing at distance <= " << double(nearest_upper);
    return any;
  }
  EXPECT_GT(h.distance, 0.0);
  EXPECT_GE(h.t, 0.0);
  EXPECT_LE(h.t, 1.0);
  // The reported point is on the curve and on the ray, at the reported distance.
  const LongVec p = bernstein_point(c, h.t);
  const long double x = p.x - ray.origin.x;
  const long double y = p.y - ray.origin.y;
  const long double side = ray.direction.x * y - ray.direction.y * x;
  const long double along = ray.direction.x * x + ray.direction.y * y;
  EXPECT_LT(std::abs(double(side)), 1e-12 * size);
  EXPECT_NEAR(double(along), h.distance, 1e-12 * size);
  // No proven crossing is nearer.
  if (any) {
    EXPECT_LE(h.distance, double(nearest_upper) + 1e-12 * size);
  }
  return any;
}

enum class Shape { Generic, FirstDouble, LastDouble, MiddleDouble, Collinear, Quadratic, Tiny };

Cubic random_shape(std::mt19937_64& rng, Shape shape) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto point = [&] { return Vec2{u(rng), u(rng)}; };
  Cubic c{{point(), point(), point(), point()}};
  switch (shape) {
    case Shape::Generic: break;
    case Shape::FirstDouble: c.p[1] = c.p[0]; break;
    case Shape::LastDouble: c.p[2] = c.p[3]; break;
    case Shape::MiddleDouble: c.p[2] = c.p[1]; break;
    case Shape::Collinear: {
      const Vec2 a = point();
      const Vec2 b = point();
      for (Vec2& p : c.p) p = lerp(a, b, 1.5 * u(rng));
      break;
    }
    case Shape::Quadratic: {
      const Vec2 q0 = point();
      const Vec2 q1 = point();
      const Vec2 q2 = point();
      c = bezier(q0, q0 + (2.0 / 3.0) * (q1 - q0), q2 + (2.0 / 3.0) * (q1 - q2), q2);
      break;
    }
    case Shape::Tiny:  // control points close to the chord: an almost straight cubic
      c.p[1] = lerp(c.p[0], c.p[3], 1.0 / 3.0) + 1e-7 * point();
      c.p[2] = lerp(c.p[0], c.p[3], 2.0 / 3.0) + 1e-7 * point();
      break;
  }
  return c;
}

Ray random_ray(std::mt19937_64& rng, const Cubic& c, bool aimed) {
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Ray ray;
  ray.origin = {u(rng), u(rng)};
  if (aimed) {
    const Vec2 target = evaluate(c, unit(rng));
    ray.direction = normalized(target - ray.origin);
  } else {
    const double angle = 2.0 * std::numbers::pi * unit(rng);
    ray.direction = {std::cos(angle), std::sin(angle)};
  }
  return ray;
}

TEST(Intersect, RandomCubicsMatchDensePolyline) {
  std::mt19937_64 rng(101);
  const Shape shapes[] = {Shape::Generic,   Shape::FirstDouble, Shape::LastDouble, Shape::MiddleDouble,
                          Shape::Collinear, Shape::Quadratic,   Shape::Tiny};
  int hits = 0;
  int proven = 0;
  int queries = 0;
  for (int trial = 0; trial < 3500; ++trial) {
    const Cubic c = random_shape(rng, shapes[trial % 7]);
    if (control_size(c) < 1e-3) continue;
    const Polyline poly(c, 2000);
    for (int k = 0; k < 6; ++k) {
      const Ray ray = random_ray(rng, c, k % 2 == 0);
      SegmentHit h;
      const bool hit = intersect_cubic(c, ray, kInfinity, &h);
      proven += check_against_polyline(c, ray, poly, hit, h);
      hits += hit;
      ++queries;
      if (hit) {
        // The range is open at max_distance: just above it the same hit, at it a miss.
        SegmentHit again;
        ASSERT_TRUE(intersect_cubic(c, ray, std::nextafter(h.distance, kInfinity), &again));
        EXPECT_EQ(again.t, h.t);
        EXPECT_EQ(again.distance, h.distance);
        EXPECT_FALSE(intersect_cubic(c, ray, h.distance, &again));
      }
    }
  }
  // Sanity of the sample: most aimed rays hit, and the reference proves most hits.
  EXPECT_GT(hits, queries / 3);
  EXPECT_GT(proven, hits * 9 / 10);
}

TEST(Intersect, AimedRaysNeverMissTransversalCrossings) {
  // A ray aimed at C(t*) crosses the curve there unless it is nearly tangent; the nearest hit is no
  // farther than C(t*).
  std::mt19937_64 rng(102);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int checked = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const Cubic c = random_shape(rng, trial % 2 ? Shape::Generic : Shape::FirstDouble);
    const double t_target = unit(rng);
    const Vec2 target = evaluate(c, t_target);
    const Vec2 tangent = derivative(c, t_target);
    Ray ray{{u(rng), u(rng)}, {1.0, 0.0}};
    ray.direction = normalized(target - ray.origin);
    if (std::abs(cross(ray.direction, tangent)) < 1e-3 * length(tangent)) continue;
    const double to_target = length(target - ray.origin);
    SegmentHit h;
    ASSERT_TRUE(intersect_cubic(c, ray, kInfinity, &h)) << trial;
    EXPECT_LE(h.distance, to_target * (1.0 + 1e-12) + 1e-12);
    ++checked;
  }
  EXPECT_GT(checked, 19000);
}

TEST(Intersect, AimedRaysNearTheEndsFindPointsOnTheRay) {
  // Crossings 1e-1 .. 1e-16 from either end (where Newton-type steps leave [0,1]): the reported
  // point must lie on the ray (long double evaluation) and be no farther than the target.
  std::mt19937_64 rng(110);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  int checked = 0;
  for (int trial = 0; trial < 4000; ++trial) {
    const Cubic c = random_shape(rng, trial % 3 == 0 ? Shape::LastDouble : Shape::Generic);
    const double offset = std::pow(10.0, -1.0 - (trial % 16));
    const double t_target = trial % 2 ? offset : 1.0 - offset;
    const Vec2 target = evaluate(c, t_target);
    const Vec2 tangent = derivative(c, t_target);
    Ray ray{{u(rng), u(rng)}, {1.0, 0.0}};
    ray.direction = normalized(target - ray.origin);
    if (std::abs(cross(ray.direction, tangent)) < 1e-2 * length(tangent)) continue;
    // A target within rounding of the end point may fall on either side of it.
    const double size = query_size(c, ray);
    if (std::min(length(target - c.p[0]), length(target - c.p[3])) < 1e-13 * size) continue;
    SegmentHit h;
    ASSERT_TRUE(intersect_cubic(c, ray, kInfinity, &h)) << trial;
    const LongVec p = bernstein_point(c, h.t);
    const long double side = ray.direction.x * (p.y - ray.origin.y) - ray.direction.y * (p.x - ray.origin.x);
    EXPECT_LT(std::abs(double(side)), 1e-13 * size) << trial << " t " << h.t;
    EXPECT_LE(h.distance, length(target - ray.origin) + 1e-13 * size) << trial;
    ++checked;
  }
  EXPECT_GT(checked, 2500);
}

TEST(Intersect, GrazingRaysAtAnExtremum) {
  // y(t) = 6 t (1 - t) peaks at 1.5 at t = 1/2; x(t) = 3 t^2 - 2 t^3. All control values exact.
  const Cubic arch = bezier({0, 0}, {0, 2}, {1, 2}, {1, 0});
  SegmentHit h;
  // Exactly tangent: a double root without a sign change is a miss.
  EXPECT_FALSE(intersect_cubic(arch, Ray{{-1.0, 1.5}, {1.0, 0.0}}, kInfinity, &h));
  EXPECT_FALSE(intersect_cubic(arch, Ray{{2.0, 1.5}, {-1.0, 0.0}}, kInfinity, &h));
  // Just above: a miss. Just below: two crossings, the nearer at 6t(1-t) = y.
  for (double offset : {1e-3, 1e-6, 1e-9, 1e-12}) {
    EXPECT_FALSE(intersect_cubic(arch, Ray{{-1.0, 1.5 + offset}, {1.0, 0.0}}, kInfinity, &h));
    const double y = 1.5 - offset;
    const double t_left = (1.0 - std::sqrt(1.0 - 2.0 * y / 3.0)) / 2.0;
    const double t_right = 1.0 - t_left;
    ASSERT_TRUE(intersect_cubic(arch, Ray{{-1.0, y}, {1.0, 0.0}}, kInfinity, &h)) << offset;
    // The root moves by rounding / f'(t), with f' ~ 5 sqrt(offset) near the double root.
    const double tolerance = 1e-14 / std::sqrt(offset);
    EXPECT_NEAR(h.t, t_left, tolerance);
    EXPECT_NEAR(h.distance, 1.0 + 3 * t_left * t_left - 2 * t_left * t_left * t_left, tolerance);
    ASSERT_TRUE(intersect_cubic(arch, Ray{{2.0, y}, {-1.0, 0.0}}, kInfinity, &h)) << offset;
    EXPECT_NEAR(h.t, t_right, tolerance);
  }
}

TEST(Intersect, RaysThroughExactJointsHitOnce) {
  // Joint (3,1) with exactly representable coordinates: a vertical ray through it has side value
  // exactly 0 at the joint, and both neighbours report the joint itself at the same distance.
  const Cubic a = bezier({0, 0}, {1, 2}, {2, 2}, {3, 1});
  const Cubic b = bezier({3, 1}, {4, 0}, {5, 0}, {6, 1});
  const Ray up{{3.0, -5.0}, {0.0, 1.0}};
  SegmentHit ha;
  SegmentHit hb;
  ASSERT_TRUE(intersect_cubic(a, up, kInfinity, &ha));
  ASSERT_TRUE(intersect_cubic(b, up, kInfinity, &hb));
  EXPECT_EQ(ha.t, 1.0);
  EXPECT_EQ(hb.t, 0.0);
  EXPECT_EQ(ha.distance, 6.0);
  EXPECT_EQ(hb.distance, 6.0);
  // A line neighbour ending at the same joint agrees bit for bit.
  SegmentHit hl;
  ASSERT_TRUE(intersect_line({0.0, 3.0}, {3.0, 1.0}, up, kInfinity, &hl));
  EXPECT_EQ(hl.t, 1.0);
  EXPECT_EQ(hl.distance, 6.0);
  ASSERT_TRUE(intersect_line({3.0, 1.0}, {6.0, 4.0}, up, kInfinity, &hl));
  EXPECT_EQ(hl.t, 0.0);
  EXPECT_EQ(hl.distance, 6.0);
}

// A chain of two segments of the given kinds sharing the end point `joint`.
struct Chain {
  Cubic first;
  Cubic second;
  bool first_is_line;
  bool second_is_line;
};

bool intersect_piece(const Cubic& c, bool is_line, const Ray& ray, SegmentHit* h) {
  return is_line ? intersect_line(c.p[0], c.p[3], ray, kInfinity, h) : intersect_cubic(c, ray, kInfinity, h);
}

TEST(Intersect, RaysThroughRandomJointsAreNeverLost) {
  std::mt19937_64 rng(103);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  auto point = [&] { return Vec2{u(rng), u(rng)}; };
  int checked = 0;
  int both = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const Vec2 joint = point();
    Chain chain{};
    chain.first_is_line = trial % 4 == 1;
    chain.second_is_line = trial % 4 == 2;
    chain.first = chain.first_is_line ? line_as_cubic(point(), joint) : bezier(point(), point(), point(), joint);
    chain.second = chain.second_is_line ? line_as_cubic(joint, point()) : bezier(joint, point(), point(), point());
    const Vec2 origin = 2.0 * point();
    // Half the rays aim at the joint as well as rounding allows (the side value there is often
    // exactly 0); the others pass it at 1e-17..1e-13 on a random side.
    Vec2 aim = joint - origin;
    if (trial % 2) {
      aim = aim + std::pow(10.0, -17.0 + 4.0 * (0.5 + 0.5 * u(rng))) * u(rng) * perp(aim);
    }
    Ray ray{origin, normalized(aim)};
    // Transversal: the chain arrives and leaves on opposite sides of the ray's line.
    const Vec2 in = unit_tangent(chain.first, 1.0, 1.0);
    const Vec2 out = unit_tangent(chain.second, 0.0, 1.0);
    if (!(cross(ray.direction, in) * cross(ray.direction, out) > 0.0)) continue;
    if (std::min(std::abs(cross(ray.direction, in)), std::abs(cross(ray.direction, out))) < 0.05) {
      continue;
    }
    // Only rays whose nearest crossing is the joint: skip when a proven crossing away from the
    // chords at the joint may lie before it.
    const double to_joint = length(joint - origin);
    bool earlier = false;
    for (const Crossing& x : Polyline(chain.first, 400).crossings(ray)) {
      earlier = earlier || (x.t_upper < 1.0 && x.upper > 0 && x.lower < to_joint);
    }
    for (const Crossing& x : Polyline(chain.second, 400).crossings(ray)) {
      earlier = earlier || (x.t_lower > 0.0 && x.upper > 0 && x.lower < to_joint);
    }
    if (earlier) continue;
    SegmentHit h1;
    SegmentHit h2;
    const bool hit1 = intersect_piece(chain.first, chain.first_is_line, ray, &h1);
    const bool hit2 = intersect_piece(chain.second, chain.second_is_line, ray, &h2);
    const bool near1 = hit1 && std::abs(h1.distance - to_joint) < 1e-9;
    const bool near2 = hit2 && std::abs(h2.distance - to_joint) < 1e-9;
    ASSERT_TRUE(near1 || near2) << "lost at trial " << trial << ": " << hit1 << " " << h1.t << " " << hit2 << " "
                                << h2.t;
    if (near1 && near2) {
      // Both only if the joint itself lies on the ray's line: then it is the same point.
      EXPECT_EQ(h1.t, 1.0);
      EXPECT_EQ(h2.t, 0.0);
      EXPECT_EQ(h1.distance, h2.distance);
      ++both;
    }
    ++checked;
  }
  EXPECT_GT(checked, 2000);
  EXPECT_GT(both, 0);  // exact joint hits occurred and were consistent
}

TEST(Intersect, LinesAsCubicsMatchIntersectLine) {
  std::mt19937_64 rng(104);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int hits = 0;
  for (int trial = 0; trial < 50000; ++trial) {
    const Vec2 a{u(rng), u(rng)};
    const Vec2 b{u(rng), u(rng)};
    const Ray ray = random_ray(rng, line_as_cubic(a, b), trial % 2 == 0);
    SegmentHit hl;
    SegmentHit hc;
    const bool line_hit = intersect_line(a, b, ray, kInfinity, &hl);
    const bool cubic_hit = intersect_cubic(line_as_cubic(a, b), ray, kInfinity, &hc);
    ASSERT_EQ(line_hit, cubic_hit) << trial;
    if (!line_hit) continue;
    ++hits;
    // Both solve the same linear function; its slope in t is m.(b - a).
    const double tolerance = 1e-14 * (1.0 + 1.0 / std::abs(cross(ray.direction, b - a)));
    EXPECT_NEAR(hl.t, hc.t, tolerance);
    EXPECT_NEAR(hl.distance, hc.distance, tolerance);
    // And the closed form itself: the point is on the segment and on the ray.
    const Vec2 p = lerp(a, b, hl.t);
    EXPECT_NEAR(cross(ray.direction, p - ray.origin), 0.0, 1e-14);
    EXPECT_NEAR(dot(ray.direction, p - ray.origin), hl.distance, 1e-14);
  }
  EXPECT_GT(hits, 20000);
}

TEST(Intersect, LineEdgeCases) {
  SegmentHit h;
  // Parallel and collinear rays miss.
  EXPECT_FALSE(intersect_line({0, 1}, {2, 1}, Ray{{0, 0}, {1, 0}}, kInfinity, &h));
  EXPECT_FALSE(intersect_line({1, 0}, {2, 0}, Ray{{0, 0}, {1, 0}}, kInfinity, &h));
  // Behind the origin, and beyond max_distance.
  EXPECT_FALSE(intersect_line({-1, -1}, {-1, 1}, Ray{{0, 0}, {1, 0}}, kInfinity, &h));
  EXPECT_FALSE(intersect_line({2, -1}, {2, 1}, Ray{{0, 0}, {1, 0}}, 2.0, &h));
  ASSERT_TRUE(intersect_line({2, -1}, {2, 1}, Ray{{0, 0}, {1, 0}}, 2.5, &h));
  EXPECT_EQ(h.distance, 2.0);
  EXPECT_EQ(h.t, 0.5);
  // End points are inclusive.
  ASSERT_TRUE(intersect_line({2, 0}, {2, 1}, Ray{{0, 0}, {1, 0}}, kInfinity, &h));
  EXPECT_EQ(h.t, 0.0);
  ASSERT_TRUE(intersect_line({2, 1}, {2, 0}, Ray{{0, 0}, {1, 0}}, kInfinity, &h));
  EXPECT_EQ(h.t, 1.0);
}

TEST(Intersect, QuadraticCubicsMatchClosedForm) {
  // A quadratic Q(t) elevated to a cubic: f(t) = m.(Q(t) - o) = alpha t^2 + beta t + gamma exactly,
  // solved here by the textbook formula in long double.
  std::mt19937_64 rng(105);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int hits = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const Vec2 q0{u(rng), u(rng)};
    const Vec2 q1{u(rng), u(rng)};
    const Vec2 q2{u(rng), u(rng)};
    const Cubic c = bezier(q0, q0 + (2.0 / 3.0) * (q1 - q0), q2 + (2.0 / 3.0) * (q1 - q2), q2);
    const Ray ray = random_ray(rng, c, trial % 2 == 0);
    const Vec2 m = perp(ray.direction);
    // Q(t) = q0 + 2t (q1 - q0) + t^2 (q0 - 2 q1 + q2).
    const long double alpha = (long double)dot(m, q0 - 2.0 * q1 + q2);
    const long double beta = 2.0L * dot(m, q1 - q0);
    const long double gamma = (long double)dot(m, q0 - ray.origin);
    const long double disc = beta * beta - 4.0L * alpha * gamma;
    if (std::abs(disc) < 1e-6L * (beta * beta + std::abs(4.0L * alpha * gamma))) continue;
    long double best = kInfinity;
    long double best_t = -1.0L;
    if (disc > 0) {
      const long double r = std::sqrt(disc);
      for (long double t : {(-beta - r) / (2 * alpha), (-beta + r) / (2 * alpha)}) {
        if (!(t >= 0.0L && t <= 1.0L) || std::min(t, 1.0L - t) < 1e-9L) continue;
        const LongVec p = bernstein_point(c, t);
        const long double sigma = ray.direction.x * (p.x - ray.origin.x) + ray.direction.y * (p.y - ray.origin.y);
        if (sigma > 1e-9L && sigma < best) {
          best = sigma;
          best_t = t;
        }
      }
    }
    SegmentHit h;
    const bool hit = intersect_cubic(c, ray, kInfinity, &h);
    if (best_t < 0) {
      // No clear crossing (a root within 1e-9 of an end or the origin is ambiguous: skip those).
      if (hit) {
        EXPECT_TRUE(std::min(h.t, 1.0 - h.t) < 1e-8 || h.distance < 1e-8) << trial;
      }
      continue;
    }
    ASSERT_TRUE(hit) << trial;
    ++hits;
    EXPECT_NEAR(h.t, double(best_t), 1e-9);
    EXPECT_NEAR(h.distance, double(best), 1e-12);
  }
  EXPECT_GT(hits, 5000);
}

TEST(Intersect, CollinearCubicsHitWhereTheLineDoes) {
  // Control points on one line (also out of order, so the curve backtracks): the hit point is the
  // line's, whichever of the parameters that reach it is reported.
  std::mt19937_64 rng(106);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  int hits = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const Vec2 a{u(rng), u(rng)};
    const Vec2 b{u(rng), u(rng)};
    const double s[4] = {0.0, 0.5 * u(rng) + 0.3, 0.5 * u(rng) + 0.6, 1.0};
    const Cubic c = bezier(a, lerp(a, b, s[1]), lerp(a, b, s[2]), b);
    // The curve covers the part of the line between its extreme parameters.
    const Ray ray = random_ray(rng, c, true);
    SegmentHit hc;
    SegmentHit hl;
    const bool cubic_hit = intersect_cubic(c, ray, kInfinity, &hc);
    // The covered range of s(t) = sum B_i s_i: min and max over dense samples (reference).
    double s_min = 0.0;
    double s_max = 1.0;
    for (int i = 0; i <= 1000; ++i) {
      const double t = i / 1000.0;
      const double v = (1 - t) * (1 - t) * (1 - t) * s[0] + 3 * (1 - t) * (1 - t) * t * s[1] +
                       3 * (1 - t) * t * t * s[2] + t * t * t * s[3];
      s_min = std::min(s_min, v);
      s_max = std::max(s_max, v);
    }
    const bool line_hit = intersect_line(lerp(a, b, s_min), lerp(a, b, s_max), ray, kInfinity, &hl);
    if (line_hit && std::min(hl.t, 1.0 - hl.t) > 1e-4 && hl.distance > 1e-6) {
      ASSERT_TRUE(cubic_hit) << trial;
      EXPECT_NEAR(hc.distance, hl.distance, 1e-12 * (1.0 + 1.0 / std::abs(cross(ray.direction, normalized(b - a)))));
      ++hits;
    }
    if (!line_hit && cubic_hit && hc.distance > 1e-6) {
      // Only just beyond the sampled extremes of the covered range.
      const Vec2 p = evaluate(c, hc.t);
      const double s_hit = dot(p - a, b - a) / length_squared(b - a);
      EXPECT_LT(std::min(std::abs(s_hit - s_min), std::abs(s_hit - s_max)), 1e-5) << trial;
    }
  }
  EXPECT_GT(hits, 10000);
}

TEST(Intersect, CoincidentControlPointsNearTheEnd) {
  // P0 == P1: the curve leaves P0 with zero speed. Rays crossing close to the end still hit, at a
  // parameter that behaves like sqrt(distance).
  const Cubic c = bezier({0, 0}, {0, 0}, {1, 1}, {2, 0});
  for (double x : {1e-2, 1e-4, 1e-6, 1e-8}) {
    // Near t = 0, C(t) ~ 3 t^2 (1, 1): a vertical ray at x crosses where x(t) = x.
    const Ray ray{{x, -1.0}, {0.0, 1.0}};
    SegmentHit h;
    ASSERT_TRUE(intersect_cubic(c, ray, kInfinity, &h)) << x;
    const Vec2 p = evaluate(c, h.t);
    EXPECT_NEAR(p.x, x, 1e-15);
    EXPECT_NEAR(h.distance, p.y + 1.0, 1e-15);
    // x(t) = 3 t^2 (1-t) + 2 t^3 = 3 t^2 - t^3, increasing on [0,1]: bisection in long double.
    long double lo = 0.0L;
    long double hi = 1.0L;
    for (int i = 0; i < 100; ++i) {
      const long double mid = 0.5L * (lo + hi);
      (3.0L * mid * mid - mid * mid * mid < x ? lo : hi) = mid;
    }
    EXPECT_NEAR(h.t, double(lo), 1e-15 / std::sqrt(x));
  }
}

TEST(Intersect, ConcaveCubicLightsItself) {
  // The arch travels up, over and down, so its front (left of travel) faces outwards: rays into
  // the back side (inwards) may hit the arch again; rays out of the front never do.
  const Cubic arch = bezier({0, 0}, {0, 4.0 / 3.0}, {1, 4.0 / 3.0}, {1, 0});
  const Polyline poly(arch, 4000);
  std::mt19937_64 rng(107);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int self_hits = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    const double t0 = trial < 4 ? double(trial % 2) : unit(rng);
    const Vec2 origin = evaluate(arch, t0);
    const Vec2 tangent = unit_tangent(arch, t0, 1.0);
    const Vec2 front = perp(tangent);
    // Angle from the tangent in (0, pi), on the front side or the back side.
    const double angle = trial % 3 == 0 ? std::pow(10.0, -12.0 * unit(rng)) : std::numbers::pi * unit(rng);
    const double along = std::cos(angle);
    const double across = std::sin(angle);
    SegmentHit h;
    // Front: never a hit, however grazing.
    const Ray out{origin, along * tangent + across * front};
    EXPECT_FALSE(intersect_cubic_from(arch, t0, out, kInfinity, &h)) << t0 << " " << angle;
    const Ray out_back{origin, -along * tangent + across * front};
    EXPECT_FALSE(intersect_cubic_from(arch, t0, out_back, kInfinity, &h)) << t0 << " " << angle;
    // Back: compare with the polyline, leaving out crossings that may be the origin itself.
    const Ray in{origin, along * tangent - across * front};
    const bool hit = intersect_cubic_from(arch, t0, in, kInfinity, &h);
    if (hit) {
      EXPECT_GT(h.distance, 0.0);
      ++self_hits;
    }
    if (angle > 1e-2 && (!hit || h.distance > 1e-3)) {
      check_against_polyline(arch, in, poly, hit, h, 1e-4);
    }
  }
  EXPECT_GT(self_hits, 5000);
}

TEST(Intersect, SelfHitsOfRandomCubicsMatchDensePolyline) {
  std::mt19937_64 rng(108);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int self_hits = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    const Cubic c = random_shape(rng, trial % 3 == 0 ? Shape::FirstDouble : Shape::Generic);
    if (control_size(c) < 1e-2) continue;
    const Polyline poly(c, 4000);
    for (int k = 0; k < 5; ++k) {
      const double t0 = unit(rng);
      const Vec2 origin = evaluate(c, t0);
      const double angle = 2.0 * std::numbers::pi * unit(rng);
      const Ray ray{origin, {std::cos(angle), std::sin(angle)}};
      const Vec2 tangent = derivative(c, t0);
      // Leave out rays within 1e-2 rad of the tangent: their self hits may be arbitrarily close.
      if (std::abs(cross(ray.direction, tangent)) < 1e-2 * length(tangent)) continue;
      SegmentHit h;
      const bool hit = intersect_cubic_from(c, t0, ray, kInfinity, &h);
      if (hit) ++self_hits;
      if (hit && h.distance < 1e-3) continue;
      check_against_polyline(c, ray, poly, hit, h, 1e-4);
    }
  }
  EXPECT_GT(self_hits, 500);
}

TEST(Intersect, SelfHitAtGrazingAngleIsAccurate) {
  // Leaving a curve of curvature kappa at a small angle a from the tangent, on the concave side,
  // the ray meets it again after a chord of length 2 a / kappa (1 + O(a)).
  const double k = 0.5522847498;  // the usual quarter circle
  const Cubic arc = bezier({1, 0}, {1, k}, {k, 1}, {0, 1});
  for (double t0 : {0.1, 0.25, 0.6}) {
    const Vec2 d1 = derivative(arc, t0);
    const Vec2 d2 = second_derivative(arc, t0);
    const double curvature = cross(d1, d2) / std::pow(length(d1), 3.0);
    for (double a : {1e-3, 1e-5, 1e-7, 1e-9}) {
      const Vec2 origin = evaluate(arc, t0);
      const Vec2 tangent = unit_tangent(arc, t0, 1.0);
      const Vec2 inward = perp(tangent);  // counter-clockwise: the front faces the centre
      const Ray ray{origin, std::cos(a) * tangent + std::sin(a) * inward};
      SegmentHit h;
      ASSERT_TRUE(intersect_cubic_from(arc, t0, ray, kInfinity, &h)) << a;
      const double expected = 2.0 * a / curvature;
      EXPECT_NEAR(h.distance, expected, expected * (10.0 * a + 1e-6)) << t0 << " " << a;
      EXPECT_GT(h.t, t0);
      // Leaving on the convex side at the same angle: nothing.
      const Ray out{origin, std::cos(a) * tangent - std::sin(a) * inward};
      EXPECT_FALSE(intersect_cubic_from(arc, t0, out, kInfinity, &h)) << a;
    }
  }
}

// Scaling and translation: the same configurations at 1e-6 and 1e6, and 1e6 away from the origin.
TEST(Intersect, ScaledAndTranslatedScenesGiveTheSameAnswers) {
  struct Transform {
    double scale;
    Vec2 offset;
  };
  const Transform transforms[] = {
      {1e-6, {0, 0}}, {1e6, {0, 0}}, {1.0, {1e6, -1e6}}, {1e3, {1e6, 1e6}}, {0.125, {-1e6, 0}}};
  std::mt19937_64 rng(109);
  for (const Transform& tf : transforms) {
    std::mt19937_64 local = rng;  // the same cases for every transform
    int compared = 0;
    // Coordinates far from the origin carry rounding of |offset| eps relative to the scene.
    const double noise = 1e-13 + 64.0 * std::numeric_limits<double>::epsilon() * length(tf.offset) / tf.scale;
    for (int trial = 0; trial < 3000; ++trial) {
      const Cubic c = random_shape(local, trial % 2 ? Shape::Generic : Shape::LastDouble);
      const Ray ray = random_ray(local, c, trial % 3 != 0);
      Cubic moved;
      for (int i = 0; i < 4; ++i) moved.p[i] = tf.scale * c.p[i] + tf.offset;
      const Ray moved_ray{tf.scale * ray.origin + tf.offset, ray.direction};
      SegmentHit h;
      SegmentHit hm;
      const bool hit = intersect_cubic(c, ray, kInfinity, &h);
      const bool hit_moved = intersect_cubic(moved, moved_ray, kInfinity, &hm);
      // Near-tangent or near-end cases may legitimately flip under rounding of the coordinates.
      // Judged in the unit frame: the crossing's angle, its distance from the segment's ends and
      // from the origin must exceed what the coordinates' rounding can move.
      auto robust = [&](double t, double distance) {
        const Vec2 v = derivative(c, t);
        const double sine = std::abs(cross(ray.direction, v)) / length(v);
        const Vec2 p = evaluate(c, t);
        const double from_ends = std::min(length(p - c.p[0]), length(p - c.p[3]));
        return sine > 1e-3 && from_ends * sine > 1e3 * noise && distance > 1e3 * noise;
      };
      if (hit != hit_moved) {
        if (hit) {
          EXPECT_FALSE(robust(h.t, h.distance)) << trial;
        }
        if (hit_moved) {
          EXPECT_FALSE(robust(hm.t, hm.distance / tf.scale)) << trial;
        }
        continue;
      }
      if (!hit || !robust(h.t, h.distance)) continue;
      const Vec2 v = derivative(c, h.t);
      const double sine = std::abs(cross(ray.direction, v)) / length(v);
      EXPECT_NEAR(hm.t, h.t, 100 * noise / sine) << trial;
      EXPECT_NEAR(hm.distance / tf.scale, h.distance, 100 * noise / sine) << trial;
      ++compared;
    }
    EXPECT_GT(compared, 800);

    // The self-lighting arch at this scale.
    const Cubic arch = bezier({0, 0}, {0, 4.0 / 3.0}, {1, 4.0 / 3.0}, {1, 0});
    Cubic moved_arch;
    for (int i = 0; i < 4; ++i) moved_arch.p[i] = tf.scale * arch.p[i] + tf.offset;
    // From C(t0) straight at C(t1) across the inside of the arch: the hit is C(t1).
    for (double t0 : {0.1, 0.3, 0.6, 0.9}) {
      const double t1 = t0 < 0.5 ? t0 + 0.5 : t0 - 0.5;
      const Vec2 from = evaluate(arch, t0);
      const Ray in{from, normalized(evaluate(arch, t1) - from)};
      const Ray moved_in{evaluate(moved_arch, t0), in.direction};
      SegmentHit h;
      SegmentHit hm;
      ASSERT_TRUE(intersect_cubic_from(arch, t0, in, kInfinity, &h));
      EXPECT_NEAR(h.t, t1, 1e-14);
      EXPECT_NEAR(h.distance, length(evaluate(arch, t1) - from), 1e-14);
      ASSERT_TRUE(intersect_cubic_from(moved_arch, t0, moved_in, kInfinity, &hm));
      EXPECT_NEAR(hm.t, h.t, 100 * noise);
      EXPECT_NEAR(hm.distance / tf.scale, h.distance, 100 * noise);
      const Vec2 tangent = unit_tangent(arch, t0, 1.0);
      const Ray out{moved_in.origin, normalized(tangent + 0.5 * perp(tangent))};
      EXPECT_FALSE(intersect_cubic_from(moved_arch, t0, out, kInfinity, &hm));
    }
  }
}

TEST(Intersect, CubicRejectsBehindAndBeyond) {
  const Cubic c = bezier({2, -1}, {3, 0}, {2, 0.5}, {2, 1});
  SegmentHit h;
  EXPECT_FALSE(intersect_cubic(c, Ray{{5, 0}, {1, 0}}, kInfinity, &h));  // behind
  EXPECT_FALSE(intersect_cubic(c, Ray{{0, 0}, {1, 0}}, 1.0, &h));        // beyond
  ASSERT_TRUE(intersect_cubic(c, Ray{{0, 0}, {1, 0}}, kInfinity, &h));
  // A collinear straight cubic along the ray: parallel, a miss like intersect_line.
  EXPECT_FALSE(intersect_cubic(line_as_cubic({1, 0}, {2, 0}), Ray{{0, 0}, {1, 0}}, kInfinity, &h));
}

}  // namespace
}  // namespace flatland
