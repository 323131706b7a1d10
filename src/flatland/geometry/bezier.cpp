// Cubic Bezier segments: evaluation, derivatives, subdivision, bounds, arc length and its inverse.
#include "flatland/geometry/bezier.hpp"

#include "flatland/base/quadrature.hpp"
#include "flatland/base/roots.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace flatland {
namespace {

// (1 - t) a + t b: unlike a + t (b - a) it returns a at t = 0 and b at t = 1 exactly, so a curve's
// end points are reproduced bit for bit and neighbouring segments agree at their joint.
constexpr Vec2 mix(Vec2 a, Vec2 b, double t) {
  const double s = 1.0 - t;
  return {s * a.x + t * b.x, s * a.y + t * b.y};
}

// The blossom (polar form) of the cubic: b(u,u,u) = C(u), and the control points of the piece
// between t0 and t1 are b(t0,t0,t0), b(t0,t0,t1), b(t0,t1,t1), b(t1,t1,t1). Evaluated by de
// Casteljau with a different parameter per level.
Vec2 blossom(const Cubic& c, double u, double v, double w) {
  const Vec2 a = mix(c.p[0], c.p[1], u);
  const Vec2 b = mix(c.p[1], c.p[2], u);
  const Vec2 d = mix(c.p[2], c.p[3], u);
  const Vec2 e = mix(a, b, v);
  const Vec2 f = mix(b, d, v);
  return mix(e, f, w);
}

// Real roots of a t^2 + b t + c = 0 that lie in the open interval (0,1), ascending; returns how
// many. Stable form: q = -(b + sign(b) sqrt(b^2 - 4ac)) / 2 gives the roots q/a and c/q without
// cancellation. A quotient is formed only when it lies in [-1,1] (|q| <= |a|, |c| <= |q|), so a
// tiny leading coefficient (a "cubic" that is really of lower degree) never produces a division
// by a tiny number; with a == 0 the same formula reduces to the linear root -c/b.
int quadratic_roots_in_unit_interval(double a, double b, double c, double roots[2]) {
  const double disc = b * b - 4.0 * a * c;
  if (!(disc >= 0.0)) return 0;
  const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
  int n = 0;
  auto keep = [&](double r) {
    if (r > 0.0 && r < 1.0) roots[n++] = r;
  };
  if (q != 0.0) {
    if (std::abs(q) < std::abs(a)) keep(q / a);
    if (std::abs(c) < std::abs(q)) keep(c / q);
  } else if (a != 0.0) {
    keep(0.0);  // b == 0 and a c == 0: the double root at 0 (never interior)
  }
  if (n == 2) {
    if (roots[0] > roots[1]) std::swap(roots[0], roots[1]);
    if (roots[0] == roots[1]) n = 1;
  }
  return n;
}

// |C'(t)|: the integrand of every arc length.
double speed(const Cubic& c, double t) { return length(derivative(c, t)); }

// Integral of |C'| over [a,b] by the 8-point Gauss-Legendre rule (exact for degree 15), its
// symmetric nodes +-x_i taken in pairs.
double gauss_length(const Cubic& c, double a, double b) {
  const double half = 0.5 * (b - a);
  const double mid = 0.5 * (a + b);
  double sum = 0.0;
  for (std::size_t i = 4; i < 8; ++i) {
    const double dx = half * gauss::kNodes8[i];
    sum += gauss::kWeights8[i] * (speed(c, mid - dx) + speed(c, mid + dx));
  }
  return half * sum;
}

// Adaptive refinement: `whole` is the rule on [a,b]; the two halves are accepted when they agree
// with it to `tolerance` (the difference estimates the error of `whole`, and the halves are much
// more accurate still). The speed is smooth except at cusps (a kink of |C'|), where only the
// interval holding the kink keeps splitting.
double adaptive_length(const Cubic& c, double a, double b, double whole, double tolerance, int depth) {
  const double m = 0.5 * (a + b);
  const double left = gauss_length(c, a, m);
  const double right = gauss_length(c, m, b);
  const double sum = left + right;
  if (depth <= 0 || std::abs(sum - whole) <= tolerance || !(m > a && m < b)) return sum;
  return adaptive_length(c, a, m, left, tolerance, depth - 1) + adaptive_length(c, m, b, right, tolerance, depth - 1);
}

// Extrema of one coordinate: the roots in (0,1) of the derivative of the Bezier polynomial with
// coefficients k0..k3, that is of the quadratic Bezier with coefficients d_i = k_(i+1) - k_i,
// whose power form is (d0 - 2 d1 + d2) t^2 + 2 (d1 - d0) t + d0.
int coordinate_extrema(double k0, double k1, double k2, double k3, double roots[2]) {
  const double d0 = k1 - k0;
  const double d1 = k2 - k1;
  const double d2 = k3 - k2;
  return quadratic_roots_in_unit_interval(d0 - 2.0 * d1 + d2, 2.0 * (d1 - d0), d0, roots);
}

}  // namespace

Cubic line_as_cubic(Vec2 a, Vec2 b) { return Cubic{{a, mix(a, b, 1.0 / 3.0), mix(a, b, 2.0 / 3.0), b}}; }

Vec2 evaluate(const Cubic& c, double t) { return blossom(c, t, t, t); }

Vec2 derivative(const Cubic& c, double t) {
  const Vec2 d0 = c.p[1] - c.p[0];
  const Vec2 d1 = c.p[2] - c.p[1];
  const Vec2 d2 = c.p[3] - c.p[2];
  return 3.0 * mix(mix(d0, d1, t), mix(d1, d2, t), t);
}

Vec2 second_derivative(const Cubic& c, double t) {
  const Vec2 e0 = c.p[2] - 2.0 * c.p[1] + c.p[0];
  const Vec2 e1 = c.p[3] - 2.0 * c.p[2] + c.p[1];
  return 6.0 * mix(e0, e1, t);
}

// Near t, C'(t + h) = C'(t) + h C''(t) + h^2/2 C'''. Where C'(t) vanishes the first non-vanishing
// term gives the direction of travel: from the right (h > 0) for t < 1/2 and from the left (h < 0,
// hence -C'') for t >= 1/2, so each end point gets the limit from inside the segment. At t = 0 with
// P0 == P1 this is the direction P2 - P0; with P0 == P1 == P2 it is P3 - P0 (from C''').
Vec2 unit_tangent(const Cubic& c, double t, double scale) {
  const double zero = 1e-12 * scale;
  const Vec2 d1 = derivative(c, t);
  const double l1 = length(d1);
  if (l1 > zero) return (1.0 / l1) * d1;
  const Vec2 d2 = (t < 0.5 ? 1.0 : -1.0) * second_derivative(c, t);
  const double l2 = length(d2);
  if (l2 > zero) return (1.0 / l2) * d2;
  const Vec2 d3 = 6.0 * ((c.p[3] - c.p[0]) + 3.0 * (c.p[1] - c.p[2]));
  const double l3 = length(d3);
  if (l3 > zero) return (1.0 / l3) * d3;
  // All control points coincide (rejected by scene validation); any unit vector is as good.
  const Vec2 chord = c.p[3] - c.p[0];
  const double lc = length(chord);
  return lc > 0.0 ? (1.0 / lc) * chord : Vec2{1.0, 0.0};
}

Vec2 unit_normal(const Cubic& c, double t, double scale) { return perp(unit_tangent(c, t, scale)); }

std::pair<Cubic, Cubic> split(const Cubic& c, double t) {
  const Vec2 a = mix(c.p[0], c.p[1], t);
  const Vec2 b = mix(c.p[1], c.p[2], t);
  const Vec2 d = mix(c.p[2], c.p[3], t);
  const Vec2 e = mix(a, b, t);
  const Vec2 f = mix(b, d, t);
  const Vec2 m = mix(e, f, t);
  return {Cubic{{c.p[0], a, e, m}}, Cubic{{m, f, d, c.p[3]}}};
}

Cubic subsegment(const Cubic& c, double t0, double t1) {
  return Cubic{{blossom(c, t0, t0, t0), blossom(c, t0, t0, t1), blossom(c, t0, t1, t1), blossom(c, t1, t1, t1)}};
}

Box hull_bounds(const Cubic& c) {
  Box box;
  for (const Vec2& p : c.p) box.extend(p);
  return box;
}

Box tight_bounds(const Cubic& c) {
  Box box;
  box.extend(c.p[0]);
  box.extend(c.p[3]);
  double roots[2];
  const int nx = coordinate_extrema(c.p[0].x, c.p[1].x, c.p[2].x, c.p[3].x, roots);
  for (int i = 0; i < nx; ++i) box.extend(evaluate(c, roots[i]));
  const int ny = coordinate_extrema(c.p[0].y, c.p[1].y, c.p[2].y, c.p[3].y, roots);
  for (int i = 0; i < ny; ++i) box.extend(evaluate(c, roots[i]));
  return box;
}

// C'(t) is the quadratic Bezier Q with control points D_i = 3 (P_(i+1) - P_i). On each of 8 equal
// subintervals [u,v] its control points are the blossoms Q(u,u), Q(u,v), Q(v,v); |.| is convex,
// so |Q| on [u,v] is at most the largest of their norms (convex hull property). The middle point
// lies within (v-u)^2/4 |D0 - 2 D1 + D2| <= 8 max|Q| / 256 of the curve, so the bound exceeds the
// true maximum by at most about 3%. The last factor covers rounding.
double speed_bound(const Cubic& c) { return speed_bound(c, 0.0, 1.0); }

double speed_bound(const Cubic& c, double t0, double t1) {
  // C' is a quadratic Bezier with control points d0, d1, d2; its blossom q(u, v) gives the control
  // points q(a, a), q(a, b), q(b, b) of its restriction to [a, b], whose hull holds C' there.
  const Vec2 d0 = 3.0 * (c.p[1] - c.p[0]);
  const Vec2 d1 = 3.0 * (c.p[2] - c.p[1]);
  const Vec2 d2 = 3.0 * (c.p[3] - c.p[2]);
  auto q = [&](double u, double v) { return mix(mix(d0, d1, u), mix(d1, d2, u), v); };
  constexpr int kPieces = 8;
  double bound = 0.0;
  for (int k = 0; k < kPieces; ++k) {
    const double u = t0 + (t1 - t0) * (k / double(kPieces));
    const double v = k + 1 == kPieces ? t1 : t0 + (t1 - t0) * ((k + 1) / double(kPieces));
    bound = std::max({bound, length(q(u, u)), length(q(u, v)), length(q(v, v))});
  }
  return bound * (1.0 + 1e-12);
}

// |C'| is smooth except where C' vanishes (a cusp: a kink like |t - t*|), and nearly so where |C'|
// has a deep minimum. There the error estimate of the adaptive rule can vanish by accident, so the
// interval is first cut at the roots of x'(t) and y'(t), which contain every cusp; each piece then
// has its kink (if any) at an end, where the rule converges quickly.
double arc_length(const Cubic& c, double t0, double t1) {
  if (!(t1 > t0)) return 0.0;
  double cuts[6];
  int n = coordinate_extrema(c.p[0].x, c.p[1].x, c.p[2].x, c.p[3].x, cuts + 1);
  n += coordinate_extrema(c.p[0].y, c.p[1].y, c.p[2].y, c.p[3].y, cuts + 1 + n);
  // Keep the cuts inside (t0, t1), sorted, with t0 and t1 as the ends.
  int inside = 0;
  for (int i = 1; i <= n; ++i) {
    if (cuts[i] > t0 && cuts[i] < t1) cuts[1 + inside++] = cuts[i];
  }
  for (int i = 2; i <= inside; ++i) {  // insertion sort of at most four values
    for (int j = i; j > 1 && cuts[j] < cuts[j - 1]; --j) std::swap(cuts[j], cuts[j - 1]);
  }
  cuts[0] = t0;
  cuts[inside + 1] = t1;
  double pieces[5];
  double estimate = 0.0;
  for (int i = 0; i <= inside; ++i) {
    pieces[i] = gauss_length(c, cuts[i], cuts[i + 1]);
    estimate += pieces[i];
  }
  if (estimate == 0.0) return 0.0;  // all control points coincide
  const double tolerance = 1e-14 * estimate;
  double sum = 0.0;
  for (int i = 0; i <= inside; ++i) {
    sum += adaptive_length(c, cuts[i], cuts[i + 1], pieces[i], tolerance, 50);
  }
  return sum;
}

// C'(t) = 0 needs both coordinates of C' to vanish, so every cusp is a root of x'(t) or of y'(t).
// Each candidate is refined by Newton steps on d/dt |C'|^2 / 2 = C'.C'' (which also repairs a
// candidate that came from an inaccurate double root), and accepted when |C'| is below the
// same threshold unit_tangent uses, 1e-12 scale.
std::optional<double> find_cusp(const Cubic& c, double scale) {
  const double zero = 1e-12 * scale;
  double candidates[4];
  int n = coordinate_extrema(c.p[0].x, c.p[1].x, c.p[2].x, c.p[3].x, candidates);
  n += coordinate_extrema(c.p[0].y, c.p[1].y, c.p[2].y, c.p[3].y, candidates + n);
  std::optional<double> best;
  double best_speed = std::numeric_limits<double>::infinity();
  const Vec2 third = 6.0 * ((c.p[3] - c.p[0]) + 3.0 * (c.p[1] - c.p[2]));
  for (int i = 0; i < n; ++i) {
    double t = candidates[i];
    for (int iteration = 0; iteration < 4; ++iteration) {
      const Vec2 d1 = derivative(c, t);
      const Vec2 d2 = second_derivative(c, t);
      const double slope = dot(d1, d2);
      const double curvature = dot(d2, d2) + dot(d1, third);
      if (!(curvature > 0.0)) break;
      const double next = t - slope / curvature;
      if (!(next > 0.0 && next < 1.0) || next == t) break;
      t = next;
    }
    const double s = length(derivative(c, t));
    if (s <= zero && s < best_speed) {
      best = t;
      best_speed = s;
    }
  }
  return best;
}

// Cumulative lengths at t = k/16 (k/16 is exact in binary, so length_at starts from exact knots).
// An interval is marked smooth when the single 8-point rule over it and over its two halves agrees
// with the adaptive value to 1e-15 of the total, and no coordinate extremum inside it is a
// near-cusp (|C'| below 1e-3 of the largest speed): then the rule is also exact to rounding on any
// part of it, and length_at and parameter_at use it directly.
ArcLengthTable::ArcLengthTable(const Cubic& c) {
  double pieces[kIntervals];
  lengths_[0] = 0.0;
  for (int k = 0; k < kIntervals; ++k) {
    pieces[k] = arc_length(c, k / double(kIntervals), (k + 1) / double(kIntervals));
    lengths_[k + 1] = lengths_[k] + pieces[k];
  }
  for (int k = 0; k <= kIntervals; ++k) speeds_[k] = speed(c, k / double(kIntervals));
  const double total = lengths_[kIntervals];
  double extrema[4];
  int n = coordinate_extrema(c.p[0].x, c.p[1].x, c.p[2].x, c.p[3].x, extrema);
  n += coordinate_extrema(c.p[0].y, c.p[1].y, c.p[2].y, c.p[3].y, extrema + n);
  const double fast = speed_bound(c);
  smooth_ = 0;
  for (int k = 0; k < kIntervals; ++k) {
    const double a = k / double(kIntervals);
    const double b = (k + 1) / double(kIntervals);
    const double m = 0.5 * (a + b);
    bool smooth = std::abs(gauss_length(c, a, b) - pieces[k]) <= 1e-15 * total &&
                  std::abs(gauss_length(c, a, m) + gauss_length(c, m, b) - pieces[k]) <= 1e-15 * total;
    for (int i = 0; i < n; ++i) {
      if (extrema[i] > a && extrema[i] < b && speed(c, extrema[i]) < 1e-3 * fast) smooth = false;
    }
    if (smooth) smooth_ |= 1u << k;
  }
}

double ArcLengthTable::length_from_knot(const Cubic& c, int k, double t) const {
  const double knot = k / double(kIntervals);
  return (smooth_ >> k) & 1u ? gauss_length(c, knot, t) : arc_length(c, knot, t);
}

double ArcLengthTable::length_at(const Cubic& c, double t) const {
  if (!(t > 0.0)) return 0.0;
  if (t >= 1.0) return lengths_[kIntervals];
  const int k = std::min(int(t * kIntervals), kIntervals - 1);
  return lengths_[k] + length_from_knot(c, k, t);
}

// Solve s(t) = s_target. The table brackets the answer in one interval [t_k, t_(k+1)]; Newton steps
// t -= (s(t) - s_target) / |C'(t)| refine it, and a step that leaves the current bracket (or a zero
// speed at a coincident end control point) falls back to bisection, so the iteration always
// converges. s(t) is integrated from the interval's knot each time, so errors do not accumulate.
double ArcLengthTable::parameter_at(const Cubic& c, double s) const {
  const double total = lengths_[kIntervals];
  if (!(s > 0.0)) return 0.0;
  if (s >= total) return 1.0;
  // First knot with length > s; the answer lies in [t_(k-1), t_k].
  const auto it = std::upper_bound(lengths_.begin(), lengths_.end(), s);
  const int k = std::clamp(int(it - lengths_.begin()), 1, kIntervals) - 1;
  double lo = k / double(kIntervals);
  double hi = (k + 1) / double(kIntervals);
  const double target = s - lengths_[k];
  const double interval = lengths_[k + 1] - lengths_[k];
  if (!(interval > 0.0)) return lo;
  // Initial guess: the cubic Hermite interpolant of the inverse t(s) on the interval, with the
  // slopes dt/ds = 1 / |C'| at its knots (error O(h^4) where the speed is smooth, so one or two
  // Newton steps finish); linear interpolation where a knot's speed vanishes, and clamped into the
  // interval.
  const double x = std::clamp(target / interval, 0.0, 1.0);
  double t = lo + (hi - lo) * x;
  const double v0 = speeds_[k];
  const double v1 = speeds_[k + 1];
  if (v0 > 0.0 && v1 > 0.0) {
    // On x in [0, 1]: t = lo + h (x + m0 x (1 - x)^2 - m1 x^2 (1 - x)) with m = (interval / h) / v - 1,
    // the slopes' departures from the chord's.
    const double h = hi - lo;
    const double m0 = interval / (h * v0) - 1.0;
    const double m1 = interval / (h * v1) - 1.0;
    const double guess = lo + h * (x + m0 * x * (1.0 - x) * (1.0 - x) - m1 * x * x * (1.0 - x));
    if (guess > lo && guess < hi) t = guess;
  }
  return newton_bisection([&](double at) { return length_from_knot(c, k, at) - target; },
                          [&](double at) { return speed(c, at); }, t, lo, hi, 100, 1e-15 * total,
                          [](double at, double next, double low, double high) -> std::optional<double> {
                            if (next == at || !(high > low)) return next;
                            if (high - low <= 4.0 * std::numeric_limits<double>::epsilon() * high)
                              return 0.5 * (low + high);
                            return std::nullopt;
                          });
}

CubicPoint closest_point_on_cubic(const Cubic& c, Vec2 p) {
  constexpr int kSamples = 32;
  int best = 0;
  double best_distance = INFINITY;
  for (int k = 0; k <= kSamples; ++k) {
    const double d = length_squared(evaluate(c, static_cast<double>(k) / kSamples) - p);
    if (d < best_distance) {
      best_distance = d;
      best = k;
    }
  }
  const double low = std::max(0, best - 1) / static_cast<double>(kSamples);
  const double high = std::min(kSamples, best + 1) / static_cast<double>(kSamples);
  double t = static_cast<double>(best) / kSamples;
  for (int iteration = 0; iteration < 30; ++iteration) {
    const Vec2 offset = evaluate(c, t) - p;
    const Vec2 velocity = derivative(c, t);
    const double g = dot(velocity, offset);
    const double slope = dot(velocity, velocity) + dot(second_derivative(c, t), offset);
    if (!(slope > 0.0)) break;  // not a minimum's basin: keep the sample
    const double next = std::clamp(t - g / slope, low, high);
    const bool done = std::fabs(next - t) <= 4.0 * std::numeric_limits<double>::epsilon();
    t = next;
    if (done) break;
  }
  CubicPoint nearest{t, length(evaluate(c, t) - p)};
  // Newton never loses to its start, the best sample (an end among them: the nearest point may be
  // at t = 0 or 1).
  const double sampled = std::sqrt(best_distance);
  if (sampled < nearest.distance) nearest = {static_cast<double>(best) / kSamples, sampled};
  return nearest;
}

double distance_to_cubic(const Cubic& c, Vec2 p) { return closest_point_on_cubic(c, p).distance; }

}  // namespace flatland
