#include "flatland/base/random.hpp"

#include <cmath>
#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "test_support.hpp"

namespace flatland {
namespace {

TEST(Random, RngStreamsReproduceAndDiffer) {
  Rng a(42, 3, 7);
  Rng b(42, 3, 7);
  Rng c(42, 3, 8);
  Rng d(42, 4, 7);
  int same_c = 0;
  int same_d = 0;
  for (int i = 0; i < 1000; ++i) {
    const std::uint64_t x = a.next();
    ASSERT_EQ(x, b.next());
    same_c += x == c.next();
    same_d += x == d.next();
  }
  EXPECT_EQ(same_c, 0);
  EXPECT_EQ(same_d, 0);
}

TEST(Random, UniformHasMeanAndVarianceOfU01) {
  Rng rng(1, 0, 0);
  const int n = 1'000'000;
  double sum = 0.0;
  double sum2 = 0.0;
  for (int i = 0; i < n; ++i) {
    const double u = rng.uniform_open();
    ASSERT_GT(u, 0.0);
    ASSERT_LT(u, 1.0);
    sum += u;
    sum2 += u * u;
  }
  // Standard errors: mean sqrt(1/12 / n), second moment sqrt(4/45 / n); allow 5 of them.
  EXPECT_NEAR(sum / n, 0.5, 5 * std::sqrt(1.0 / 12 / n));
  EXPECT_NEAR(sum2 / n, 1.0 / 3, 5 * std::sqrt(4.0 / 45 / n));
}

TEST(Random, IndexedUniformsAreSplitMixsOutputsAndUniform) {
  // Number i is SplitMix64's output i + 1 from the state `key`, stepped one output at a time here;
  // and 100,000 of them fill 20 bins evenly (chi-square).
  const std::uint64_t key = 0x1234abcdull;
  std::uint64_t state = key;
  const int n = 100'000;
  const int bins = 20;
  std::vector<double> observed(bins, 0.0);
  for (int i = 0; i < n; ++i) {
    const double stepped = static_cast<double>(flatland::splitmix64(state) >> 11) * 0x1.0p-53;
    const double u = flatland::indexed_uniform(key, static_cast<std::uint64_t>(i));
    ASSERT_EQ(u, stepped) << i;
    ASSERT_GE(u, 0.0);
    ASSERT_LT(u, 1.0);
    observed[static_cast<std::size_t>(u * bins)] += 1;
  }
  const std::vector<double> expected(bins, static_cast<double>(n) / bins);
  EXPECT_LT(testing::chi_square(observed, expected), testing::chi_square_critical(bins - 1));
}

}  // namespace
}  // namespace flatland
