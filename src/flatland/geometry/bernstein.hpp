// Bernstein polynomials of degree <= 5 on an interval: subdivision and root isolation, for the
// tangent and crossing equations of the discontinuity events (polynomials in a curve's parameter).
#pragma once

#include <algorithm>
#include <cmath>
#include <optional>
#include <vector>

#include "flatland/base/roots.hpp"

namespace flatland::bernstein {

// The two halves at the middle of a polynomial with Bernstein coefficients c[0..n] (de Casteljau).
inline void split_half(const double* c, int n, double* left, double* right) {
  double w[6];
  std::copy(c, c + n + 1, w);
  left[0] = w[0];
  right[n] = w[n];
  for (int level = 1; level <= n; ++level) {
    for (int i = 0; i + level <= n; ++i) w[i] = 0.5 * (w[i] + w[i + 1]);
    left[level] = w[0];
    right[n - level] = w[n - level];
  }
}

// Sign changes of the coefficient sequence, zeros skipped: by Descartes' rule for the Bernstein
// basis an upper bound of the number of roots inside the interval, of the same parity.
inline int sign_changes(const double* c, int n) {
  int changes = 0;
  int last = 0;
  for (int i = 0; i <= n; ++i) {
    const int s = (c[i] > 0.0) - (c[i] < 0.0);
    if (s == 0) continue;
    if (last != 0 && s != last) ++changes;
    last = s;
  }
  return changes;
}

// The root of f in [lo, hi], where f changes sign: bisection on f's own sign (the polynomial's end
// signs `rising` decide which half to keep when f rounds to the wrong sign at an end).
template <class F>
double bisect(const F& f, double lo, double hi, bool rising) {
  // Newton-bisection without a slope is bisection: each point the bracket's middle, until the
  // middle is no longer strictly inside (the bracket is two adjacent doubles).
  return newton_bisection([&](double x) { return rising ? f(x) : -f(x); }, [](double) { return 0.0; }, 0.5 * (lo + hi),
                          lo, hi, 200, 0.0,
                          [](double, double next, double low, double high) -> std::optional<double> {
                            if (!(next > low && next < high)) return 0.5 * (low + high);
                            return std::nullopt;
                          });
}

// The simple (sign-changing) roots of f inside (lo, hi), where f has Bernstein coefficients c[0..n]
// on [lo, hi]. Halves the interval until the coefficients have at most one sign change (then there
// is exactly one root if the end coefficients differ in sign, none otherwise), then bisects f
// itself, evaluated directly for accuracy. Coefficients all within `noise` of zero are rounding: no
// root is claimed there. Roots exactly at lo or hi of the first call are not reported (the caller
// decides about segment ends); a double root (tangency) is not a sign change and is not reported.
template <class F>
void isolate_roots(const double* c, int n, double lo, double hi, double noise, const F& f, int depth,
                   std::vector<double>& roots) {
  double largest = 0.0;
  for (int i = 0; i <= n; ++i) largest = std::max(largest, std::fabs(c[i]));
  if (largest <= noise) return;
  const int changes = sign_changes(c, n);
  if (changes == 0) return;
  const bool opposite_ends = (c[0] < 0.0 && c[n] > 0.0) || (c[0] > 0.0 && c[n] < 0.0);
  if ((changes == 1 && opposite_ends) || depth >= 44) {
    if (opposite_ends) roots.push_back(bisect(f, lo, hi, c[0] < 0.0));
    return;
  }
  double left[6];
  double right[6];
  split_half(c, n, left, right);
  const double middle = 0.5 * (lo + hi);
  isolate_roots(left, n, lo, middle, noise, f, depth + 1, roots);
  // A root exactly at the split point: the polynomial crosses zero there.
  if (left[n] == 0.0 && ((left[n - 1] < 0.0 && right[1] > 0.0) || (left[n - 1] > 0.0 && right[1] < 0.0)))
    roots.push_back(middle);
  isolate_roots(right, n, middle, hi, noise, f, depth + 1, roots);
}

}  // namespace flatland::bernstein
