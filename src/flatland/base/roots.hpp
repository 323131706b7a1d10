// One safeguarded Newton iteration for every root the core solves in a bracket: the inversions of
// cumulative distributions (photon origins on a basis function or a Hermite piece, the Gaussian ray
// profile), the inversion of a cubic's arc length, and, where no slope is given, bisection. (The
// ray caster's roots of a cubic take Halley's third-order step instead: geometry/intersect.cpp.)
#pragma once

#include <cmath>
#include <optional>

namespace flatland {

// Solves f(x) = 0 for an f that increases on [lo, hi] (f(lo) <= 0 <= f(hi)), from x in [lo, hi]:
//   g = f(x), and |g| <= value_tolerance ends it at x;
//   the bracket keeps the root: lo = x where g < 0, hi = x otherwise;
//   the next point is Newton's step x - g / slope(x) where the slope is positive, and the bracket's
//   middle where it is not or where the step would leave the bracket;
//   stop(x, next, lo, hi) ends it with the value it returns (the caller's tests of the step's
//   size or the bracket's width), or with nothing it goes on from next;
// and after `iterations` points it ends at the last. The bracket makes it converge whatever the
// slope does; Newton's step makes it take a few points near a simple root. A slope of 0 everywhere
// bisects.
template <class Value, class Slope, class Stop>
double newton_bisection(const Value& f, const Slope& slope, double x, double lo, double hi, int iterations,
                        double value_tolerance, const Stop& stop) {
  for (int iteration = 0; iteration < iterations; ++iteration) {
    const double g = f(x);
    if (std::fabs(g) <= value_tolerance) return x;
    if (g < 0.0) {
      lo = x;
    } else {
      hi = x;
    }
    const double d = slope(x);
    double next = d > 0.0 ? x - g / d : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    if (const std::optional<double> end = stop(x, next, lo, hi)) return *end;
    x = next;
  }
  return x;
}

}  // namespace flatland
