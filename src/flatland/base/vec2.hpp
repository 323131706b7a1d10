// Two-dimensional vectors in double precision: the only geometric primitive of the core.
#pragma once

#include <algorithm>
#include <cmath>

namespace flatland {

struct Vec2 {
  double x = 0.0;
  double y = 0.0;
};

constexpr Vec2 operator+(Vec2 a, Vec2 b) { return {a.x + b.x, a.y + b.y}; }
constexpr Vec2 operator-(Vec2 a, Vec2 b) { return {a.x - b.x, a.y - b.y}; }
constexpr Vec2 operator-(Vec2 a) { return {-a.x, -a.y}; }
constexpr Vec2 operator*(double s, Vec2 a) { return {s * a.x, s * a.y}; }
constexpr Vec2 operator*(Vec2 a, double s) { return {s * a.x, s * a.y}; }
constexpr bool operator==(Vec2 a, Vec2 b) { return a.x == b.x && a.y == b.y; }

constexpr double dot(Vec2 a, Vec2 b) { return a.x * b.x + a.y * b.y; }
// z component of the 3D cross product: positive when b is counter-clockwise from a.
constexpr double cross(Vec2 a, Vec2 b) { return a.x * b.y - a.y * b.x; }
// a rotated by +90 degrees: the left normal of a direction of travel.
constexpr Vec2 perp(Vec2 a) { return {-a.y, a.x}; }
// sqrt of the dot product, not std::hypot: hypot guards against overflow beyond 1e150, which no
// scene reaches, at several times the cost in the ray caster's inner loops.
inline double length(Vec2 a) { return std::sqrt(a.x * a.x + a.y * a.y); }
constexpr double length_squared(Vec2 a) { return dot(a, a); }
inline Vec2 normalized(Vec2 a) { return (1.0 / length(a)) * a; }
constexpr Vec2 lerp(Vec2 a, Vec2 b, double t) { return {a.x + t * (b.x - a.x), a.y + t * (b.y - a.y)}; }
inline bool is_finite(Vec2 a) { return std::isfinite(a.x) && std::isfinite(a.y); }

// Axis-aligned box; an empty box has lower > upper.
struct Box {
  Vec2 lower{INFINITY, INFINITY};
  Vec2 upper{-INFINITY, -INFINITY};

  // Comparisons, not std::fmin/fmax: those are library calls here (they must order -0 and +0
  // and handle NaN), 18 % of building the tree of 65,536 segments. A NaN point is skipped as
  // fmin skips it; -0 and +0 may differ from fmin's choice, which no bound or extent tells apart.
  void extend(Vec2 p) {
    lower = {p.x < lower.x ? p.x : lower.x, p.y < lower.y ? p.y : lower.y};
    upper = {p.x > upper.x ? p.x : upper.x, p.y > upper.y ? p.y : upper.y};
  }
  void extend(const Box& b) {
    extend(b.lower);
    extend(b.upper);
  }
  bool empty() const { return lower.x > upper.x || lower.y > upper.y; }
  Vec2 center() const { return 0.5 * (lower + upper); }
  Vec2 extent() const { return upper - lower; }
  // hypot, not sqrt(x^2 + y^2): a scene 1e-300 across has a diagonal, not 0.
  // Scaled by the larger side so that the squares neither overflow nor underflow, with IEEE basic
  // operations only (hypot's last bit differs between C libraries).
  double diagonal() const {
    if (empty()) return 0.0;
    const double dx = std::fabs(upper.x - lower.x);
    const double dy = std::fabs(upper.y - lower.y);
    const double larger = std::max(dx, dy);
    if (larger == 0.0) return 0.0;
    const double a = dx / larger;
    const double b = dy / larger;
    return larger * std::sqrt(a * a + b * b);
  }
  // The box grown by `pad` on every side.
  Box padded(double pad) const { return Box{lower - Vec2{pad, pad}, upper + Vec2{pad, pad}}; }
  // Whether the two closed boxes share a point.
  bool overlaps(const Box& b) const {
    return lower.x <= b.upper.x && b.lower.x <= upper.x && lower.y <= b.upper.y && b.lower.y <= upper.y;
  }
};

}  // namespace flatland
