#include "flatland/basis.hpp"

#include <array>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/sampling.hpp"
#include "test_support.hpp"

namespace flatland {
namespace {

using Values = std::array<double, SplineBasis::kMaxDegree + 1>;

// f(u) = sum_k c_k phi_k(u) for given coefficients.
double spline_value(const SplineBasis& basis, const std::vector<double>& c, double u) {
  Values phi{};
  const std::size_t first = basis.evaluate(u, phi.data());
  double sum = 0.0;
  for (int j = 0; j <= basis.degree(); ++j) sum += c[first + j] * phi[j];
  return sum;
}

TEST(Basis, MultiplicityEncodesContinuity) {
  EXPECT_EQ(SplineBasis::multiplicity(3, Continuity::C1), 2);
  EXPECT_EQ(SplineBasis::multiplicity(3, Continuity::C0), 3);
  EXPECT_EQ(SplineBasis::multiplicity(3, Continuity::Jump), 4);
  EXPECT_EQ(SplineBasis::multiplicity(1, Continuity::C1), 1);  // a linear spline is at most C0
  EXPECT_EQ(SplineBasis::multiplicity(1, Continuity::Jump), 2);
  EXPECT_EQ(SplineBasis::multiplicity(0, Continuity::C0), 1);  // a constant spline always jumps
}

TEST(Basis, SingleCubicElementIsBernstein) {
  const SplineBasis basis(3, 0.0, 1.0, {});
  ASSERT_EQ(basis.size(), 4u);
  for (double u : {0.0, 0.1, 0.37, 0.5, 0.9, 1.0}) {
    Values phi{};
    ASSERT_EQ(basis.evaluate(u, phi.data()), 0u);
    const double v = 1.0 - u;
    EXPECT_NEAR(phi[0], v * v * v, 1e-15);
    EXPECT_NEAR(phi[1], 3 * u * v * v, 1e-15);
    EXPECT_NEAR(phi[2], 3 * u * u * v, 1e-15);
    EXPECT_NEAR(phi[3], u * u * u, 1e-15);
  }
}

TEST(Basis, LinearBasisIsHatFunctions) {
  const std::vector<MeshNode> nodes = {{0.25, Continuity::C0}, {0.5, Continuity::C0}};
  const SplineBasis basis(1, 0.0, 1.0, nodes);
  ASSERT_EQ(basis.size(), 4u);
  // Hat k peaks at breakpoint k: at u = 0.375 halfway between nodes 1 and 2.
  Values phi{};
  const std::size_t first = basis.evaluate(0.375, phi.data());
  EXPECT_EQ(first, 1u);
  EXPECT_NEAR(phi[0], 0.5, 1e-15);
  EXPECT_NEAR(phi[1], 0.5, 1e-15);
}

TEST(Basis, PartitionOfUnityAndNonnegative) {
  std::mt19937_64 random(7);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const std::array<Continuity, 3> kinds = {Continuity::Jump, Continuity::C0, Continuity::C1};
  for (int degree : {0, 1, 3}) {
    for (int trial = 0; trial < 50; ++trial) {
      std::vector<MeshNode> nodes;
      double u = 0.0;
      for (int i = 0; i < 6; ++i) {
        u += 0.05 + uniform(random);
        nodes.push_back({u, kinds[random() % 3]});
      }
      const double end = u + 0.5;
      const SplineBasis basis(degree, 0.0, end, nodes);
      for (int i = 0; i < 200; ++i) {
        const double x = end * uniform(random);
        Values phi{};
        const std::size_t first = basis.evaluate(x, phi.data());
        ASSERT_LE(first + degree, basis.size() - 1);
        double sum = 0.0;
        for (int j = 0; j <= degree; ++j) {
          EXPECT_GE(phi[j], -1e-15);
          sum += phi[j];
        }
        EXPECT_NEAR(sum, 1.0, 1e-14);
      }
    }
  }
}

TEST(Basis, CountsOfCoefficients) {
  // n cubic elements with C1 interior nodes: 4 + 2 (n - 1) coefficients; C0: 4 + 3 (n - 1).
  std::vector<MeshNode> c1;
  std::vector<MeshNode> c0;
  for (int i = 1; i < 5; ++i) {
    c1.push_back({i * 1.0, Continuity::C1});
    c0.push_back({i * 1.0, Continuity::C0});
  }
  EXPECT_EQ(SplineBasis(3, 0, 5, c1).size(), 12u);
  EXPECT_EQ(SplineBasis(3, 0, 5, c0).size(), 16u);
  EXPECT_EQ(SplineBasis(0, 0, 5, c0).size(), 5u);
  EXPECT_EQ(SplineBasis(1, 0, 5, c0).size(), 6u);
}

// One-sided limits of value and slope at a node, for random coefficients.
struct Limits {
  double value_jump;
  double slope_jump;
};
Limits limits_at(const SplineBasis& basis, const std::vector<double>& c, double node) {
  const double h = 1e-6;
  const double left = spline_value(basis, c, node - h);
  const double right = spline_value(basis, c, node + h);
  const double left_slope = (left - spline_value(basis, c, node - 2 * h)) / h;
  const double right_slope = (spline_value(basis, c, node + 2 * h) - right) / h;
  return {std::fabs(right - left), std::fabs(right_slope - left_slope)};
}

TEST(Basis, SelectedContinuityHoldsAtNodes) {
  std::mt19937_64 random(11);
  std::uniform_real_distribution<double> coefficient(0.0, 1.0);
  const std::vector<MeshNode> nodes = {
      {1.0, Continuity::C1}, {2.0, Continuity::C0}, {3.0, Continuity::Jump}};
  const SplineBasis basis(3, 0.0, 4.0, nodes);
  std::vector<double> c(basis.size());
  for (double& v : c) v = coefficient(random);
  const Limits c1 = limits_at(basis, c, 1.0);
  const Limits c0 = limits_at(basis, c, 2.0);
  const Limits jump = limits_at(basis, c, 3.0);
  // Value jumps are O(h) when continuous, O(1) otherwise; slope jumps O(h) when C1.
  EXPECT_LT(c1.value_jump, 1e-5);
  EXPECT_LT(c1.slope_jump, 1e-4);
  EXPECT_LT(c0.value_jump, 1e-5);
  EXPECT_GT(c0.slope_jump, 1e-2);
  EXPECT_GT(jump.value_jump, 1e-3);
}

TEST(Basis, StorageIntegralsSumToCurveLength) {
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 1,
    "materials": {"wall": {"reflectivity": 0.5, "emittance": 1}},
    "curves": [
      {"id": "line", "material": "wall", "line": [[0,0],[3,0],[3,4]]},
      {"id": "arch", "material": "wall", "bezier": [[0,1],[0,3],[4,3],[4,1],[4,0],[6,0],[6,2]]}
    ]})");
  ASSERT_EQ(scene.curves.size(), 2u);
  for (const Curve& curve : scene.curves) {
    for (BasisKind kind : {BasisKind::Constant, BasisKind::Linear, BasisKind::Cubic}) {
      const CurveStorage storage = build_curve_storage(scene, curve, kind, 10);
      double sum = 0.0;
      for (double v : storage.basis_length) {
        EXPECT_GT(v, 0.0);
        sum += v;
      }
      EXPECT_NEAR(sum, curve.length, 1e-11 * curve.length) << curve.id << " " << to_string(kind);
    }
  }
  // Constant elements on a straight polyline of lengths 3 and 4 with 7 elements: each 1 long.
  const CurveStorage constant = build_curve_storage(scene, scene.curves[0], BasisKind::Constant, 7);
  ASSERT_EQ(constant.basis.size(), 7u);
  for (double v : constant.basis_length) EXPECT_NEAR(v, 1.0, 1e-13);
}

TEST(Basis, GalerkinReproducesFunctionsInTheSpace) {
  // On a straight line (u proportional to arc length) a cubic f(u) lies in the cubic spline space:
  // from exact deposits p_k = integral(f phi_k ds) the Galerkin estimate gives back f, while the
  // lumped estimate p_k / integral(phi_k ds) does not.
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 1,
    "materials": {"lamp": {"emittance": 1}},
    "curves": [{"id": "line", "material": "lamp", "line": [[0,0],[4,0]]}]})");
  const CurveStorage storage = build_curve_storage(scene, scene.curves[0], BasisKind::Cubic, 6);
  auto f = [](double u) { return 1.0 + 2.0 * u - 3.0 * u * u + 2.5 * u * u * u; };
  const std::size_t n = storage.basis.size();
  std::vector<double> deposits(n, 0.0);
  const int steps = 200'000;
  Values phi{};
  for (int i = 0; i < steps; ++i) {
    const double u = (i + 0.5) / steps;
    const std::size_t first = storage.basis.evaluate(u, phi.data());
    for (int j = 0; j <= 3; ++j) deposits[first + j] += f(u) * phi[j] * 4.0 / steps;  // ds = 4 du
  }
  std::vector<double> galerkin(n);
  galerkin_estimate(storage, deposits.data(), galerkin.data(), 1);
  std::vector<double> lumped(n);
  for (std::size_t k = 0; k < n; ++k) lumped[k] = deposits[k] / storage.basis_length[k];
  double worst_galerkin = 0.0;
  double worst_lumped = 0.0;
  for (double u : {0.05, 0.2, 0.37, 0.5, 0.81, 0.97}) {
    worst_galerkin = std::max(worst_galerkin, std::fabs(spline_value(storage.basis, galerkin, u) - f(u)));
    worst_lumped = std::max(worst_lumped, std::fabs(spline_value(storage.basis, lumped, u) - f(u)));
  }
  EXPECT_LT(worst_galerkin, 1e-8);
  EXPECT_GT(worst_lumped, 1e-3);
}

TEST(Basis, GalerkinClampsAndConservesPower) {
  // Deposits concentrated on one basis function make the L2 projection oscillate negative; the
  // clamped estimate is nonnegative and holds exactly the deposited power.
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 1,
    "materials": {"lamp": {"emittance": 1}},
    "curves": [{"id": "line", "material": "lamp", "line": [[0,0],[4,0]]}]})");
  const CurveStorage storage = build_curve_storage(scene, scene.curves[0], BasisKind::Cubic, 8);
  std::vector<double> deposits(storage.basis.size(), 0.0);
  deposits[5] = 2.0;
  std::vector<double> b(storage.basis.size());
  galerkin_estimate(storage, deposits.data(), b.data(), 1);
  double power = 0.0;
  for (std::size_t k = 0; k < b.size(); ++k) {
    EXPECT_GE(b[k], 0.0);
    power += b[k] * storage.basis_length[k];
  }
  EXPECT_NEAR(power, 2.0, 1e-13);
}

TEST(Basis, SamplerMassIsTheClosedFormIntegral) {
  // integral(phi_k du) = (knot[k + p + 1] - knot[k]) / (p + 1) for a normalised B-spline.
  const std::vector<MeshNode> nodes = {
      {0.7, Continuity::C1}, {1.0, Continuity::Jump}, {1.9, Continuity::C0}, {2.2, Continuity::C1}};
  for (int degree : {0, 1, 3}) {
    const SplineBasis basis(degree, 0.0, 3.0, nodes);
    const BasisSampler sampler(basis);
    for (std::size_t k = 0; k < basis.size(); ++k) {
      const double exact = (basis.knots()[k + degree + 1] - basis.knots()[k]) / (degree + 1);
      EXPECT_NEAR(sampler.mass(k), exact, 1e-13) << "degree " << degree << " k " << k;
    }
  }
}

TEST(Basis, SamplerFollowsTheBasisFunction) {
  // Chi-square of samples of every basis function against the integral of phi_k over each bin,
  // computed by the midpoint rule from SplineBasis::evaluate (not from the sampler).
  const std::vector<MeshNode> nodes = {
      {0.5, Continuity::C1}, {1.0, Continuity::Jump}, {1.6, Continuity::C0}, {2.5, Continuity::C1}};
  const SplineBasis basis(3, 0.0, 3.0, nodes);
  const BasisSampler sampler(basis);
  flatland::Rng rng(21, 0, 0);
  const int n = 100'000;
  const int bins = 24;
  for (std::size_t k = 0; k < basis.size(); ++k) {
    const double a = basis.knots()[k];
    const double b = basis.knots()[k + 4];
    std::vector<double> observed(bins, 0.0);
    for (int i = 0; i < n; ++i) {
      const double u = sampler.sample(k, rng.uniform(), rng.uniform());
      ASSERT_GE(u, a);
      ASSERT_LE(u, b);
      observed[std::min(bins - 1, static_cast<int>((u - a) / (b - a) * bins))] += 1;
    }
    std::vector<double> expected(bins, 0.0);
    const int steps = 2000;
    double total = 0.0;
    for (int bin = 0; bin < bins; ++bin) {
      for (int j = 0; j < steps; ++j) {
        const double u = a + (b - a) * (bin + (j + 0.5) / steps) / bins;
        Values phi{};
        const std::size_t first = basis.evaluate(u, phi.data());
        if (k >= first && k <= first + 3) expected[bin] += phi[k - first];
      }
      total += expected[bin];
    }
    // Merge bins with small expectations (support ends of a cubic B-spline) into neighbours.
    std::vector<double> o;
    std::vector<double> e;
    double pending_o = 0.0;
    double pending_e = 0.0;
    for (int bin = 0; bin < bins; ++bin) {
      pending_o += observed[bin];
      pending_e += expected[bin] / total * n;
      if (pending_e >= 20.0) {
        o.push_back(pending_o);
        e.push_back(pending_e);
        pending_o = pending_e = 0.0;
      }
    }
    if (pending_e > 0.0 && !e.empty()) {
      o.back() += pending_o;
      e.back() += pending_e;
    }
    EXPECT_LT(testing::chi_square(o, e), testing::chi_square_critical(static_cast<int>(o.size()) - 1))
        << "basis function " << k;
  }
}

}  // namespace
}  // namespace flatland
