// Ray queries against single segments: closed form for lines, bracketed Halley (Newton-type)
// iteration for cubics.
#include "flatland/geometry/intersect.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace flatland {
namespace {

constexpr double kEpsilon = std::numeric_limits<double>::epsilon();

// m . (p - o) with m = perp(d): the signed distance of p to the ray's line, positive to the left.
// Every segment computes the value of a control point with this one expression, so two segments
// that share an end point see the same number there and a ray through the joint crosses exactly
// one of them (or touches both at the joint itself).
inline double side_of(Vec2 p, const Ray& ray) {
  const double x = p.x - ray.origin.x;
  const double y = p.y - ray.origin.y;
  return ray.direction.x * y - ray.direction.y * x;
}

// d . (p - o): the distance along the ray of p's projection.
inline double along(Vec2 p, const Ray& ray) {
  const double x = p.x - ray.origin.x;
  const double y = p.y - ray.origin.y;
  return ray.direction.x * x + ray.direction.y * y;
}

// Scalar cubic Bernstein polynomial by de Casteljau with (1 - t) a + t b, exact at t = 0 and 1.
inline double bernstein(const double k[4], double t) {
  const double s = 1.0 - t;
  const double a = s * k[0] + t * k[1];
  const double b = s * k[1] + t * k[2];
  const double c = s * k[2] + t * k[3];
  const double d = s * a + t * b;
  const double e = s * b + t * c;
  return s * d + t * e;
}

// The power form a0 + a1 t + a2 t^2 + a3 t^3 of the Bernstein coefficients k0..k3.
struct Power {
  double a0, a1, a2, a3;
};
inline Power to_power(const double k[4]) {
  return {k[0], 3.0 * (k[1] - k[0]), 3.0 * ((k[0] + k[2]) - 2.0 * k[1]), (k[3] - k[0]) + 3.0 * (k[1] - k[2])};
}
inline double value(const Power& f, double t) { return ((f.a3 * t + f.a2) * t + f.a1) * t + f.a0; }
inline double slope(const Power& f, double t) { return (3.0 * f.a3 * t + 2.0 * f.a2) * t + f.a1; }

// Real roots of a t^2 + b t + c in [0,1] (`closed`) or in (0,1), ascending. Stable form
// q = -(b + sign(b) sqrt(b^2 - 4ac)) / 2 with roots q/a and c/q; a quotient is formed only when
// its magnitude is at most 1, so a tiny leading coefficient never divides (with a == 0 this is the
// linear root -c/b). `simple_only` drops a double root (discriminant exactly 0): the polynomial
// does not change sign there.
int quadratic_roots(double a, double b, double c, bool closed, bool simple_only, double roots[2]) {
  const double disc = b * b - 4.0 * a * c;
  if (!(disc >= 0.0) || (simple_only && disc == 0.0)) return 0;
  const double q = -0.5 * (b + std::copysign(std::sqrt(disc), b));
  int n = 0;
  auto keep = [&](double r) {
    if (closed ? (r >= 0.0 && r <= 1.0) : (r > 0.0 && r < 1.0)) roots[n++] = r;
  };
  if (q != 0.0) {
    if (std::abs(q) <= std::abs(a)) keep(q / a);
    if (std::abs(c) <= std::abs(q)) keep(c / q);
  } else if (a != 0.0 && !simple_only) {
    keep(0.0);  // b == 0 and a c == 0: the double root at 0
  }
  if (n == 2) {
    if (roots[0] > roots[1]) std::swap(roots[0], roots[1]);
    if (roots[0] == roots[1]) n = 1;
  }
  return n;
}

inline double curvature(const Power& f, double t) { return 6.0 * f.a3 * t + 2.0 * f.a2; }

// The root of f in [u,v], where it is the only one and f(u), f(v) have strictly opposite signs (a
// monotone piece, or all of [0,1] when Descartes' rule allows only one root).
//
// f'' is linear, so if it changes sign inside (the inflection) the piece is first cut there,
// keeping the half with the sign change; f is then convex or concave on [u,v]. The first guess is
// where the piece's control polygon crosses zero (its Bernstein coefficients follow from f and f'
// at the ends: f(u), f(u) + h f'(u), f(v) - h f'(v), f(v) with h = (v-u)/3), which is within
// O((v-u)^2) of the root. Halley's iteration t -= f f' / (f'^2 - f f''/2) (a cubic's f'' is at
// hand) then converges cubically. The bracket [lo,hi] is kept, and a step that leaves it bisects
// instead.
//
// It stops when the next correction is below the resolution of t, when |f(t)| is down to the
// rounding `noise` of evaluating f (any further step would chase rounding), or when the steps show
// cubic convergence (|step| / previous^3 estimates the constant) and predict that the step just
// computed lands within half an ulp; the last correction is applied without evaluating f again.
double bracketed_root(const Power& f, double u, double v, double fu, double fv, double noise) {
  const double cu = curvature(f, u);
  const double cv = curvature(f, v);
  if ((cu < 0.0 && cv > 0.0) || (cu > 0.0 && cv < 0.0)) {
    const double inflection = u + (v - u) * (cu / (cu - cv));  // |cu / (cu - cv)| < 1
    const double fi = value(f, inflection);
    if (fi == 0.0) return inflection;
    if ((fi < 0.0) == (fu < 0.0)) {
      u = inflection;
      fu = fi;
    } else {
      v = inflection;
      fv = fi;
    }
  }
  const double h = (v - u) / 3.0;
  const double b[4] = {fu, fu + h * slope(f, u), fv - h * slope(f, v), fv};
  int i = 0;
  while (i < 2 && ((b[i] < 0.0) == (b[i + 1] < 0.0))) ++i;
  double s = b[i] / (b[i] - b[i + 1]);
  if (!(s >= 0.0 && s <= 1.0)) s = 0.5;
  double t = u + h * (i + s);
  if (!(t > u && t < v)) t = 0.5 * (u + v);

  const bool rising = fu < 0.0;
  double lo = u;
  double hi = v;
  double moved = 0.0;  // the last Halley step taken (0: none yet, or a bisection)
  for (int iteration = 0; iteration < 100; ++iteration) {
    const double ft = value(f, t);
    if (ft == 0.0) return t;
    if ((ft < 0.0) == rising) {
      lo = t;
    } else {
      hi = t;
    }
    const double d1 = slope(f, t);
    const double d2 = curvature(f, t);
    const double step = ft * d1 / (d1 * d1 - 0.5 * ft * d2);
    const double size = std::abs(step);
    const double next = t - step;
    if (size <= 2.0 * kEpsilon * std::abs(t) || std::abs(ft) <= noise ||
        (size <= 1e-3 * moved && size * size * size * size <= 0.5 * kEpsilon * std::abs(t) * moved * moved * moved)) {
      return std::clamp(next, lo, hi);  // the root is inside the bracket
    }
    if (next > lo && next < hi) {
      moved = size;
      t = next;
    } else {
      const double middle = 0.5 * (lo + hi);
      if (!(middle > lo && middle < hi)) return t;  // the bracket is down to adjacent doubles
      moved = 0.0;
      t = middle;
    }
  }
  return t;
}

}  // namespace

// The line a + t (b - a) crosses the ray's line where the signed distance (1 - t) c0 + t c1
// vanishes: t = c0 / (c0 - c1), for c0 and c1 of opposite signs or one of them zero. With c0 = 0
// the quotient is exactly 0 (and with c1 = 0 exactly 1), so end points are hit exactly. Both zero
// is a ray along the line: parallel rays miss. sigma interpolates d . (P - o) the same way, so at
// an end point it equals the value any neighbouring segment computes there.
bool intersect_line(Vec2 a, Vec2 b, const Ray& ray, double max_distance, SegmentHit* hit) {
  const double c0 = side_of(a, ray);
  const double c1 = side_of(b, ray);
  if ((c0 > 0.0 && c1 > 0.0) || (c0 < 0.0 && c1 < 0.0) || c0 == c1) return false;
  const double t = c0 / (c0 - c1);
  const double distance = (1.0 - t) * along(a, ray) + t * along(b, ray);
  if (!(distance > 0.0 && distance < max_distance)) return false;
  hit->distance = distance;
  hit->t = t;
  return true;
}

// f(t) = m . (C(t) - o) has Bernstein coefficients c_i = m . (P_i - o). Rejections, each implied by
// the convex hull property: all c_i of one strict sign (no crossing), all e_i = d . (P_i - o) <= 0
// (behind the origin), all e_i >= max_distance (beyond the range). The roots of f' (a quadratic
// with Bernstein coefficients c_(i+1) - c_i) cut [0,1] into at most three monotone pieces; a piece
// whose end values have strictly opposite signs holds exactly one crossing. A double root without
// a sign change (tangency) is a miss, also when it falls exactly on a cut. f(0) = c_0 and
// f(1) = c_3 are used as they are, so a joint shared with a neighbour is judged by the same number
// on both sides, and an end point on the ray's line is a hit (as for lines).
bool intersect_cubic(const Cubic& c, const Ray& ray, double max_distance, SegmentHit* hit) {
  const double k[4] = {side_of(c.p[0], ray), side_of(c.p[1], ray), side_of(c.p[2], ray), side_of(c.p[3], ray)};
  if (k[0] > 0.0 && k[1] > 0.0 && k[2] > 0.0 && k[3] > 0.0) return false;
  if (k[0] < 0.0 && k[1] < 0.0 && k[2] < 0.0 && k[3] < 0.0) return false;
  if (k[0] == 0.0 && k[1] == 0.0 && k[2] == 0.0 && k[3] == 0.0) return false;  // along the ray
  const double e[4] = {along(c.p[0], ray), along(c.p[1], ray), along(c.p[2], ray), along(c.p[3], ray)};
  if (e[0] <= 0.0 && e[1] <= 0.0 && e[2] <= 0.0 && e[3] <= 0.0) return false;
  if (std::min(std::min(e[0], e[1]), std::min(e[2], e[3])) >= max_distance) return false;

  const Power f = to_power(k);
  // Rounding of f evaluated in power form on [0,1]: a few ulps of the coefficients' magnitudes.
  const double noise = 8.0 * kEpsilon * (std::abs(f.a0) + std::abs(f.a1) + std::abs(f.a2) + std::abs(f.a3));
  // The common case: all c_i nonzero with exactly one sign change. By Descartes' rule of signs for
  // the Bernstein basis f then has exactly one root in (0,1) (and f(0), f(1) differ in sign), so
  // no cut into monotone pieces is needed: the safeguarded iteration runs on [0,1] directly.
  if (k[0] != 0.0 && k[1] != 0.0 && k[2] != 0.0 && k[3] != 0.0) {
    const int changes =
        ((k[0] < 0.0) != (k[1] < 0.0)) + ((k[1] < 0.0) != (k[2] < 0.0)) + ((k[2] < 0.0) != (k[3] < 0.0));
    if (changes == 1) {
      const double t = bracketed_root(f, 0.0, 1.0, k[0], k[3], noise);
      const double distance = bernstein(e, t);
      if (!(distance > 0.0 && distance < max_distance)) return false;
      hit->distance = distance;
      hit->t = t;
      return true;
    }
  }
  // f'/3 in Bernstein form has coefficients b_i = k_(i+1) - k_i; power form
  // (b0 - 2 b1 + b2) t^2 + 2 (b1 - b0) t + b0.
  const double b0 = k[1] - k[0];
  const double b1 = k[2] - k[1];
  const double b2 = k[3] - k[2];
  double cuts[4];
  cuts[0] = 0.0;
  const int n_roots = quadratic_roots((b0 + b2) - 2.0 * b1, 2.0 * (b1 - b0), b0, false, false, cuts + 1);
  const int n_cuts = n_roots + 2;
  cuts[n_cuts - 1] = 1.0;

  // f at the cuts; the end values are the end coefficients themselves.
  double values[4];
  values[0] = k[0];
  for (int i = 1; i + 1 < n_cuts; ++i) values[i] = value(f, cuts[i]);
  values[n_cuts - 1] = k[3];

  bool found = false;
  double best = max_distance;
  auto consider = [&](double t) {
    const double distance = bernstein(e, t);
    if (distance > 0.0 && distance < best) {
      best = distance;
      hit->distance = distance;
      hit->t = t;
      found = true;
    }
  };
  for (int i = 0; i < n_cuts; ++i) {
    const double fu = values[i];
    if (fu == 0.0) {
      // A root exactly on a cut. End points are inclusive (as for lines); at an interior cut (an
      // extremum of f) it is a crossing only if f changes sign across it, otherwise a tangency.
      const bool end = i == 0 || i == n_cuts - 1;
      if (end || (values[i - 1] < 0.0 && values[i + 1] > 0.0) || (values[i - 1] > 0.0 && values[i + 1] < 0.0)) {
        consider(cuts[i]);
      }
      continue;
    }
    if (i + 1 == n_cuts) break;
    const double fv = values[i + 1];
    if ((fu < 0.0 && fv > 0.0) || (fu > 0.0 && fv < 0.0)) {
      consider(bracketed_root(f, cuts[i], cuts[i + 1], fu, fv, noise));
    }
  }
  return found;
}

// The origin is C(t0), so f(t0) = 0 up to rounding. In power form f(t) = (t - t0) g(t) + r, where
// synthetic division gives the quadratic g and the remainder r = f(t0) (rounding only) is dropped.
// The crossings other than the origin are the simple roots of g in [0,1]; a double root of g is a
// tangency, and a root of g at t0 itself (f has a double root there: the ray leaves along the
// tangent) has distance 0. The distance is deflated the same way, sigma(t) = (t - t0) h(t) with
// d . (C(t) - o) = (t - t0) h(t) + r', so its sign and size are accurate even for a hit just next
// to the origin (a ray that leaves a concave curve at a grazing angle).
bool intersect_cubic_from(const Cubic& c, double t_origin, const Ray& ray, double max_distance, SegmentHit* hit) {
  const double t0 = std::clamp(t_origin, 0.0, 1.0);
  const double e[4] = {along(c.p[0], ray), along(c.p[1], ray), along(c.p[2], ray), along(c.p[3], ray)};
  if (e[0] <= 0.0 && e[1] <= 0.0 && e[2] <= 0.0 && e[3] <= 0.0) return false;
  const double k[4] = {side_of(c.p[0], ray), side_of(c.p[1], ray), side_of(c.p[2], ray), side_of(c.p[3], ray)};
  const Power f = to_power(k);
  // g = g2 t^2 + g1 t + g0 with f = (t - t0) g + r.
  const double g2 = f.a3;
  const double g1 = f.a2 + t0 * g2;
  const double g0 = f.a1 + t0 * g1;
  double roots[2];
  const int n = quadratic_roots(g2, g1, g0, true, true, roots);
  if (n == 0) return false;
  const Power s = to_power(e);
  const double h2 = s.a3;
  const double h1 = s.a2 + t0 * h2;
  const double h0 = s.a1 + t0 * h1;
  bool found = false;
  double best = max_distance;
  for (int i = 0; i < n; ++i) {
    const double t = roots[i];
    const double distance = (t - t0) * ((h2 * t + h1) * t + h0);
    if (distance > 0.0 && distance < best) {
      best = distance;
      hit->distance = distance;
      hit->t = t;
      found = true;
    }
  }
  return found;
}

}  // namespace flatland
