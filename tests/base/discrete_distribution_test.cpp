#include "flatland/base/discrete_distribution.hpp"

#include <cmath>
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/base/random.hpp"
#include "test_support.hpp"

namespace flatland {
namespace {

TEST(DiscreteDistribution, FollowsWeightsAndSkipsZeros) {
  const std::vector<double> weights = {0.0, 3.0, 0.0, 1.0, 6.0, 0.0};
  const DiscreteDistribution distribution(weights);
  EXPECT_DOUBLE_EQ(distribution.total(), 10.0);
  EXPECT_DOUBLE_EQ(distribution.pmf(4), 0.6);
  // No u, the extremes included, gives an index of zero weight.
  for (double u : {0.0, 1e-300, 0.5, std::nextafter(1.0, 0.0)}) EXPECT_GT(weights[distribution.sample(u)], 0.0) << u;
  for (int i = 0; i < 6000; ++i) EXPECT_GT(weights[distribution.sample(i / 6000.0)], 0.0);
  Rng rng(3, 0, 0);
  const int n = 200'000;
  std::vector<double> counts(weights.size(), 0.0);
  for (int i = 0; i < n; ++i) counts[distribution.sample(rng.uniform())] += 1;
  EXPECT_EQ(counts[0] + counts[2] + counts[5], 0.0);
  const std::vector<double> observed = {counts[1], counts[3], counts[4]};
  const std::vector<double> expected = {0.3 * n, 0.1 * n, 0.6 * n};
  EXPECT_LT(testing::chi_square(observed, expected), testing::chi_square_critical(2));
}

TEST(DiscreteDistribution, IgnoresRoundingOfTiedWeights) {
  // Weights whose scaled values (w n / total) are integers: 5 and 3 over 8 columns with six
  // zeros. Topping up the zeros from the 3 leaves it at exactly 1 after two of them; on the other
  // side of 1 by rounding (the same weights times a factor, as in a scaled copy of a scene) it
  // used to turn small and take the next zero, and every pairing after it changed. The table must
  // not depend on which side rounding falls: every u maps to the same index.
  const std::vector<double> exact = {5.0, 3.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  for (double nudge : {1.0 + 4e-16, 1.0 - 4e-16, 1.0 + 1e-14, 1.0 - 1e-14}) {
    std::vector<double> moved = exact;
    moved[1] *= nudge;
    const DiscreteDistribution a(exact);
    const DiscreteDistribution b(moved);
    int differing = 0;
    for (int i = 0; i < 8000; ++i) differing += a.sample((i + 0.5) / 8000.0) != b.sample((i + 0.5) / 8000.0);
    EXPECT_EQ(differing, 0) << "weight 1 times " << nudge;
    EXPECT_NEAR(b.pmf(1), 3.0 / 8.0, 1e-9);
  }
}

TEST(DiscreteDistribution, RestIsUniformGivenTheIndex) {
  // sample(u, rest) chooses as sample(u) does, and what is left of u is uniform in [0,1) and
  // independent of the index: a chi-square test over (index, quarter of rest) cells.
  const std::vector<double> weights = {0.0, 3.0, 0.0, 1.0, 6.0, 0.0};
  const DiscreteDistribution distribution(weights);
  Rng rng(5, 0, 0);
  const int n = 200'000;
  std::vector<double> counts(weights.size() * 4, 0.0);
  for (int i = 0; i < n; ++i) {
    const double u = rng.uniform();
    double rest = -1.0;
    const std::size_t index = distribution.sample(u, rest);
    ASSERT_EQ(index, distribution.sample(u));
    ASSERT_GE(rest, 0.0);
    ASSERT_LT(rest, 1.0);
    counts[index * 4 + static_cast<std::size_t>(rest * 4.0)] += 1;
  }
  std::vector<double> observed;
  std::vector<double> expected;
  for (std::size_t index : {1u, 3u, 4u})
    for (std::size_t quarter = 0; quarter < 4; ++quarter) {
      observed.push_back(counts[index * 4 + quarter]);
      expected.push_back(distribution.pmf(index) * n / 4.0);
    }
  EXPECT_LT(testing::chi_square(observed, expected), testing::chi_square_critical(11));
  // A stratified u stays stratified: 4096 midpoints give every index's rests evenly spaced, so
  // each quarter of rest holds a quarter of the index's points (to one point per piece of u).
  std::vector<double> stratified(weights.size() * 4, 0.0);
  for (int i = 0; i < 4096; ++i) {
    double rest = 0.0;
    const std::size_t index = distribution.sample((i + 0.5) / 4096.0, rest);
    stratified[index * 4 + static_cast<std::size_t>(rest * 4.0)] += 1;
  }
  for (std::size_t index : {1u, 3u, 4u})
    for (std::size_t quarter = 0; quarter < 4; ++quarter)
      EXPECT_NEAR(stratified[index * 4 + quarter], distribution.pmf(index) * 4096 / 4.0, 12.0)
          << index << " " << quarter;
}

}  // namespace
}  // namespace flatland
