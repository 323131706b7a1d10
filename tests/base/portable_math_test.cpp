// The portable sin, cos, exp, log and pow against the C library (glibc, itself within one ulp of the
// exact value) on dense random arguments. The portable functions are Taylor polynomials whose
// truncation is below 1e-19 relative, evaluated in a handful of roundings: within 3 ulps of the
// exact value, so within 4 of glibc's. pow is exp(y log x): log's 3 ulps and the product's rounding
// make an absolute error of up to 4 |y log x| ulps in y log x, which exp turns into the same
// relative error: 4 |y log x| + 4 ulps in all.
#include "flatland/base/portable_math.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>

namespace flatland {
namespace {

// |a - b| in units in the last place of b.
double ulps(double a, double b) {
  if (a == b) return 0.0;
  return std::fabs(a - b) / std::fabs(std::nextafter(b, std::numeric_limits<double>::infinity()) - b);
}

TEST(PortableMath, SineAndCosineWithinFourUlps) {
  std::mt19937_64 random(1);
  std::uniform_real_distribution<double> uniform(-20.0, 20.0);
  for (int i = 0; i < 200'000; ++i) {
    const double x = uniform(random);
    ASSERT_LE(ulps(portable::sin(x), std::sin(x)), 4.0) << x;
    ASSERT_LE(ulps(portable::cos(x), std::cos(x)), 4.0) << x;
  }
  // Small arguments, the quadrant boundaries and the exact values.
  for (const double x : {1e-300, 1e-8, 0.25 * std::numbers::pi, 0.5 * std::numbers::pi, std::numbers::pi, 1e5}) {
    EXPECT_LE(ulps(portable::sin(x), std::sin(x)), 4.0) << x;
    EXPECT_LE(ulps(portable::cos(x), std::cos(x)), 4.0) << x;
  }
  EXPECT_EQ(portable::sin(0.0), 0.0);
  EXPECT_EQ(portable::cos(0.0), 1.0);
  EXPECT_EQ(portable::sin(-1e-200), -1e-200);
  double s = 0.0;
  double c = 0.0;
  portable::sin_cos(2.5, s, c);
  EXPECT_EQ(s, portable::sin(2.5));
  EXPECT_EQ(c, portable::cos(2.5));
}

TEST(PortableMath, ExponentialAndLogarithmWithinFourUlps) {
  std::mt19937_64 random(2);
  std::uniform_real_distribution<double> uniform(-700.0, 700.0);
  for (int i = 0; i < 200'000; ++i) {
    const double x = uniform(random);
    ASSERT_LE(ulps(portable::exp(x), std::exp(x)), 4.0) << x;
    const double y = std::exp(x);
    ASSERT_LE(ulps(portable::log(y), std::log(y)), 4.0) << y;
  }
  for (const double x : {1e-300, 0.5, 0.7071067811865476, 1.0 + 1e-15, 2.0, 1e300})
    EXPECT_LE(ulps(portable::log(x), std::log(x)), 4.0) << x;
  EXPECT_EQ(portable::exp(0.0), 1.0);
  EXPECT_EQ(portable::log(1.0), 0.0);
  EXPECT_EQ(portable::exp(-800.0), 0.0);
  EXPECT_EQ(portable::exp(800.0), std::numeric_limits<double>::infinity());
  EXPECT_EQ(portable::log(0.0), -std::numeric_limits<double>::infinity());
  EXPECT_TRUE(std::isnan(portable::log(-1.0)));
  EXPECT_TRUE(std::isnan(portable::exp(std::numeric_limits<double>::quiet_NaN())));
}

TEST(PortableMath, PowerWithinItsConditionNumber) {
  std::mt19937_64 random(3);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int i = 0; i < 200'000; ++i) {
    // The lobe's use: a cosine in (0, 1] to an exponent in [0, 1000].
    const double x = unit(random);
    const double y = 1000.0 * unit(random) * unit(random);
    const double expected = std::pow(x, y);
    if (expected < std::numeric_limits<double>::min()) continue;  // subnormal: fewer bits to compare
    ASSERT_LE(ulps(portable::pow(x, y), expected), 4.0 * std::fabs(y * std::log(x)) + 4.0) << x << "^" << y;
  }
  EXPECT_EQ(portable::pow(0.3, 0.0), 1.0);
  EXPECT_EQ(portable::pow(0.0, 0.0), 1.0);
  EXPECT_EQ(portable::pow(0.0, 2.5), 0.0);
  EXPECT_EQ(portable::pow(1.0, 1e6), 1.0);
  EXPECT_TRUE(std::isnan(portable::pow(-0.5, 2.0)));
}

TEST(PortableMath, IntegerPowerIsRepeatedMultiplication) {
  EXPECT_EQ(portable::integer_power(1.7, 0), 1.0);
  EXPECT_EQ(portable::integer_power(2.0, 10), 1024.0);  // exact: powers of two
  EXPECT_EQ(portable::integer_power(1.5, 3), 3.375);
  EXPECT_EQ(portable::integer_power(0.1, 4), 0.1 * 0.1 * 0.1 * 0.1);
}

}  // namespace
}  // namespace flatland
