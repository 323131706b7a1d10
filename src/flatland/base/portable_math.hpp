// sin, cos, exp, log and pow computed with the four basic operations only, so their results are the
// same bits on every platform: C libraries (glibc, emscripten's musl; glibc's FMA and non-FMA
// paths) implement these differently and promise no correct rounding, and results that depend
// on them per photon would differ between the desktop and the web page. Accuracy: within a few
// units in the last place of the exact value (tests/base/portable_math_test.cpp measures it
// against the C library), pow within 4 |y log x| + 4 of them.
#pragma once

namespace flatland::portable {

// For |x| < 1e6 (larger arguments return the C library's value, which no caller needs).
double sin(double x);
double cos(double x);
// Both at once (one argument reduction).
void sin_cos(double x, double& sine, double& cosine);
double exp(double x);
// x > 0 (0 gives -infinity, a negative x or NaN gives NaN).
double log(double x);
// x >= 0: x^y (0^0 = 1; 0^y = 0 for y > 0, infinity for y < 0). A negative x gives NaN.
double pow(double x, double y);
// x^n for a whole n >= 0 (small: n multiplications), the same bits everywhere.
inline double integer_power(double x, int n) {
  double result = 1.0;
  for (int i = 0; i < n; ++i) result *= x;
  return result;
}

}  // namespace flatland::portable
