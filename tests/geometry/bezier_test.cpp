#include "flatland/geometry/bezier.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "test_support.hpp"

namespace flatland {
namespace {

// Independent references: the explicit Bernstein polynomial in long double.
using testing::bernstein_point;
using testing::LongVec;

long double distance(LongVec a, LongVec b) { return std::hypot(a.x - b.x, a.y - b.y); }
long double distance(LongVec a, Vec2 b) { return std::hypot(a.x - b.x, a.y - b.y); }

// Length of the polyline through n + 1 uniform samples, summed in long double.
long double polyline_length(const Cubic& c, double t0, double t1, int n) {
  long double sum = 0.0L;
  LongVec prev = bernstein_point(c, t0);
  for (int i = 1; i <= n; ++i) {
    const long double t = t0 + (t1 - t0) * static_cast<long double>(i) / n;
    const LongVec p = bernstein_point(c, t);
    sum += distance(prev, p);
    prev = p;
  }
  return sum;
}

// The polyline error is c2 h^2 + c4 h^4 + ...: one Richardson step on n and 2n chords leaves
// O(h^4).
long double dense_arc_length(const Cubic& c, double t0 = 0.0, double t1 = 1.0) {
  const int n = 500000;
  const long double coarse = polyline_length(c, t0, t1, n);
  const long double fine = polyline_length(c, t0, t1, 2 * n);
  return fine + (fine - coarse) / 3.0L;
}

Cubic random_cubic(std::mt19937_64& rng, double size = 1.0) {
  std::uniform_real_distribution<double> u(-size, size);
  Cubic c;
  for (Vec2& p : c.p) p = {u(rng), u(rng)};
  return c;
}

Cubic bezier(Vec2 p0, Vec2 p1, Vec2 p2, Vec2 p3) { return Cubic{{p0, p1, p2, p3}}; }

double control_size(const Cubic& c) { return hull_bounds(c).diagonal(); }

TEST(Bezier, EvaluateMatchesBernsteinPolynomial) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int trial = 0; trial < 2000; ++trial) {
    const Cubic c = random_cubic(rng, 10.0);
    for (int k = 0; k < 10; ++k) {
      const double t = unit(rng);
      const LongVec expected = bernstein_point(c, t);
      EXPECT_LT(distance(expected, evaluate(c, t)), 1e-14 * control_size(c));
    }
  }
}

TEST(Bezier, EndPointsAreReproducedExactly) {
  std::mt19937_64 rng(2);
  for (int trial = 0; trial < 1000; ++trial) {
    const Cubic c = random_cubic(rng, 1e3);
    EXPECT_EQ(evaluate(c, 0.0), c.p[0]);
    EXPECT_EQ(evaluate(c, 1.0), c.p[3]);
    const auto [left, right] = split(c, 0.3);
    EXPECT_EQ(left.p[0], c.p[0]);
    EXPECT_EQ(right.p[3], c.p[3]);
    EXPECT_EQ(left.p[3], right.p[0]);
    const Cubic whole = subsegment(c, 0.0, 1.0);
    for (int i = 0; i < 4; ++i) EXPECT_EQ(whole.p[i], c.p[i]);
  }
}

TEST(Bezier, LineAsCubicTracesTheSegmentAtConstantSpeed) {
  const Vec2 a{1.0, -2.0};
  const Vec2 b{4.0, 2.0};
  const Cubic c = line_as_cubic(a, b);
  for (double t : {0.0, 0.1, 0.25, 0.5, 0.8, 1.0}) {
    const Vec2 p = evaluate(c, t);
    EXPECT_NEAR(p.x, 1.0 + 3.0 * t, 1e-15);
    EXPECT_NEAR(p.y, -2.0 + 4.0 * t, 1e-15);
    const Vec2 v = derivative(c, t);
    EXPECT_NEAR(v.x, 3.0, 1e-14);
    EXPECT_NEAR(v.y, 4.0, 1e-14);
    const Vec2 w = second_derivative(c, t);
    EXPECT_NEAR(w.x, 0.0, 1e-14);
    EXPECT_NEAR(w.y, 0.0, 1e-14);
  }
}

TEST(Bezier, DerivativesMatchCentralDifferences) {
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> unit(0.05, 0.95);
  const double h = 1e-5;
  for (int trial = 0; trial < 500; ++trial) {
    const Cubic c = random_cubic(rng);
    const double size = control_size(c);
    for (int k = 0; k < 5; ++k) {
      const double t = unit(rng);
      const LongVec p_plus = bernstein_point(c, t + h);
      const LongVec p_minus = bernstein_point(c, t - h);
      const LongVec p_mid = bernstein_point(c, t);
      // Central differences: error h^2/6 |C'''| for the first, h^2/12 |C''''| = 0 for the second.
      const Vec2 d1 = derivative(c, t);
      EXPECT_NEAR(d1.x, double((p_plus.x - p_minus.x) / (2 * h)), 1e-8 * size);
      EXPECT_NEAR(d1.y, double((p_plus.y - p_minus.y) / (2 * h)), 1e-8 * size);
      const Vec2 d2 = second_derivative(c, t);
      EXPECT_NEAR(d2.x, double((p_plus.x - 2 * p_mid.x + p_minus.x) / (h * h)), 1e-5 * size);
      EXPECT_NEAR(d2.y, double((p_plus.y - 2 * p_mid.y + p_minus.y) / (h * h)), 1e-5 * size);
    }
  }
}

TEST(Bezier, SplitHalvesReproduceTheCurve) {
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int trial = 0; trial < 500; ++trial) {
    const Cubic c = random_cubic(rng);
    const double size = control_size(c);
    const double at = unit(rng);
    const auto [left, right] = split(c, at);
    for (int k = 0; k <= 20; ++k) {
      const double u = k / 20.0;
      EXPECT_LT(distance(bernstein_point(c, at * u), evaluate(left, u)), 1e-14 * size);
      EXPECT_LT(distance(bernstein_point(c, at + (1.0 - at) * u), evaluate(right, u)), 1e-14 * size);
    }
  }
}

TEST(Bezier, SubsegmentReproducesThePiece) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int trial = 0; trial < 500; ++trial) {
    const Cubic c = random_cubic(rng);
    const double size = control_size(c);
    double t0 = unit(rng);
    double t1 = unit(rng);
    if (t0 > t1) std::swap(t0, t1);
    const Cubic piece = subsegment(c, t0, t1);
    for (int k = 0; k <= 20; ++k) {
      const double u = k / 20.0;
      EXPECT_LT(distance(bernstein_point(c, t0 + (t1 - t0) * u), evaluate(piece, u)), 1e-14 * size);
    }
  }
}

TEST(Bezier, ArcLengthOfLinesIsTheirLength) {
  std::mt19937_64 rng(6);
  std::uniform_real_distribution<double> u(-100.0, 100.0);
  for (int trial = 0; trial < 200; ++trial) {
    const Vec2 a{u(rng), u(rng)};
    const Vec2 b{u(rng), u(rng)};
    const double expected = std::hypot(b.x - a.x, b.y - a.y);
    EXPECT_NEAR(arc_length(line_as_cubic(a, b)), expected, 1e-14 * expected);
    EXPECT_NEAR(arc_length(line_as_cubic(a, b), 0.25, 0.75), 0.5 * expected, 1e-14 * expected);
    // Collinear inner points that do not backtrack: the speed is a polynomial, still exact.
    const Cubic uneven{{a, lerp(a, b, 0.05), lerp(a, b, 0.9), b}};
    EXPECT_NEAR(arc_length(uneven), expected, 1e-14 * expected);
  }
  // A backtracking "line": from 0 out to the far point and back; the length counts both ways.
  // x(t) = 3 (1-t)^2 t 2 + 3 (1-t) t^2 2 + t^3 = 6 t (1-t) + t^3 = 6t - 6t^2 + t^3,
  // x'(t) = 6 - 12 t + 3 t^2 = 0 at t* = 2 - sqrt(2); length = 2 x(t*) - x(1).
  const Cubic back = bezier({0.0, 0.0}, {2.0, 0.0}, {2.0, 0.0}, {1.0, 0.0});
  const double ts = 2.0 - std::sqrt(2.0);
  const double peak = 6.0 * ts - 6.0 * ts * ts + ts * ts * ts;
  EXPECT_NEAR(arc_length(back), 2.0 * peak - 1.0, 1e-13);
}

TEST(Bezier, ArcLengthOfParabolaMatchesClosedForm) {
  // The quadratic (0,0), (1/2,0), (1,1) traces y = x^2 with x = t; degree-elevated to a cubic.
  const Cubic c = bezier({0.0, 0.0}, {1.0 / 3.0, 0.0}, {2.0 / 3.0, 1.0 / 3.0}, {1.0, 1.0});
  const double expected = std::sqrt(5.0) / 2.0 + std::asinh(2.0) / 4.0;
  EXPECT_NEAR(arc_length(c), expected, 1e-14 * expected);
  // From 0 to x: x sqrt(1 + 4x^2)/2 + asinh(2x)/4.
  auto closed = [](double x) { return x * std::sqrt(1 + 4 * x * x) / 2 + std::asinh(2 * x) / 4; };
  EXPECT_NEAR(arc_length(c, 0.2, 0.7), closed(0.7) - closed(0.2), 1e-14 * expected);
}

TEST(Bezier, ArcLengthOfCubicsMatchesDensePolyline) {
  std::mt19937_64 rng(7);
  std::vector<Cubic> cases = {
      bezier({0, 0}, {1, 1}, {0, 1}, {1, 0}),              // cusp: |C'| has a kink at t = 1/2
      bezier({0, 0}, {0, 0}, {1, 1}, {2, 0}),              // P0 == P1
      bezier({0, 0}, {1, 2}, {1, 2}, {2, 0}),              // P1 == P2
      bezier({0, 0}, {0, 4.0 / 3}, {1, 4.0 / 3}, {1, 0}),  // arch
      bezier({0, 0}, {3, 1}, {-2, 1}, {1, 0}),             // loop
  };
  for (int i = 0; i < 5; ++i) cases.push_back(random_cubic(rng));
  for (const Cubic& c : cases) {
    const double expected = double(dense_arc_length(c));
    EXPECT_NEAR(arc_length(c), expected, 1e-12 * expected);
    // A part whose ends keep the cusp at t = 1/2 on a polyline vertex (no corner is cut).
    const double part = double(dense_arc_length(c, 0.125, 0.625));
    EXPECT_NEAR(arc_length(c, 0.125, 0.625), part, 1e-12 * expected);
  }
}

TEST(Bezier, ArcLengthScalesWithTheCurve) {
  const Cubic c = bezier({0, 0}, {3, 1}, {-2, 1}, {1, 0});
  const double base = arc_length(c);
  for (double s : {1e-6, 1e6}) {
    Cubic scaled;
    for (int i = 0; i < 4; ++i) scaled.p[i] = s * c.p[i];
    EXPECT_NEAR(arc_length(scaled) / s, base, 1e-13 * base);
  }
  // Far from the origin the control points themselves carry rounding of 1e6 eps.
  Cubic moved;
  for (int i = 0; i < 4; ++i) moved.p[i] = c.p[i] + Vec2{1e6, -1e6};
  EXPECT_NEAR(arc_length(moved), base, 1e-9 * base);
}

TEST(Bezier, ParameterAtInvertsLengthAt) {
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Cubic> cases = {
      bezier({0, 0}, {0, 0}, {1, 1}, {2, 0}),  // zero speed at t = 0
      bezier({0, 0}, {1, 1}, {2, 0}, {2, 0}),  // zero speed at t = 1
      bezier({0, 0}, {0, 0}, {0, 0}, {2, 1}),  // zero speed and acceleration at t = 0
      bezier({0, 0}, {1, 1}, {0, 1}, {1, 0}),  // interior cusp
      line_as_cubic({0, 0}, {3, 4}),
  };
  for (int i = 0; i < 20; ++i) cases.push_back(random_cubic(rng));
  for (const Cubic& c : cases) {
    const ArcLengthTable table(c);
    const double total = table.total();
    EXPECT_NEAR(total, arc_length(c), 1e-13 * total);
    EXPECT_EQ(table.length_at(c, 0.0), 0.0);
    EXPECT_EQ(table.length_at(c, 1.0), total);
    EXPECT_EQ(table.parameter_at(c, 0.0), 0.0);
    EXPECT_EQ(table.parameter_at(c, total), 1.0);
    EXPECT_EQ(table.parameter_at(c, -1.0), 0.0);
    EXPECT_EQ(table.parameter_at(c, 2.0 * total), 1.0);
    for (int k = 0; k < 200; ++k) {
      const double t = unit(rng);
      const double s = table.length_at(c, t);
      EXPECT_NEAR(s, arc_length(c, 0.0, t), 1e-13 * total);
      const double back = table.parameter_at(c, s);
      // In length: exact to rounding. In t: up to the sensitivity dt = ds / |C'(t)|.
      EXPECT_NEAR(table.length_at(c, back), s, 1e-13 * total);
      const double speed = length(derivative(c, t));
      if (speed > 1e-3 * total) {
        EXPECT_NEAR(back, t, 1e-12 * total / speed) << "t = " << t;
      }
    }
    // Uniform arc length samples: s(t(s)) == s.
    for (int k = 0; k <= 100; ++k) {
      const double s = total * k / 100.0;
      EXPECT_NEAR(table.length_at(c, table.parameter_at(c, s)), s, 1e-13 * total);
    }
  }
}

TEST(Bezier, ParameterAtOfLineIsProportional) {
  const Cubic c = line_as_cubic({1, 1}, {4, 5});
  const ArcLengthTable table(c);
  EXPECT_NEAR(table.total(), 5.0, 1e-14);
  for (int k = 0; k <= 50; ++k) {
    const double t = k / 50.0;
    EXPECT_NEAR(table.parameter_at(c, 5.0 * t), t, 1e-14);
  }
}

TEST(Bezier, TightBoundsContainAndTouchTheCurve) {
  std::mt19937_64 rng(9);
  const int n = 100000;
  for (int trial = 0; trial < 100; ++trial) {
    const Cubic c = random_cubic(rng, 5.0);
    const double size = control_size(c);
    const Box tight = tight_bounds(c);
    const Box hull = hull_bounds(c);
    Box sampled;
    for (int i = 0; i <= n; ++i) {
      const LongVec p = bernstein_point(c, static_cast<long double>(i) / n);
      sampled.extend(Vec2{double(p.x), double(p.y)});
    }
    const double slack = 1e-14 * size;
    EXPECT_LE(tight.lower.x, sampled.lower.x + slack);
    EXPECT_LE(tight.lower.y, sampled.lower.y + slack);
    EXPECT_GE(tight.upper.x, sampled.upper.x - slack);
    EXPECT_GE(tight.upper.y, sampled.upper.y - slack);
    // Touching: an extremum lies between samples, within h^2/8 max|C''| <= 1e-9 size of them.
    EXPECT_NEAR(tight.lower.x, sampled.lower.x, 1e-8 * size);
    EXPECT_NEAR(tight.lower.y, sampled.lower.y, 1e-8 * size);
    EXPECT_NEAR(tight.upper.x, sampled.upper.x, 1e-8 * size);
    EXPECT_NEAR(tight.upper.y, sampled.upper.y, 1e-8 * size);
    EXPECT_LE(hull.lower.x, tight.lower.x);
    EXPECT_LE(hull.lower.y, tight.lower.y);
    EXPECT_GE(hull.upper.x, tight.upper.x);
    EXPECT_GE(hull.upper.y, tight.upper.y);
  }
  // A straight line: the box of its end points.
  const Box line = tight_bounds(line_as_cubic({2, 1}, {-1, 3}));
  EXPECT_EQ(line.lower.x, -1.0);
  EXPECT_EQ(line.lower.y, 1.0);
  EXPECT_EQ(line.upper.x, 2.0);
  EXPECT_EQ(line.upper.y, 3.0);
}

// |C'(t)| = |3 sum_i B_i^2(t) (P_(i+1) - P_i)|, written out in long double.
long double exact_speed(const Cubic& c, long double t) {
  const long double s = 1.0L - t;
  long double x = 0.0L;
  long double y = 0.0L;
  const long double w[3] = {s * s, 2.0L * s * t, t * t};
  for (int j = 0; j < 3; ++j) {
    x += 3.0L * w[j] * ((long double)c.p[j + 1].x - c.p[j].x);
    y += 3.0L * w[j] * ((long double)c.p[j + 1].y - c.p[j].y);
  }
  return std::hypot(x, y);
}

// The largest |C'| at n + 1 even steps over [t0, t1].
double sampled_max_speed(const Cubic& c, double t0, double t1, int n) {
  long double max_speed = 0.0L;
  for (int i = 0; i <= n; ++i)
    max_speed = std::max(max_speed, exact_speed(c, t0 + (t1 - t0) * (static_cast<long double>(i) / n)));
  return static_cast<double>(max_speed);
}

TEST(Bezier, SpeedBoundIsTightUpperBound) {
  std::mt19937_64 rng(10);
  std::vector<Cubic> cases = {
      bezier({0, 0}, {1, 1}, {0, 1}, {1, 0}),
      bezier({0, 0}, {0, 0}, {1, 1}, {2, 0}),
      bezier({0, 0}, {10, 0}, {-10, 0}, {1, 0}),
      line_as_cubic({0, 0}, {3, 4}),
  };
  for (int i = 0; i < 200; ++i) cases.push_back(random_cubic(rng));
  for (const Cubic& c : cases) {
    const double max_speed = sampled_max_speed(c, 0.0, 1.0, 20000);
    const double bound = speed_bound(c);
    EXPECT_GE(bound, max_speed);
    EXPECT_LE(bound, 1.1 * max_speed);
    EXPECT_EQ(speed_bound(c, 0.0, 1.0), bound);
    // On a part of the curve: an upper bound there, and nearly the speed itself on a short part
    // (the origins' rejection on speed draws again with the bound's excess over the speed).
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    for (const double width : {0.5, 1.0 / 16, 1.0 / 256}) {
      const double t0 = (1.0 - width) * uniform(rng);
      const double local = sampled_max_speed(c, t0, t0 + width, 2000);
      const double part = speed_bound(c, t0, t0 + width);
      EXPECT_GE(part, local) << "width " << width;
      if (width < 0.01 && local > 1e-3 * max_speed) {
        EXPECT_LE(part, 1.001 * local) << "width " << width;
      }
    }
  }
  EXPECT_NEAR(speed_bound(line_as_cubic({0, 0}, {3, 4})), 5.0, 1e-10);
}

TEST(Bezier, FindCuspDetectsTheClassicCusp) {
  const Cubic cusp = bezier({0, 0}, {1, 1}, {0, 1}, {1, 0});
  const auto t = find_cusp(cusp, 1.0);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(*t, 0.5, 1e-12);
  EXPECT_LE(length(derivative(cusp, *t)), 1e-12);
  // The same cusp scaled is found with a tolerance relative to its size.
  for (double s : {1e-3, 1e3}) {
    Cubic scaled;
    for (int i = 0; i < 4; ++i) scaled.p[i] = s * cusp.p[i];
    const auto t_scaled = find_cusp(scaled, s);
    ASSERT_TRUE(t_scaled.has_value());
    EXPECT_NEAR(*t_scaled, 0.5, 1e-12);
  }
}

TEST(Bezier, FindCuspIgnoresSmoothCurves) {
  EXPECT_FALSE(find_cusp(bezier({0, 0}, {1, 1}, {1, -1}, {2, 0}), 2.0).has_value());  // S curve
  EXPECT_FALSE(find_cusp(bezier({0, 0}, {0, 1}, {1, 1}, {1, 0}), 1.0).has_value());   // arch
  EXPECT_FALSE(find_cusp(bezier({0, 0}, {3, 1}, {-2, 1}, {1, 0}), 3.0).has_value());  // loop
  EXPECT_FALSE(find_cusp(line_as_cubic({0, 0}, {1, 2}), 2.0).has_value());
  // Coincident end control points vanish C' only at the end points, which are not interior.
  EXPECT_FALSE(find_cusp(bezier({0, 0}, {0, 0}, {1, 1}, {2, 0}), 2.0).has_value());
  EXPECT_FALSE(find_cusp(bezier({0, 0}, {1, 1}, {2, 0}, {2, 0}), 2.0).has_value());
  // Near-cusps with a clearly nonzero minimum speed are not cusps.
  EXPECT_FALSE(find_cusp(bezier({0, 0}, {1, 1}, {0, 1.001}, {1, 0}), 1.0).has_value());
}

TEST(Bezier, FindCuspDetectsReversal) {
  // A straight "line" that turns back: x'(t) = 6 - 12 t + 3 t^2 vanishes at 2 - sqrt(2).
  const auto t = find_cusp(bezier({0, 0}, {2, 0}, {2, 0}, {1, 0}), 2.0);
  ASSERT_TRUE(t.has_value());
  EXPECT_NEAR(*t, 2.0 - std::sqrt(2.0), 1e-12);
}

TEST(Bezier, UnitTangentAndNormalOfRegularCurve) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const Cubic c = random_cubic(rng);
    const double t = unit(rng);
    const Vec2 d = derivative(c, t);
    if (length(d) < 1e-3) continue;
    const Vec2 tangent = unit_tangent(c, t, 1.0);
    EXPECT_NEAR(length(tangent), 1.0, 1e-15);
    EXPECT_NEAR(cross(tangent, d), 0.0, 1e-14 * length(d));
    EXPECT_GT(dot(tangent, d), 0.0);
    const Vec2 normal = unit_normal(c, t, 1.0);
    EXPECT_NEAR(normal.x, -tangent.y, 1e-15);
    EXPECT_NEAR(normal.y, tangent.x, 1e-15);
  }
  // Counter-clockwise travel around an arch that bulges to the right: at t = 0 the travel is +x,
  // so the front normal (left of travel) is +y, towards the inside of the arch.
  const Cubic arch = bezier({0, 0}, {1, 0}, {1, 1}, {0, 1});
  const Vec2 n0 = unit_normal(arch, 0.0, 1.0);
  EXPECT_NEAR(n0.x, 0.0, 1e-15);
  EXPECT_NEAR(n0.y, 1.0, 1e-15);
}

// The direction of C'(t) for t just inside the segment, by the long double polynomial.
Vec2 limit_direction(const Cubic& c, long double t) {
  const long double s = 1.0L - t;
  const long double w[3] = {s * s, 2.0L * s * t, t * t};
  long double x = 0.0L;
  long double y = 0.0L;
  for (int j = 0; j < 3; ++j) {
    x += w[j] * ((long double)c.p[j + 1].x - c.p[j].x);
    y += w[j] * ((long double)c.p[j + 1].y - c.p[j].y);
  }
  const long double l = std::hypot(x, y);
  return {double(x / l), double(y / l)};
}

TEST(Bezier, CoincidentControlPointsGiveTheLimitTangent) {
  std::mt19937_64 rng(12);
  for (int trial = 0; trial < 200; ++trial) {
    Cubic c = random_cubic(rng);
    c.p[1] = c.p[0];  // C'(0) = 0
    const Vec2 start = unit_tangent(c, 0.0, 2.0);
    ASSERT_TRUE(is_finite(start));
    EXPECT_NEAR(length(start), 1.0, 1e-15);
    const Vec2 inside = limit_direction(c, 1e-9L);
    EXPECT_NEAR(start.x, inside.x, 1e-7);
    EXPECT_NEAR(start.y, inside.y, 1e-7);
    // The limit is the direction to the next distinct control point, P2 - P0.
    const Vec2 chord = normalized(c.p[2] - c.p[0]);
    EXPECT_NEAR(start.x, chord.x, 1e-14);
    EXPECT_NEAR(start.y, chord.y, 1e-14);
    const Vec2 normal = unit_normal(c, 0.0, 2.0);
    EXPECT_NEAR(normal.x, -start.y, 1e-15);
    EXPECT_NEAR(normal.y, start.x, 1e-15);

    Cubic d = random_cubic(rng);
    d.p[2] = d.p[3];  // C'(1) = 0: the limit from inside points from P1 to P3
    const Vec2 end = unit_tangent(d, 1.0, 2.0);
    const Vec2 before = limit_direction(d, 1.0L - 1e-9L);
    EXPECT_NEAR(end.x, before.x, 1e-7);
    EXPECT_NEAR(end.y, before.y, 1e-7);
    const Vec2 back = normalized(d.p[3] - d.p[1]);
    EXPECT_NEAR(end.x, back.x, 1e-14);
    EXPECT_NEAR(end.y, back.y, 1e-14);

    Cubic e = random_cubic(rng);
    e.p[1] = e.p[0];
    e.p[2] = e.p[0];  // C' and C'' vanish at 0: the direction is P3 - P0
    const Vec2 third = unit_tangent(e, 0.0, 2.0);
    const Vec2 chord3 = normalized(e.p[3] - e.p[0]);
    EXPECT_NEAR(third.x, chord3.x, 1e-14);
    EXPECT_NEAR(third.y, chord3.y, 1e-14);
    const Vec2 third_end = unit_tangent(e, 1.0, 2.0);
    const Vec2 end3 = normalized(e.p[3] - e.p[2]);
    EXPECT_NEAR(third_end.x, end3.x, 1e-14);
    EXPECT_NEAR(third_end.y, end3.y, 1e-14);
  }
}

TEST(Bezier, DegenerateTangentIsRelativeToScale) {
  // The same configuration at a tiny scale: |C'(0)| = 0 exactly, the limit is still found, and a
  // genuinely small (but not vanishing) derivative is used as it is.
  const double s = 1e-9;
  const Cubic c = bezier({0, 0}, {0, 0}, {s, s}, {2 * s, 0});
  const Vec2 t0 = unit_tangent(c, 0.0, 2 * s);
  EXPECT_NEAR(t0.x, std::sqrt(0.5), 1e-14);
  EXPECT_NEAR(t0.y, std::sqrt(0.5), 1e-14);
  const Cubic small_line = line_as_cubic({0, 0}, {0, s});
  const Vec2 up = unit_tangent(small_line, 0.5, s);
  EXPECT_NEAR(up.x, 0.0, 1e-15);
  EXPECT_NEAR(up.y, 1.0, 1e-15);
}

}  // namespace
}  // namespace flatland
