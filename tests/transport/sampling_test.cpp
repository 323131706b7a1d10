#include "flatland/transport/sampling.hpp"

#include <array>
#include <cmath>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "test_support.hpp"

namespace flatland {
namespace {

TEST(Sampling, DiffuseDirectionsFollowCosineOverTwo) {
  // Chi-square of the angle from the normal against the CDF (1 + sin theta) / 2, for a normal
  // that is not axis-aligned.
  const Vec2 normal = normalized(Vec2{0.3, -0.8});
  const Vec2 tangent{normal.y, -normal.x};
  Rng rng(5, 0, 0);
  const int bins = 64;
  const int n = 400'000;
  std::vector<double> observed(bins, 0.0);
  std::vector<double> expected(bins, 0.0);
  int within_30_degrees = 0;
  for (int i = 0; i < n; ++i) {
    const Vec2 d = square_to_diffuse(rng.uniform(), normal);
    ASSERT_NEAR(length(d), 1.0, 1e-14);
    ASSERT_GE(dot(d, normal), 0.0);
    const double theta = std::atan2(dot(d, tangent), dot(d, normal));
    const int bin = std::min(bins - 1, static_cast<int>((theta / std::numbers::pi + 0.5) * bins));
    observed[bin] += 1;
    within_30_degrees += std::fabs(theta) <= std::numbers::pi / 6;
  }
  for (int b = 0; b < bins; ++b) {
    const double a = (static_cast<double>(b) / bins - 0.5) * std::numbers::pi;
    const double c = (static_cast<double>(b + 1) / bins - 0.5) * std::numbers::pi;
    expected[b] = n * 0.5 * (std::sin(c) - std::sin(a));
  }
  EXPECT_LT(testing::chi_square(observed, expected), testing::chi_square_critical(bins - 1));
  // Half the power leaves within +-30 degrees of the normal: (sin 30 - sin -30) / 2 = 1/2.
  const double sigma = std::sqrt(0.25 / n);
  EXPECT_NEAR(static_cast<double>(within_30_degrees) / n, 0.5, 5 * sigma);
}

TEST(Sampling, DiffusePdfIntegratesToOneAndInverts) {
  const Vec2 normal = normalized(Vec2{-1.0, 2.0});
  // Integral of the pdf over the circle by the midpoint rule.
  const int steps = 100000;
  double integral = 0.0;
  for (int i = 0; i < steps; ++i) {
    const double phi = 2 * std::numbers::pi * (i + 0.5) / steps;
    integral += square_to_diffuse_pdf(normal, {std::cos(phi), std::sin(phi)});
  }
  EXPECT_NEAR(integral * 2 * std::numbers::pi / steps, 1.0, 1e-8);
  for (double u : {0.001, 0.2, 0.5, 0.77, 0.999}) {
    EXPECT_NEAR(square_to_diffuse_invert(normal, square_to_diffuse(u, normal)), u, 1e-13);
  }
}

TEST(Sampling, FractionOfDirectionsHittingASegmentIsTheFormFactor) {
  // From the origin with normal +y, the segment from (a, h) to (b, h): the fraction of diffuse
  // directions through it is (sin theta_b - sin theta_a) / 2 with sin theta = x / sqrt(x^2 + h^2).
  const double a = -0.4;
  const double b = 1.7;
  const double h = 0.9;
  const double exact = 0.5 * (b / std::hypot(b, h) - a / std::hypot(a, h));
  Rng rng(9, 0, 0);
  const int n = 1'000'000;
  int hits = 0;
  for (int i = 0; i < n; ++i) {
    const Vec2 d = square_to_diffuse(rng.uniform(), {0.0, 1.0});
    if (d.y <= 0.0) continue;
    const double x = d.x / d.y * h;
    hits += x >= a && x <= b;
  }
  const double sigma = std::sqrt(exact * (1 - exact) / n);
  EXPECT_NEAR(static_cast<double>(hits) / n, exact, 5 * sigma);
}

// Chi-square of sampled angles from the normal against a density given per radian, integrated
// over each bin by the midpoint rule.
template <typename Sample, typename Density>
void check_angular(Sample sample, Density density, int n) {
  const Vec2 normal = normalized(Vec2{0.6, 0.8});
  const Vec2 tangent{normal.y, -normal.x};
  const int bins = 48;
  std::vector<double> observed(bins, 0.0);
  for (int i = 0; i < n; ++i) {
    const Vec2 d = sample(normal);
    ASSERT_NEAR(length(d), 1.0, 1e-14);
    const double theta = std::atan2(dot(d, tangent), dot(d, normal));
    observed[std::min(bins - 1, static_cast<int>((theta / std::numbers::pi + 0.5) * bins))] += 1;
  }
  std::vector<double> o;
  std::vector<double> e;
  double tail_observed = 0.0;  // bins expecting under 5 samples, pooled
  double tail_expected = 0.0;
  double total = 0.0;
  for (int b = 0; b < bins; ++b) {
    double mass = 0.0;
    const int steps = 2000;
    for (int j = 0; j < steps; ++j) {
      const double theta = ((b + (j + 0.5) / steps) / bins - 0.5) * std::numbers::pi;
      mass += density(normal, std::sin(theta) * tangent + std::cos(theta) * normal) * std::numbers::pi / bins / steps;
    }
    total += mass;
    if (mass * n < 5.0) {
      tail_observed += observed[b];
      tail_expected += mass * n;
      continue;
    }
    o.push_back(observed[b]);
    e.push_back(mass * n);
  }
  if (tail_expected >= 1.0) {
    o.push_back(tail_observed);
    e.push_back(tail_expected);
  } else {
    EXPECT_LE(tail_observed, 10.0);  // (almost) nothing where (almost) nothing is expected
  }
  // The pdf integrates to one; the midpoint rule misses at most (jump x step) at a beam's edges,
  // below 2 x 5.8 x 3.3e-5 for a 5 degree beam.
  EXPECT_NEAR(total, 1.0, 5e-4);
  EXPECT_LT(testing::chi_square(o, e), testing::chi_square_critical(static_cast<int>(o.size()) - 1));
}

TEST(Sampling, LobeFollowsCosinePower) {
  for (double n : {0.5, 1.0, 4.0, 30.0}) {
    Rng rng(17, static_cast<std::uint64_t>(n * 10), 0);
    check_angular([&](Vec2 normal) { return sample_lobe(rng, n, normal); },
                  [&](Vec2 normal, Vec2 d) { return sample_lobe_pdf(n, normal, d); }, 200'000);
  }
  // Exponent 1 is the diffuse distribution.
  const Vec2 normal{0.0, 1.0};
  const Vec2 d = normalized(Vec2{0.3, 0.7});
  EXPECT_NEAR(sample_lobe_pdf(1.0, normal, d), square_to_diffuse_pdf(normal, d), 1e-14);
}

TEST(Sampling, BeamStaysInsideItsCone) {
  for (double degrees : {5.0, 30.0, 90.0}) {
    const double a = degrees * std::numbers::pi / 180;
    Rng rng(23, static_cast<std::uint64_t>(degrees), 0);
    check_angular(
        [&](Vec2 normal) {
          const Vec2 d = square_to_beam(rng.uniform(), a, normal);
          EXPECT_GE(dot(d, normal), std::cos(a) - 1e-15);  // never outside the cone
          return d;
        },
        [&](Vec2 normal, Vec2 d) { return square_to_beam_pdf(a, normal, d); }, 200'000);
  }
}

}  // namespace
}  // namespace flatland
