#include "flatland/base/statistics.hpp"

#include <cmath>

#include <gtest/gtest.h>

namespace flatland {
namespace {

TEST(Statistics, AtanMatchesTheLibraryWithinAFewUlps) {
  for (double x = -50.0; x <= 50.0; x += 0.0137) {
    const double exact = std::atan(x);
    EXPECT_NEAR(portable::atan(x), exact, 8e-16 * std::fabs(exact) + 1e-300) << x;
  }
  EXPECT_EQ(portable::atan(0.0), 0.0);
}

TEST(Statistics, NormalProbabilitiesMatchErf) {
  for (double z = 0.01; z < 6.0; z += 0.0731) EXPECT_NEAR(normal_two_sided(z), std::erf(z / std::sqrt(2.0)), 2e-15);
}

// Two-sided quantiles from published tables (Abramowitz and Stegun 26.2, 26.7; R's qnorm, qt).
TEST(Statistics, QuantilesMatchPublishedTables) {
  EXPECT_NEAR(normal_quantile_two_sided(0.95), 1.959963984540054, 1e-12);
  EXPECT_NEAR(normal_quantile_two_sided(0.99), 2.575829303548901, 1e-12);
  EXPECT_NEAR(student_t_quantile_two_sided(0.95, 1), 12.70620473617471, 1e-9);
  EXPECT_NEAR(student_t_quantile_two_sided(0.95, 3), 3.182446305284263, 1e-11);
  EXPECT_NEAR(student_t_quantile_two_sided(0.95, 7), 2.364624251592785, 1e-11);
  EXPECT_NEAR(student_t_quantile_two_sided(0.99, 7), 3.499483297350326, 1e-11);
  EXPECT_NEAR(student_t_quantile_two_sided(0.95, 15), 2.131449545559323, 1e-11);
  EXPECT_NEAR(student_t_quantile_two_sided(0.95, 63), 1.998340542520614, 1e-11);
}

// For large nu, P(|Z| <= z) - P(|T| <= z) = 2 phi(z) (z^3 + z) / (4 nu) + O(nu^-2) (the first
// term of the t distribution's expansion about the normal, Abramowitz and Stegun 26.7.5).
TEST(Statistics, StudentTApproachesTheNormalForManyDegrees) {
  const double z = 1.96;
  const double nu = 2001.0;
  const double phi = std::exp(-0.5 * z * z) / std::sqrt(2.0 * 3.14159265358979323846);
  EXPECT_NEAR(normal_two_sided(z) - student_t_two_sided(z, 2001), 2.0 * phi * (z * z * z + z) / (4.0 * nu), 1e-7);
  EXPECT_LT(student_t_two_sided(1.96, 7), normal_two_sided(1.96));
}

}  // namespace
}  // namespace flatland
