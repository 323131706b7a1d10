#include "flatland/transport/qmc.hpp"

#include <cmath>
#include <cstdio>
#include <set>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/transport/sampling.hpp"
#include "test_support.hpp"

namespace flatland {
namespace {

// Whether points first .. first + 2^m - 1 of dimensions (0, 1) put exactly one point in every
// elementary interval [a 2^-k, (a+1) 2^-k) x [b 2^-(m-k), (b+1) 2^-(m-k)), for every k = 0..m:
// the (0,m,2)-net property, counted by brute force over the cells.
template <typename Coordinate>
bool is_02_net(int m, std::uint32_t first, Coordinate coordinate) {
  const std::uint32_t n = std::uint32_t{1} << m;
  for (int k = 0; k <= m; ++k) {
    std::vector<int> cells(n, 0);
    for (std::uint32_t i = first; i < first + n; ++i) {
      // The leading k digits of x and m - k digits of y (64-bit shifts: a shift by 32 is fine).
      const auto column = static_cast<std::uint32_t>(std::uint64_t{coordinate(i, 0)} >> (32 - k));
      const auto row = static_cast<std::uint32_t>(std::uint64_t{coordinate(i, 1)} >> (32 - (m - k)));
      ++cells[(column << (m - k)) | row];
    }
    for (int count : cells)
      if (count != 1) return false;
  }
  return true;
}

// Whether each of the first 2^m points' coordinate in `dimension` lies in its own interval
// [j 2^-m, (j+1) 2^-m): the (0,m,1)-net property of a one-dimensional projection.
template <typename Coordinate>
bool is_stratified(int m, int dimension, Coordinate coordinate) {
  const std::uint32_t n = std::uint32_t{1} << m;
  std::vector<int> cells(n, 0);
  for (std::uint32_t i = 0; i < n; ++i)
    ++cells[static_cast<std::size_t>(std::uint64_t{coordinate(i, dimension)} >> (32 - m))];
  for (int count : cells)
    if (count != 1) return false;
  return true;
}

TEST(Qmc, ReverseBitsMirrors) {
  EXPECT_EQ(reverse_bits(1u), 0x80000000u);
  EXPECT_EQ(reverse_bits(0x80000000u), 1u);
  EXPECT_EQ(reverse_bits(0x00000006u), 0x60000000u);
  EXPECT_EQ(reverse_bits(reverse_bits(0x12345678u)), 0x12345678u);
}

TEST(Qmc, SobolStartsAsTheKnownSequence) {
  // Dimension 0: van der Corput 0, 1/2, 1/4, 3/4, ...; dimension 1: 0, 1/2, 3/4, 1/4, 5/8, 1/8
  // (the second Sobol' coordinate, generator matrix Pascal's triangle mod 2, in index order, not
  // Gray-code order).
  const double dim0[] = {0.0, 0.5, 0.25, 0.75, 0.125, 0.625};
  const double dim1[] = {0.0, 0.5, 0.75, 0.25, 0.625, 0.125};
  for (std::uint32_t i = 0; i < 6; ++i) {
    EXPECT_EQ(sobol_bits(i, 0) * 0x1.0p-32, dim0[i]) << i;
    EXPECT_EQ(sobol_bits(i, 1) * 0x1.0p-32, dim1[i]) << i;
  }
}

TEST(Qmc, UnscrambledDimensionsZeroAndOneFormA02Sequence) {
  auto coordinate = [](std::uint32_t i, int d) { return sobol_bits(i, d); };
  for (int m = 0; m <= 12; ++m) EXPECT_TRUE(is_02_net(m, 0, coordinate)) << "m = " << m;
  // Every block of 2^m points that starts at a multiple of 2^m is a net too.
  for (std::uint32_t block : {1u, 5u, 77u}) EXPECT_TRUE(is_02_net(8, block << 8, coordinate)) << block;
}

TEST(Qmc, ScrambledDimensionsZeroAndOneFormA02Sequence) {
  for (std::uint64_t seed : {1u, 2u, 12345u}) {
    const ScrambledSobol sobol(seed, 3);
    auto coordinate = [&](std::uint32_t i, int d) { return sobol.scrambled_bits(i, d); };
    for (int m = 0; m <= 12; ++m) EXPECT_TRUE(is_02_net(m, 0, coordinate)) << seed << " m = " << m;
    EXPECT_TRUE(is_02_net(10, 7u << 10, coordinate)) << seed;
  }
}

TEST(Qmc, EveryDimensionIsStratifiedScrambledOrNot) {
  const ScrambledSobol sobol(9, 0);
  for (int d = 0; d < kSobolDimensions; ++d)
    for (int m = 0; m <= 14; ++m) {
      EXPECT_TRUE(is_stratified(m, d, [](std::uint32_t i, int dim) { return sobol_bits(i, dim); }))
          << "dimension " << d << ", m = " << m;
      EXPECT_TRUE(is_stratified(m, d, [&](std::uint32_t i, int dim) { return sobol.scrambled_bits(i, dim); }))
          << "scrambled, dimension " << d << ", m = " << m;
    }
}

TEST(Qmc, ScrambleIsABijectionThatKeepsLeadingDigitsTogether) {
  // Nested: two fractions that share their leading k digits still share k leading digits after
  // the scramble (the digits below depend only on those above), and distinct stay distinct.
  Rng rng(1, 2, 3);
  for (int trial = 0; trial < 20'000; ++trial) {
    const auto seed = static_cast<std::uint32_t>(rng.next());
    const auto x = static_cast<std::uint32_t>(rng.next());
    const int k = static_cast<int>(rng.next() % 32);
    const std::uint32_t low = static_cast<std::uint32_t>(rng.next()) >> k;
    const std::uint32_t y = k == 0 ? low : ((x >> (32 - k)) << (32 - k)) | low;
    const std::uint32_t sx = nested_uniform_scramble(x, seed);
    const std::uint32_t sy = nested_uniform_scramble(y, seed);
    if (k > 0) {
      ASSERT_EQ(sx >> (32 - k), sy >> (32 - k)) << trial;
    }
    if (x != y) {
      ASSERT_NE(sx, sy) << trial;
    }
  }
}

TEST(Qmc, PointsAreDeterministicInOpenUnitIntervalAndDifferBySeed) {
  const ScrambledSobol a(7, 11);
  const ScrambledSobol same(7, 11);
  const ScrambledSobol other_seed(8, 11);
  const ScrambledSobol other_stream(7, 12);
  int differ_seed = 0;
  int differ_stream = 0;
  for (std::uint32_t i = 0; i < 4096; ++i)
    for (int d = 0; d < kSobolDimensions; ++d) {
      const double x = a.sample(i, d);
      ASSERT_GT(x, 0.0);
      ASSERT_LT(x, 1.0);
      ASSERT_EQ(x, same.sample(i, d));
      differ_seed += x != other_seed.sample(i, d);
      differ_stream += x != other_stream.sample(i, d);
    }
  EXPECT_GT(differ_seed, 4096 * kSobolDimensions * 99 / 100);
  EXPECT_GT(differ_stream, 4096 * kSobolDimensions * 99 / 100);
  // The dimensions of a point use different scrambles: point 0 (all digits zero unscrambled) is
  // not the same number in every dimension.
  std::set<double> first_point;
  for (int d = 0; d < kSobolDimensions; ++d) first_point.insert(a.sample(0, d));
  EXPECT_EQ(first_point.size(), static_cast<std::size_t>(kSobolDimensions));
}

TEST(Qmc, CursorWalksThePointsBitForBit) {
  // Consecutive indices by one XOR per dimension, jumps (back, ahead, to 0, across the top bit of
  // a 2^m block) by recomputation: every coordinate equal to ScrambledSobol::sample exactly.
  const ScrambledSobol sobol(11, 3);
  SobolCursor cursor(sobol);
  std::vector<std::uint32_t> indices;
  for (std::uint32_t i = 0; i < 5000; ++i) indices.push_back(i);
  for (std::uint32_t i : {70000u, 70001u, 65535u, 65536u, 65537u, 3u, 0u, 1u, 0x7fffffffu, 0x80000000u, 0xfffffffeu,
                          0xffffffffu, 0u, 12u, 12u, 13u})
    indices.push_back(i);
  for (std::uint32_t index : indices) {
    cursor.seek(index);
    for (int d = 0; d < kSobolDimensions; ++d)
      ASSERT_EQ(cursor.sample(d), sobol.sample(index, d)) << "index " << index << " dimension " << d;
  }
}

TEST(Qmc, EachScrambledPointIsUniformOverSeeds) {
  // Over independent scrambles, a fixed point is uniform in [0,1): chi-square over 32 bins, for
  // a few points and dimensions (one point is all an unbiased estimator needs).
  for (std::uint32_t index : {0u, 1u, 6u, 1000u})
    for (int d = 0; d < kSobolDimensions; ++d) {
      const int n = 32'000;
      std::vector<double> observed(32, 0.0);
      for (int seed = 0; seed < n; ++seed)
        observed[static_cast<std::size_t>(ScrambledSobol(static_cast<std::uint64_t>(seed), 0).sample(index, d) * 32)] +=
            1;
      const std::vector<double> expected(32, n / 32.0);
      EXPECT_LT(testing::chi_square(observed, expected), testing::chi_square_critical(31))
          << "point " << index << ", dimension " << d;
    }
}

// Variance over seeds of the scrambled-net estimate of the area of a quarter disc (an integrand
// with a jump along a curve) with n points.
double quarter_disc_variance(std::uint32_t n, int seeds) {
  const double exact = std::acos(-1.0) / 4.0;
  double sum = 0.0;
  for (int seed = 0; seed < seeds; ++seed) {
    const ScrambledSobol sobol(static_cast<std::uint64_t>(seed) + 1000, 0);
    int inside = 0;
    for (std::uint32_t i = 0; i < n; ++i) {
      const double x = sobol.sample(i, 0);
      const double y = sobol.sample(i, 1);
      inside += x * x + y * y < 1.0;
    }
    const double error = inside / static_cast<double>(n) - exact;
    sum += error * error;
  }
  return sum / seeds;
}

TEST(Qmc, VarianceFallsFasterThanMonteCarloAcrossAJump) {
  // Owen: for an indicator of a smooth region in 2D the scrambled net's variance falls as
  // n^-3/2 (Monte Carlo: n^-1). From 256 to 16384 points (64 times as many) the variance must
  // fall at least 64^1.25 = 181 times, against 64 for Monte Carlo; the expected fall is
  // 64^1.5 = 512. With 200 seeds each variance is known to about 10% (chi-square, 200 degrees).
  const double coarse = quarter_disc_variance(256, 200);
  const double fine = quarter_disc_variance(16384, 200);
  std::printf("quarter disc: variance %.3g at 256 points, %.3g at 16384, ratio %.0f\n", coarse, fine, coarse / fine);
  EXPECT_GT(coarse / fine, 181.0);
  // And at 256 points it already beats Monte Carlo's (pi/4)(1 - pi/4) / n.
  const double p = std::acos(-1.0) / 4.0;
  EXPECT_LT(coarse, 0.5 * p * (1 - p) / 256);
}

}  // namespace
}  // namespace flatland
