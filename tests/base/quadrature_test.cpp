// Gauss-Legendre rules (base/quadrature.hpp): exact for polynomials of degree 2n - 1, checked
// against the integrals of monomials in closed form.
#include "flatland/base/quadrature.hpp"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

namespace flatland {
namespace {

// integral of x^k over [-1, 1]: 2 / (k + 1) for even k, 0 for odd.
double monomial_on_symmetric(int k) { return k % 2 == 0 ? 2.0 / (k + 1) : 0.0; }

template <std::size_t N>
double rule_on_symmetric(const std::array<double, N>& nodes, const std::array<double, N>& weights, int k) {
  double sum = 0.0;
  for (std::size_t i = 0; i < N; ++i) sum += weights[i] * std::pow(nodes[i], k);
  return sum;
}

TEST(Quadrature, FixedRulesIntegrateTheirDegreesExactly) {
  for (int k = 0; k <= 15; ++k) {
    if (k <= 5) {
      EXPECT_NEAR(rule_on_symmetric(gauss::kNodes3, gauss::kWeights3, k), monomial_on_symmetric(k), 1e-15) << k;
    }
    if (k <= 7) {
      EXPECT_NEAR(rule_on_symmetric(gauss::kNodes4, gauss::kWeights4, k), monomial_on_symmetric(k), 1e-15) << k;
    }
    EXPECT_NEAR(rule_on_symmetric(gauss::kNodes8, gauss::kWeights8, k), monomial_on_symmetric(k), 1e-15) << k;
  }
  // One degree more is not exact (the rules are not over-fitted).
  EXPECT_GT(std::fabs(rule_on_symmetric(gauss::kNodes4, gauss::kWeights4, 8) - monomial_on_symmetric(8)), 1e-4);
}

// The generated rules on [0, 1]: integral of x^k = 1 / (k + 1) for every k <= 2n - 1, nodes
// increasing inside (0, 1), and the 8-point rule the fixed table's, moved to [0, 1].
TEST(Quadrature, GeneratedRulesAreExactAndAgreeWithTheTable) {
  for (int n : {1, 2, 3, 5, 8, 13, 32, 64}) {
    std::vector<double> nodes, weights;
    gauss::legendre_unit_rule(n, nodes, weights);
    ASSERT_EQ(nodes.size(), static_cast<std::size_t>(n));
    for (int i = 0; i < n; ++i) {
      EXPECT_GT(nodes[i], 0.0);
      EXPECT_LT(nodes[i], 1.0);
      if (i > 0) {
        EXPECT_GT(nodes[i], nodes[i - 1]);
      }
    }
    for (int k = 0; k <= std::min(2 * n - 1, 40); ++k) {
      double sum = 0.0;
      for (int i = 0; i < n; ++i) sum += weights[i] * std::pow(nodes[i], k);
      EXPECT_NEAR(sum, 1.0 / (k + 1), 4e-15) << "n " << n << " k " << k;
    }
  }
  // The same rule to a few tens of ulps: the recurrence for P_n and the squared slope in each
  // weight round that much.
  std::vector<double> nodes, weights;
  gauss::legendre_unit_rule(8, nodes, weights);
  for (std::size_t i = 0; i < 8; ++i) {
    EXPECT_NEAR(nodes[i], 0.5 * (1.0 + gauss::kNodes8[i]), 64 * 1.1e-16 * nodes[i]);
    EXPECT_NEAR(weights[i], 0.5 * gauss::kWeights8[i], 64 * 1.1e-16 * weights[i]);
  }
}

}  // namespace
}  // namespace flatland
