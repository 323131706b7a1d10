// Compensated summation (base/summation.hpp): totals exact to about one rounding whatever the
// terms' number, order and magnitudes, where a plain sum loses them.
#include "flatland/base/summation.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

namespace flatland {
namespace {

TEST(Summation, KeepsWhatAPlainSumLoses) {
  // 1 between two terms of 1e16: a plain sum gives 0, the exact total is 1.
  CompensatedSum sum;
  double plain = 0.0;
  for (double term : {1e16, 1.0, -1e16}) {
    sum.add(term);
    plain += term;
  }
  EXPECT_EQ(plain, 0.0);
  EXPECT_EQ(sum.value(), 1.0);
}

// A million terms 0.1 each: the plain sum drifts by about 1e-6 relative, the compensated one stays
// within one rounding of the exact 100000 (0.1 is not a binary fraction, so the exact total of the
// doubles is 1e6 times the double nearest 0.1).
TEST(Summation, ManyTermsStayWithinOneRounding) {
  CompensatedSum sum;
  double plain = 0.0;
  for (int i = 0; i < 1'000'000; ++i) {
    sum.add(0.1);
    plain += 0.1;
  }
  const long double exact = 1e6L * static_cast<long double>(0.1);
  EXPECT_LE(std::fabs(static_cast<long double>(sum.value()) - exact), 1e-11L);
  EXPECT_GT(std::fabs(static_cast<long double>(plain) - exact), 1e-7L);
}

// Terms of every magnitude in random order sum to the same value as in sorted order.
TEST(Summation, OrderDoesNotMatter) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> exponent(-20.0, 20.0);
  std::uniform_real_distribution<double> sign(-1.0, 1.0);
  std::vector<double> terms;
  for (int i = 0; i < 10'000; ++i) terms.push_back(std::copysign(std::pow(10.0, exponent(rng)), sign(rng)));
  CompensatedSum forward;
  for (double t : terms) forward.add(t);
  std::shuffle(terms.begin(), terms.end(), rng);
  CompensatedSum shuffled;
  for (double t : terms) shuffled.add(t);
  EXPECT_NEAR(forward.value(), shuffled.value(), 4e-16 * std::fabs(forward.value()) + 1e-300);
}

}  // namespace
}  // namespace flatland
