#include "flatland/base/portable_math.hpp"

#include <cmath>
#include <initializer_list>
#include <limits>

namespace flatland::portable {

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// pi/2 in three parts, the first two of 33 significant bits: k * part is exact for |k| < 2^20,
// so x - k pi/2 is computed to about 2^-100 relative to pi/2 (Cody and Waite's reduction).
constexpr double kHalfPi1 = 1.5707963267341256;
constexpr double kHalfPi2 = 6.077100506303966e-11;
constexpr double kHalfPi3 = 2.0222662487959506e-21;
constexpr double kTwoOverPi = 0.6366197723675814;
// ln 2 in two parts, the first of 32 significant bits (k * part exact for |k| < 2^21).
constexpr double kLn2High = 0.6931471803691238;
constexpr double kLn2Low = 1.9082149292705877e-10;

// p(z) = sum of coefficients[i] z^(n-1-i) by Horner's rule, highest power first.
double horner(std::initializer_list<double> coefficients, double z) {
  double p = 0.0;
  for (const double coefficient : coefficients) p = p * z + coefficient;
  return p;
}

// Taylor polynomials on the reduced range |r| <= pi/4 (+ rounding): the first omitted terms,
// r^21/21! and r^22/22!, are below 1e-21, far under half an ulp of the result.
double sin_kernel(double r) {
  const double z = r * r;
  const double p =
      horner({-1.0 / 121645100408832000.0, 1.0 / 355687428096000.0, -1.0 / 1307674368000.0, 1.0 / 6227020800.0,
              -1.0 / 39916800.0, 1.0 / 362880.0, -1.0 / 5040.0, 1.0 / 120.0, -1.0 / 6.0},  // -1/19!, 1/17!, ..., -1/3!
             z);
  return r + r * z * p;
}

double cos_kernel(double r) {
  const double z = r * r;
  const double p = horner(
      {1.0 / 2432902008176640000.0, -1.0 / 6402373705728000.0, 1.0 / 20922789888000.0, -1.0 / 87178291200.0,
       1.0 / 479001600.0, -1.0 / 3628800.0, 1.0 / 40320.0, -1.0 / 720.0, 1.0 / 24.0},  // 1/20!, -1/18!, ..., 1/4!
      z);
  // 1 - z/2 + z^2 p, with the large terms added last.
  const double half = 0.5 * z;
  return (1.0 - half) + z * z * p;
}

}  // namespace

void sin_cos(double x, double& sine, double& cosine) {
  if (!(std::fabs(x) < 1e6)) {  // also NaN and infinities
    sine = std::sin(x);
    cosine = std::cos(x);
    return;
  }
  const double k = std::nearbyint(x * kTwoOverPi);
  const double r = ((x - k * kHalfPi1) - k * kHalfPi2) - k * kHalfPi3;
  const double s = sin_kernel(r);
  const double c = cos_kernel(r);
  switch (static_cast<long long>(k) & 3) {
    case 0: sine = s, cosine = c; break;
    case 1: sine = c, cosine = -s; break;
    case 2: sine = -s, cosine = -c; break;
    default: sine = -c, cosine = s; break;
  }
}

double sin(double x) {
  double s = 0.0;
  double c = 0.0;
  sin_cos(x, s, c);
  return s;
}

double cos(double x) {
  double s = 0.0;
  double c = 0.0;
  sin_cos(x, s, c);
  return c;
}

// exp(x) = 2^k exp(r), r = x - k ln 2 in [-ln2/2, ln2/2]; the Taylor polynomial to r^14 leaves
// out r^15/15! < 1e-19.
double exp(double x) {
  if (std::isnan(x)) return x;
  if (x > 709.8) return kInfinity;
  if (x < -745.2) return 0.0;
  const double k = std::nearbyint(x / 0.6931471805599453);
  const double r = (x - k * kLn2High) - k * kLn2Low;
  double p = 1.0 / 87178291200.0;  // 1/14!
  for (const double coefficient :
       {1.0 / 6227020800.0, 1.0 / 479001600.0, 1.0 / 39916800.0, 1.0 / 3628800.0, 1.0 / 362880.0, 1.0 / 40320.0,
        1.0 / 5040.0, 1.0 / 720.0, 1.0 / 120.0, 1.0 / 24.0, 1.0 / 6.0, 0.5})
    p = p * r + coefficient;
  const double e = 1.0 + (r + r * r * p);
  return std::ldexp(e, static_cast<int>(k));  // exact (scaling by a power of two)
}

// log(x) = e ln 2 + log(m), m in [sqrt(1/2), sqrt(2)); log(m) = 2 atanh(s) with s = (m - 1)/(m + 1),
// |s| <= 0.172: the series to s^25 leaves out s^27/27 < 1e-22.
double log(double x) {
  if (std::isnan(x) || x < 0.0) return kNaN;
  if (x == 0.0) return -kInfinity;
  if (std::isinf(x)) return x;
  int e = 0;
  double m = std::frexp(x, &e);  // exact: x = m 2^e, m in [0.5, 1)
  if (m < 0.7071067811865476) {
    m *= 2.0;
    --e;
  }
  const double s = (m - 1.0) / (m + 1.0);
  const double z = s * s;
  const double p = horner({1.0 / 25.0, 1.0 / 23.0, 1.0 / 21.0, 1.0 / 19.0, 1.0 / 17.0, 1.0 / 15.0, 1.0 / 13.0,
                           1.0 / 11.0, 1.0 / 9.0, 1.0 / 7.0, 1.0 / 5.0, 1.0 / 3.0},
                          z);
  const double log_m = 2.0 * s + 2.0 * s * z * p;
  const double k = static_cast<double>(e);
  return k * kLn2High + (log_m + k * kLn2Low);
}

double pow(double x, double y) {
  if (std::isnan(x) || std::isnan(y) || x < 0.0) return kNaN;
  if (y == 0.0 || x == 1.0) return 1.0;
  if (x == 0.0) return y > 0.0 ? 0.0 : kInfinity;
  return exp(y * log(x));
}

}  // namespace flatland::portable
