#include "flatland/transport/ray_profiles.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/transport/sampling.hpp"
#include "test_support.hpp"

namespace flatland {
namespace {

// Second moments integral x^2 k(x) dx in closed form, independent of the code under test:
// box 1/3, tent 2 (1/3 - 1/4) = 1/6, Epanechnikov 3/4 (2/3 - 2/5) = 1/5, cosine 1 - 8/pi^2,
// truncated Gaussian sigma^2 (1 - 2 c phi(c) / (2 Phi(c) - 1)) with c = 3.
double second_moment(RayProfile profile) {
  switch (profile) {
    case RayProfile::Box: return 1.0 / 3.0;
    case RayProfile::Tent: return 1.0 / 6.0;
    case RayProfile::Epanechnikov: return 0.2;
    case RayProfile::Cosine: return 1.0 - 8.0 / (std::numbers::pi * std::numbers::pi);
    case RayProfile::Gauss: {
      const double phi3 = std::exp(-4.5) / std::sqrt(2.0 * std::numbers::pi);
      return (1.0 - 6.0 * phi3 / std::erf(3.0 / std::numbers::sqrt2)) / 9.0;
    }
  }
  return 0.0;
}

TEST(RayProfiles, ProfilesIntegrateToOneWithTheirMomentsAndCdf) {
  // Midpoint rule with 10^6 cells on [-1, 1]: the tent's kink at 0 is a cell boundary, so the
  // error is O(h^2) ~ 1e-12 for every profile.
  const int cells = 1'000'000;
  const double h = 2.0 / cells;
  for (RayProfile profile : kRayProfiles) {
    double mass = 0.0;
    double first = 0.0;
    double second = 0.0;
    for (int i = 0; i < cells; ++i) {
      const double x = -1.0 + (i + 0.5) * h;
      const double k = profile_density(profile, x);
      ASSERT_GE(k, 0.0);
      mass += h * k;
      first += h * x * k;
      second += h * x * x * k;
      if ((i + 1) % 50'000 == 0) {  // the CDF at the cell's right edge
        const double edge = -1.0 + (i + 1) * h;
        EXPECT_NEAR(profile_cdf(profile, edge), mass, 1e-11) << to_string(profile) << " x " << edge;
      }
    }
    EXPECT_NEAR(mass, 1.0, 1e-11) << to_string(profile);
    EXPECT_NEAR(first, 0.0, 1e-12) << to_string(profile);
    EXPECT_NEAR(second, second_moment(profile), 1e-11) << to_string(profile);
    EXPECT_EQ(profile_density(profile, 1.0 + 1e-12), 0.0);
    EXPECT_EQ(profile_density(profile, -1.5), 0.0);
    EXPECT_EQ(profile_cdf(profile, -1.0), 0.0);
    EXPECT_EQ(profile_cdf(profile, -2.0), 0.0);
    EXPECT_EQ(profile_cdf(profile, 1.0), 1.0);
    EXPECT_EQ(profile_cdf(profile, 3.0), 1.0);
    EXPECT_NEAR(profile_cdf(profile, 0.0), 0.5, 1e-15);
  }
  // The Gaussian's normaliser against std::erf: k(0) = 1 / (sigma sqrt(2 pi) erf(3 / sqrt 2)).
  EXPECT_NEAR(profile_density(RayProfile::Gauss, 0.0),
              3.0 / (std::sqrt(2.0 * std::numbers::pi) * std::erf(3.0 / std::numbers::sqrt2)), 1e-15);
  // Its lower tail keeps relative accuracy: F(-1 + d) ~ k(-1) d for small d.
  const double d = 1e-9;
  const double edge_density = profile_density(RayProfile::Gauss, -1.0);
  EXPECT_NEAR(profile_cdf(RayProfile::Gauss, -1.0 + d) / (edge_density * d), 1.0, 1e-6);
}

TEST(RayProfiles, SampleInvertsTheCdf) {
  for (RayProfile profile : kRayProfiles) {
    for (int i = 0; i <= 1000; ++i) {
      const double u = i / 1000.0;
      const double x = profile_sample(profile, u);
      ASSERT_GE(x, -1.0);
      ASSERT_LE(x, 1.0);
      EXPECT_NEAR(profile_cdf(profile, x), u, 2e-15) << to_string(profile) << " u " << u;
    }
    EXPECT_EQ(profile_sample(profile, 0.0), -1.0) << to_string(profile);
    EXPECT_EQ(profile_sample(profile, 1.0), 1.0) << to_string(profile);
    EXPECT_NEAR(profile_sample(profile, 0.5), 0.0, 1e-15) << to_string(profile);
    for (double x : {-0.99, -0.6, -0.1, 0.3, 0.97})
      EXPECT_NEAR(profile_sample(profile, profile_cdf(profile, x)), x, 1e-12) << to_string(profile);
  }
}

TEST(RayProfiles, SampleFollowsTheDensityByChiSquare) {
  const int n = 200'000;
  const int bins = 40;
  for (RayProfile profile : kRayProfiles) {
    Rng rng(17, static_cast<std::uint64_t>(profile), 0);
    std::vector<double> observed(bins, 0.0);
    for (int i = 0; i < n; ++i) {
      const double x = profile_sample(profile, rng.uniform());
      observed[std::min(bins - 1, static_cast<int>((x + 1.0) * 0.5 * bins))] += 1.0;
    }
    std::vector<double> expected(bins);
    for (int b = 0; b < bins; ++b) {
      const double lo = -1.0 + 2.0 * b / bins;
      const double hi = -1.0 + 2.0 * (b + 1) / bins;
      expected[b] = n * (profile_cdf(profile, hi) - profile_cdf(profile, lo));
      ASSERT_GT(expected[b], 50.0);  // no bin needs merging
    }
    EXPECT_LT(testing::chi_square(observed, expected), testing::chi_square_critical(bins - 1)) << to_string(profile);
  }
}

TEST(RayProfiles, QuadratureIsEqualWeightCentroidsOfEqualMassStrata) {
  std::vector<double> offsets;
  std::vector<double> weights;
  for (RayProfile profile : kRayProfiles) {
    const double m2 = second_moment(profile);
    double previous_error = 0.0;
    for (int count : {3, 5, 1, 2, 4, 8, 16, 32, 64}) {
      profile_quadrature(profile, count, offsets, weights);
      ASSERT_EQ(offsets.size(), static_cast<std::size_t>(count));
      ASSERT_EQ(weights.size(), static_cast<std::size_t>(count));
      double sum = 0.0;
      double first = 0.0;
      double second = 0.0;
      for (int i = 0; i < count; ++i) {
        EXPECT_NEAR(weights[i], 1.0 / count, 1e-16);
        EXPECT_GE(offsets[i], -1.0);
        EXPECT_LE(offsets[i], 1.0);
        if (i > 0) {
          EXPECT_GT(offsets[i], offsets[i - 1]);
        }
        EXPECT_EQ(offsets[i], -offsets[count - 1 - i]);  // symmetric
        // Node i lies in its stratum [F^-1(i/K), F^-1((i+1)/K)] (stratum boundaries by cdf).
        EXPECT_GE(profile_cdf(profile, offsets[i]), static_cast<double>(i) / count - 1e-15);
        EXPECT_LE(profile_cdf(profile, offsets[i]), static_cast<double>(i + 1) / count + 1e-15);
        sum += weights[i];
        first += weights[i] * offsets[i];
        second += weights[i] * offsets[i] * offsets[i];
      }
      EXPECT_EQ(sum, 1.0);
      EXPECT_NEAR(first, 0.0, 1e-15);
      // The rule misses the mean within-stratum variance, so 0 <= m2 - Q[x^2], and by less than
      // 1/K^2 for K <= 64 (measured K^2 x error at K = 64: box 1/3 exactly, Epanechnikov 0.44,
      // cosine 0.46, tent 0.51, Gauss 0.97; the wide tail strata of the last two grow it slowly).
      // Each doubling of K divides it by at least 2.5 (4 in the limit).
      const double error = m2 - second;
      EXPECT_GE(error, -1e-15) << to_string(profile) << " K " << count;
      EXPECT_LE(error, 1.0 / (count * count)) << to_string(profile) << " K " << count;
      if (profile == RayProfile::Box) {
        EXPECT_NEAR(error, 1.0 / (3.0 * count * count), 1e-15);
      }
      if (count >= 2 && (count & (count - 1)) == 0) {  // previous: K / 2
        EXPECT_GE(previous_error / error, 2.5) << to_string(profile) << " K " << count;
      }
      previous_error = error;
    }
    // K = 1: the centre ray alone.
    profile_quadrature(profile, 1, offsets, weights);
    EXPECT_EQ(offsets[0], 0.0);
    EXPECT_EQ(weights[0], 1.0);
  }
  // Box: midpoints of K equal strata, -1 + (2i + 1)/K.
  profile_quadrature(RayProfile::Box, 5, offsets, weights);
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(offsets[i], -1.0 + (2.0 * i + 1.0) / 5.0, 1e-15);
}

}  // namespace
}  // namespace flatland
