#include "flatland/base/statistics.hpp"

#include <cmath>

#include "flatland/base/portable_math.hpp"

namespace flatland {

namespace {

constexpr double kPi = 3.14159265358979323846;

// The x in [low, high] where the increasing function f reaches `target`, halving the bracket
// until it no longer shrinks.
template <class F>
double bisect_increasing(F f, double target, double low, double high) {
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (low + high);
    if (mid <= low || mid >= high) break;
    (f(mid) < target ? low : high) = mid;
  }
  return 0.5 * (low + high);
}

}  // namespace

double portable::atan(double x) {
  if (x < 0.0) return -portable::atan(-x);
  if (x > 1.0) return 0.5 * kPi - portable::atan(1.0 / x);
  // tan(pi/12) = 2 - sqrt 3: beyond it, atan x = pi/6 + atan((x sqrt3 - 1) / (x + sqrt3)).
  constexpr double kSqrt3 = 1.7320508075688772;
  if (x > 0.2679491924311227) return kPi / 6.0 + portable::atan((x * kSqrt3 - 1.0) / (x + kSqrt3));
  // |x| <= 0.268: the series' terms fall by 0.072 each; 13 of them leave < 1e-17.
  const double z = x * x;
  double sum = 0.0;
  for (int n = 25; n >= 1; n -= 2) sum = 1.0 / n - z * sum;
  return x * sum;
}

double normal_two_sided(double z) {
  if (!(z > 0.0)) return 0.0;
  if (z > 8.0) return 1.0;
  const double x = z / std::sqrt(2.0);
  double term = x;
  double sum = x;
  for (int n = 1; n < 400 && term > 1e-18 * sum; ++n) {
    term *= 2.0 * x * x / (2.0 * n + 1.0);
    sum += term;
  }
  const double value = 2.0 / std::sqrt(kPi) * portable::exp(-x * x) * sum;
  return value < 1.0 ? value : 1.0;
}

double student_t_two_sided(double t, int odd_dof) {
  if (!(t > 0.0)) return 0.0;
  const int m = (odd_dof + 1) / 2;
  const double x = t / std::sqrt(static_cast<double>(odd_dof));
  const double one_plus = 1.0 + x * x;
  double part = portable::atan(x);  // J_1(x)
  double whole = 0.5 * kPi;         // J_1(infinity)
  double power = 1.0;               // (1 + x^2)^(k-1)
  for (int k = 2; k <= m; ++k) {
    const double ratio = (2.0 * k - 3.0) / (2.0 * (k - 1));
    part = x / (2.0 * (k - 1) * power * one_plus) + ratio * part;
    power *= one_plus;
    whole *= ratio;
  }
  const double value = part / whole;
  return value < 1.0 ? value : 1.0;
}

double normal_quantile_two_sided(double probability) {
  return bisect_increasing([](double z) { return normal_two_sided(z); }, probability, 0.0, 8.0);
}

double student_t_quantile_two_sided(double probability, int odd_dof) {
  return bisect_increasing([odd_dof](double t) { return student_t_two_sided(t, odd_dof); }, probability, 0.0, 1e6);
}

}  // namespace flatland
