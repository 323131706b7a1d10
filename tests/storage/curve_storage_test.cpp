#include "flatland/storage/curve_storage.hpp"
#include "flatland/storage/estimators.hpp"
#include "flatland/storage/restriction.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <numeric>
#include <random>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/base/quadrature.hpp"
#include "flatland/base/random.hpp"
#include "flatland/transport/solver.hpp"
#include "test_support.hpp"

namespace flatland {
namespace {

using Values = std::array<double, SplineBasis::kMaxDegree + 1>;

// f(u) = sum_k c_k phi_k(u) for given coefficients.
double spline_value(const SplineBasis& basis, const std::vector<double>& c, double u) {
  Values phi{};
  const std::size_t first = basis.evaluate(u, phi.data());
  double sum = 0.0;
  for (int j = 0; j <= basis.degree(); ++j) sum += c[basis.index(first + j)] * phi[j];
  return sum;
}

// A closed ring of radius 1: eight cubic arcs of 45 degrees (handles (4/3) tan(pi/16)), counter-
// clockwise from (1, 0), with the given format version (1: the closing point is a seam).
Scene ring_scene(int version) {
  const double pi = std::numbers::pi;
  const double handle = 4.0 / 3.0 * std::tan(pi / 16.0);
  std::string points;
  for (int i = 0; i < 8; ++i) {
    const double a = i * pi / 4.0;
    const double b = (i + 1) * pi / 4.0;
    auto add = [&](double x, double y) {
      char text[96];
      std::snprintf(text, sizeof text, "[%.17g,%.17g],", x, y);
      points += text;
    };
    if (i == 0) add(1.0, 0.0);
    add(std::cos(a) - handle * std::sin(a), std::sin(a) + handle * std::cos(a));
    add(std::cos(b) + handle * std::sin(b), std::sin(b) - handle * std::cos(b));
    if (i == 7)
      points += "[1,0]";
    else
      add(std::cos(b), std::sin(b));
  }
  return testing::scene_from_text("{\"flatland\": " + std::to_string(version) + R"(,
    "materials": {"wall": {"reflectivity": 0.5, "emittance": 1}},
    "curves": [{"id": "ring", "material": "wall", "bezier": [)" +
                                  points + "]}]}");
}

// A smooth R on ring_scene's ring at curve parameter u: 2 + cos(angle) + sin(2 angle) / 2.
double smooth_on_ring(const Scene& ring, double u) {
  const auto j = static_cast<std::uint32_t>(std::min(std::floor(u), 7.0));
  const Vec2 p = evaluate(ring.segments[j].geometry.shape, u - j);
  const double angle = std::atan2(p.y, p.x);
  return 2.0 + std::cos(angle) + 0.5 * std::sin(2.0 * angle);
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

TEST(Basis, PeriodicBasisWrapsRoundTheClosingPoint) {
  // A periodic spline is a partition of unity everywhere, takes the same value at u and u + period,
  // and keeps the closing point's continuity: with C1 there, value and slope agree across it.
  std::mt19937_64 random(11);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const std::vector<MeshNode> nodes = {{0.4, Continuity::C1},
                                       {0.9, Continuity::C0},
                                       {1.5, Continuity::C1},
                                       {2.1, Continuity::C1},
                                       {2.6, Continuity::Jump}};
  for (int degree : {1, 3}) {
    for (Continuity closing : {Continuity::C1, Continuity::C0}) {
      const SplineBasis basis = SplineBasis::periodic(degree, 0.0, 3.0, nodes, closing);
      ASSERT_TRUE(basis.is_periodic());
      int knots = SplineBasis::multiplicity(degree, closing);
      for (const MeshNode& node : nodes) knots += SplineBasis::multiplicity(degree, node.continuity);
      ASSERT_EQ(basis.size(), static_cast<std::size_t>(knots));  // one function per knot
      EXPECT_EQ(basis.u_begin(), 0.0);
      EXPECT_EQ(basis.u_end(), 3.0);
      std::vector<double> c(basis.size());
      for (double& v : c) v = uniform(random);
      for (int i = 0; i < 300; ++i) {
        const double u = 3.0 * (i + 0.37) / 300.0;  // off the nodes (one is a jump)
        Values phi{};
        const std::size_t first = basis.evaluate(u, phi.data());
        ASSERT_LT(first, basis.size());
        double sum = 0.0;
        for (int j = 0; j <= degree; ++j) {
          EXPECT_GE(phi[j], -1e-15);
          sum += phi[j];
        }
        EXPECT_NEAR(sum, 1.0, 1e-14) << u;
        EXPECT_NEAR(spline_value(basis, c, u + 3.0), spline_value(basis, c, u), 1e-13);
        EXPECT_NEAR(spline_value(basis, c, u - 3.0), spline_value(basis, c, u), 1e-13);
      }
      // Across the closing point: value (C0) and, for a C1 cubic, slope.
      const double e = 1e-7;
      const double before = spline_value(basis, c, 3.0 - e);
      const double after = spline_value(basis, c, e);
      EXPECT_NEAR(before, after, 1e-5);
      if (degree == 3 && closing == Continuity::C1) {
        const double slope_before = (spline_value(basis, c, 3.0 - e) - spline_value(basis, c, 3.0 - 2 * e)) / e;
        const double slope_after = (spline_value(basis, c, 2 * e) - spline_value(basis, c, e)) / e;
        EXPECT_NEAR(slope_before, slope_after, 1e-4 * (1.0 + std::fabs(slope_after)));
      }
    }
  }
}

TEST(Basis, ClosedCurvesGetPeriodicStorageByFormatVersion) {
  // Version 2: the ring's closing point is a smooth joint, so the storage wraps round (16 cubic
  // elements with C1 nodes: 32 functions, none clamped). Version 1: a seam, the clamped basis.
  const Scene ring = ring_scene(2);
  ASSERT_TRUE(ring.curves[0].closed);
  EXPECT_EQ(ring.curves[0].joints.size(), 8u);
  const CurveStorage periodic = build_curve_storage(ring, ring.curves[0], BasisKind::Cubic, 16);
  EXPECT_TRUE(periodic.basis.is_periodic());
  EXPECT_EQ(periodic.closing, Continuity::C1);
  EXPECT_EQ(periodic.basis.size(), 32u);
  const Scene seam = ring_scene(1);
  ASSERT_TRUE(seam.curves[0].closed);
  EXPECT_EQ(seam.curves[0].joints.back(), Continuity::Jump);
  const CurveStorage clamped = build_curve_storage(seam, seam.curves[0], BasisKind::Cubic, 16);
  EXPECT_FALSE(clamped.basis.is_periodic());
  EXPECT_EQ(clamped.basis.size(), 4u + 2u * 15u);
  // A C-1 node asked for at the closing point (a contact there) makes the storage clamped.
  const std::vector<MeshNode> contact = {{0.0, Continuity::Jump}};
  EXPECT_FALSE(build_curve_storage(ring, ring.curves[0], BasisKind::Cubic, 16, false, contact).basis.is_periodic());
  // Few elements are refined until no function meets itself round the loop.
  for (BasisKind kind : {BasisKind::Linear, BasisKind::Cubic}) {
    const CurveStorage few = build_curve_storage(ring, ring.curves[0], kind, 1);
    EXPECT_TRUE(few.basis.is_periodic());
    EXPECT_GE(few.basis.size(), static_cast<std::size_t>(2 * degree_of(kind) + 2));
    double sum = 0.0;
    for (double v : few.basis_length) sum += v;
    EXPECT_NEAR(sum, ring.curves[0].length, 1e-11);
  }
}

TEST(Basis, PeriodicStorageHasNoSeamBias) {
  // Noise-free: exact deposits p_k = integral(B phi_k ds) of a smooth B(phi) on the ring (by a
  // fine midpoint rule, independent of the storage's quadrature), 16 cubic elements (h = pi/8).
  auto errors = [&](const Scene& scene, bool galerkin, auto b_of) {
    const Curve& ring = scene.curves[0];
    const CurveStorage storage = build_curve_storage(scene, ring, BasisKind::Cubic, 16);
    const std::size_t n = storage.basis.size();
    std::vector<double> deposits(n, 0.0);
    const int steps = 80'000;
    Values phi{};
    for (int i = 0; i < steps; ++i) {
      const double u = ring.segment_count * (i + 0.5) / steps;
      const auto j = static_cast<std::uint32_t>(u);
      const Cubic& shape = scene.segments[j].geometry.shape;
      const Vec2 p = evaluate(shape, u - j);
      const double ds = length(derivative(shape, u - j)) * ring.segment_count / steps;
      const std::size_t first = storage.basis.evaluate(u, phi.data());
      for (int r = 0; r <= 3; ++r) deposits[storage.basis.index(first + r)] += b_of(std::atan2(p.y, p.x)) * phi[r] * ds;
    }
    std::vector<double> c(n);
    if (galerkin) {
      galerkin_estimate(storage, deposits.data(), c.data(), 1);
    } else {
      for (std::size_t k = 0; k < n; ++k) c[k] = deposits[k] / storage.basis_length[k];
    }
    double near = 0.0;  // largest error within 0.4 rad of the closing point, and elsewhere
    double away = 0.0;
    for (int i = 0; i < 2000; ++i) {
      const double u = ring.segment_count * (i + 0.5) / 2000;
      const auto j = static_cast<std::uint32_t>(u);
      const Vec2 p = evaluate(scene.segments[j].geometry.shape, u - j);
      const double angle = std::atan2(p.y, p.x);
      const double error = std::fabs(spline_value(storage.basis, c, u) - b_of(angle));
      double& worst = std::fabs(angle) < 0.4 ? near : away;
      worst = std::max(worst, error);
    }
    return std::pair{near, away};
  };
  // Galerkin on the periodic storage: O(h^4) all round. The L2 projection's error is about
  // h^4 max|B^(4)| / 384 = 0.0235 x 9 / 384 = 5.5e-4 at most for this B.
  auto wavy = [](double phi) { return 2.0 + std::cos(phi) + 0.5 * std::sin(2.0 * phi); };
  const auto [periodic_near, periodic_away] = errors(ring_scene(2), true, wavy);
  EXPECT_LT(periodic_away, 5.5e-4);
  EXPECT_LT(periodic_near, 1.5 * periodic_away);
  // Lumped, with B steepest at the closing point (B' = 1, B'' = 0 there): the lumped estimate
  // puts each coefficient at its function's centroid. Periodic, the closing point is like any
  // other place; a seam (format version 1) makes it two curve ends, where the end function's
  // centroid sits h/4 inside, an O(h) error of about B' h / 4 = 0.1.
  auto steep = [](double phi) { return 2.0 + std::sin(phi); };
  const auto [lumped_near, lumped_away] = errors(ring_scene(2), false, steep);
  EXPECT_LT(lumped_near, 1.5 * lumped_away);
  const auto [seam_near, seam_away] = errors(ring_scene(1), false, steep);
  EXPECT_GT(seam_near, 3.0 * seam_away);
  EXPECT_GT(seam_near, 3.0 * lumped_near);
}

// The two ways BasisSampler draws function k: inversion from (u1, u2), and the simplex draw from
// degree + 1 uniforms.
enum class Draw { Inversion, Simplex };

double draw(const BasisSampler& sampler, std::size_t k, Draw how, flatland::Rng& rng) {
  if (how == Draw::Inversion) {
    const double u1 = rng.uniform();
    return sampler.sample(k, u1, rng.uniform());
  }
  std::array<double, 4> uniforms{};
  for (int i = 0; i <= sampler.degree(); ++i) uniforms[static_cast<std::size_t>(i)] = rng.uniform();
  return sampler.sample_simplex(k, uniforms);
}

TEST(Basis, PeriodicSamplerWrapsAndFollowsTheFunction) {
  // A function straddling the closing point: samples lie in [u_begin, u_end) and follow phi_k,
  // checked by a chi-square against midpoint integrals of SplineBasis::evaluate over the support
  // [knots[k], knots[k + 4]] (which starts before 0: samples there come back a period later).
  const std::vector<MeshNode> nodes = {
      {0.5, Continuity::C1}, {1.2, Continuity::C1}, {2.0, Continuity::C1}, {2.5, Continuity::C1}};
  const SplineBasis basis = SplineBasis::periodic(3, 0.0, 3.0, nodes, Continuity::C1);
  const BasisSampler sampler(basis);
  std::size_t k = 0;  // the function whose support contains the closing point
  while (!(basis.knots()[k] < 0.0 && basis.knots()[k + 4] > 0.0)) ++k;
  const double a = basis.knots()[k];
  const double b = basis.knots()[k + 4];
  ASSERT_LT(a, 0.0);
  ASSERT_GT(b, 0.0);
  const int n = 40'000;
  const int bins = 10;
  std::vector<double> expected(bins, 0.0);
  double total = 0.0;
  for (int bin = 0; bin < bins; ++bin) {
    for (int j = 0; j < 1000; ++j) {
      const double u = a + (b - a) * (bin + (j + 0.5) / 1000) / bins;
      Values phi{};
      const std::size_t first = basis.evaluate(u, phi.data());
      for (int r = 0; r <= 3; ++r)
        if (basis.index(first + r) == k) expected[bin] += phi[r];
    }
    total += expected[bin];
  }
  for (double& e : expected) e *= n / total;
  for (const Draw how : {Draw::Inversion, Draw::Simplex}) {
    flatland::Rng rng(how == Draw::Inversion ? 5 : 6, 0, 0);
    std::vector<double> observed(bins, 0.0);
    for (int i = 0; i < n; ++i) {
      const double u = draw(sampler, k, how, rng);
      ASSERT_GE(u, 0.0);
      ASSERT_LT(u, 3.0);
      const double unwrapped = u >= b ? u - 3.0 : u;
      observed[std::clamp(static_cast<int>((unwrapped - a) / (b - a) * bins), 0, bins - 1)] += 1;
    }
    EXPECT_LT(testing::chi_square(observed, expected), testing::chi_square_critical(bins - 1))
        << (how == Draw::Simplex ? "simplex" : "inversion");
  }
  EXPECT_GT(sampler.pdf(k, 0.1), 0.0);
  EXPECT_GT(sampler.pdf(k, 2.95), 0.0);  // the part before 0, a period later
  EXPECT_EQ(sampler.pdf(k, 1.5), 0.0);
}

TEST(Basis, EvaluateFindsTheSpanHoldingU) {
  // evaluate() finds the span through a grid of cells per unit of u; the answer must be the span
  // a plain search gives: the last i in [first_span, end_span) with knots[i] <= u (the non-empty
  // span starting at u when u is a knot of any multiplicity). Meshes: crowded and sparse unit
  // intervals (32 nodes in [1, 2), one in [3, 4)), repeated nodes (C0, C-1), an extent below one
  // unit, a start off the integers, and periodic bases; u random, on every knot and one step
  // either side of it.
  std::vector<MeshNode> crowded;
  for (int i = 1; i < 33; ++i) crowded.push_back({1.0 + i / 33.0, i % 5 == 0 ? Continuity::C0 : Continuity::C1});
  crowded.push_back({2.0, Continuity::Jump});
  crowded.push_back({3.5, Continuity::C1});
  std::vector<MeshNode> graded;  // 30 nodes crowding towards u = 1: most in one grid cell
  for (int i = 30; i >= 1; --i) graded.push_back({1.0 + std::ldexp(1.0, -i), Continuity::C1});
  const std::vector<MeshNode> short_nodes = {{0.1, Continuity::C1}, {0.25, Continuity::C0}};
  const std::vector<MeshNode> offset = {{2.7, Continuity::C1}, {3.0, Continuity::C1}, {4.9, Continuity::C0}};
  std::vector<SplineBasis> bases;
  for (int degree = 0; degree <= 3; ++degree) {
    bases.emplace_back(degree, 0.0, 4.0, crowded);
    bases.emplace_back(degree, 0.0, 0.4, short_nodes);
    bases.emplace_back(degree, 0.0, 3.0, graded);
    bases.emplace_back(degree, 2.3, 5.6, offset);
    if (degree > 0) {
      std::vector<MeshNode> ring;
      for (int i = 1; i < 12; ++i) ring.push_back({i * 0.25, Continuity::C1});
      bases.push_back(SplineBasis::periodic(degree, 0.0, 3.0, ring, Continuity::C1));
      bases.push_back(SplineBasis::periodic(degree, 0.0, 4.0, crowded, Continuity::C0));
    }
  }
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (const SplineBasis& basis : bases) {
    const std::vector<double>& knots = basis.knots();
    std::vector<double> probes;
    for (int i = 0; i < 400; ++i) probes.push_back(basis.u_begin() + (basis.u_end() - basis.u_begin()) * unit(rng));
    for (std::size_t i = basis.first_span(); i < basis.end_span(); ++i) {
      probes.push_back(knots[i]);
      probes.push_back(std::nextafter(knots[i], -1e300));
      probes.push_back(std::nextafter(knots[i], 1e300));
    }
    std::array<double, SplineBasis::kMaxDegree + 1> values{};
    for (double u : probes) {
      if (!(u >= basis.u_begin() && u < basis.u_end())) continue;
      std::size_t want = basis.first_span();
      for (std::size_t i = basis.first_span(); i < basis.end_span(); ++i)
        if (knots[i] <= u) want = i;
      const std::size_t first = basis.evaluate(u, values.data());
      EXPECT_EQ(first + static_cast<std::size_t>(basis.degree()), want)
          << "degree " << basis.degree() << " periodic " << basis.is_periodic() << " u " << u;
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
  const std::vector<MeshNode> nodes = {{1.0, Continuity::C1}, {2.0, Continuity::C0}, {3.0, Continuity::Jump}};
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

TEST(Basis, SpeedBoundHoldsOverEachSupportAndIsTight) {
  // speed_bound[k] bounds |C'(u)| over phi_k's support, on every segment the support touches
  // (periodic supports wrap round the closing point), and is close to the largest speed there:
  // compared with |C'| sampled densely, on curves of several segments whose speed varies along
  // each segment (closed with smooth joints, so periodic; and open).
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 2,
    "materials": {"wall": {"reflectivity": 0.5, "emittance": 1}},
    "curves": [
      {"id": "loop", "material": "wall",
       "bezier": [[0,0],[0.2,0],[3,-0.5],[3,1],[3,2.5],[2.5,3],[1,3],[0.2,3],[-1,2],[-1,1],[-1,0.2],[-0.1,0],[0,0]]},
      {"id": "wave", "material": "wall",
       "bezier": [[0,5],[0.1,6],[2,6],[2,5],[2,4],[2.5,4.2],[4,5],[5,5.5],[6,7],[8,5]]},
      {"id": "kinked", "material": "wall",
       "bezier": [[5,0],[6,0],[7,1],[7,2],[7,3],[6,3],[5,2],[4,1.5],[4,0.5],[5,0]]}
    ]})");
  ASSERT_TRUE(scene.curves[0].closed);
  ASSERT_TRUE(scene.curves[2].closed);  // with corners: clamped storage unless joints are smoothed
  for (const Curve& curve : scene.curves) {
    const double period = curve.segment_count;
    bool periodic = false;
    auto speed = [&](double u) {
      if (periodic) u -= period * std::floor(u / period);
      const auto j = static_cast<std::uint32_t>(std::clamp(std::floor(u), 0.0, period - 1.0));
      return length(derivative(scene.segments[curve.first_segment + j].geometry.shape, u - j));
    };
    for (BasisKind kind : {BasisKind::Constant, BasisKind::Linear, BasisKind::Cubic}) {
      for (int elements : {1, 3, 16, 64}) {
        for (bool smooth : {true, false}) {
          const CurveStorage storage = build_curve_storage(scene, curve, kind, elements, smooth, {}, 0);
          periodic = storage.basis.is_periodic();
          if (curve.id == "kinked") {
            EXPECT_EQ(periodic, smooth);
          }
          const std::vector<double>& knots = storage.basis.knots();
          const std::size_t p = static_cast<std::size_t>(storage.basis.degree());
          for (std::size_t k = 0; k < storage.basis.size(); ++k) {
            const double begin = knots[k];
            const double end = knots[k + p + 1];
            double fastest = 0.0;
            constexpr int kSamples = 2000;
            // Midpoints: the support's own ends may be another segment's start (a corner).
            for (int i = 0; i < kSamples; ++i)
              fastest = std::max(fastest, speed(begin + (end - begin) * (i + 0.5) / kSamples));
            EXPECT_GE(storage.speed_bound[k], fastest * (1.0 - 1e-12))
                << curve.id << " " << to_string(kind) << " " << elements << " k " << k;
            EXPECT_LE(storage.speed_bound[k], 1.1 * fastest)
                << curve.id << " " << to_string(kind) << " " << elements << " k " << k;
          }
        }
      }
    }
  }
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

TEST(Basis, GalerkinConservesPowerAndClampKeepsIt) {
  // Deposits concentrated on one basis function make the L2 projection oscillate negative; it
  // still holds exactly the deposited power (the functions sum to one, so sum_k b_k L_k = 1^T M b
  // = sum_k p_k), and clamp_keeping_power makes it nonnegative with the same power.
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
  double lowest = 0.0;
  for (std::size_t k = 0; k < b.size(); ++k) {
    lowest = std::min(lowest, b[k]);
    power += b[k] * storage.basis_length[k];
  }
  EXPECT_LT(lowest, 0.0);
  EXPECT_NEAR(power, 2.0, 1e-13);
  EXPECT_TRUE(clamp_keeping_power(storage, b.data(), 1, 2.0));
  // Nothing positive left: false, all zero (the solver then falls back to the lumped density).
  std::vector<double> negative(storage.basis.size(), -1.0);
  EXPECT_FALSE(clamp_keeping_power(storage, negative.data(), 1, 2.0));
  for (double v : negative) EXPECT_EQ(v, 0.0);
  power = 0.0;
  for (std::size_t k = 0; k < b.size(); ++k) {
    EXPECT_GE(b[k], 0.0);
    power += b[k] * storage.basis_length[k];
  }
  EXPECT_NEAR(power, 2.0, 1e-13);
}

// Noise-free estimator order (exact expected deposits, no photons). The deposits
// p_k = integral(phi_k R ds) of a closed-form R, by 16 Gauss panels of 8 points per knot span (far
// finer than the storage's own quadrature, and R is smooth inside every span), then the largest
// reconstruction error on a fine grid and at both sides of every node, for h halved four times;
// the observed order is the least-squares slope of log error against log h. exact(u, mid) is R
// at u on the piece of R that holds mid (the middle of the span being integrated).
template <typename Exact>
double worst_error(const Scene& scene, const Curve& curve, BasisKind kind, int elements, int subdivisions,
                   std::span<const MeshNode> extra, Estimator estimator, Exact exact) {
  CurveStorage storage = build_curve_storage(scene, curve, kind, elements, false, extra, subdivisions);
  const SplineBasis& basis = storage.basis;
  const std::size_t n = basis.size();
  const std::size_t p = static_cast<std::size_t>(basis.degree());
  const std::vector<double>& knots = basis.knots();
  auto speed = [&](double u) {
    const auto j = static_cast<std::uint32_t>(std::min<double>(std::floor(u), curve.segment_count - 1.0));
    return length(derivative(scene.segments[curve.first_segment + j].geometry.shape, u - j));
  };
  std::vector<double> deposits(n, 0.0);
  Values phi{};
  for (std::size_t span = basis.first_span(); span < basis.end_span(); ++span) {
    const double a = knots[span];
    const double b = knots[span + 1];
    if (!(b > a)) continue;
    constexpr int kPanels = 16;
    for (int panel = 0; panel < kPanels; ++panel) {
      const double pa = a + (b - a) * panel / kPanels;
      const double half = 0.5 * (b - a) / kPanels;
      for (std::size_t g = 0; g < gauss::kNodes8.size(); ++g) {
        const double u = pa + half * (1.0 + gauss::kNodes8[g]);
        const double wrapped = basis.wrap(u);
        basis.evaluate_in_span(span, u, phi.data());
        const double weight = gauss::kWeights8[g] * half * speed(wrapped) * exact(wrapped, basis.wrap(0.5 * (a + b)));
        for (std::size_t j = 0; j <= p; ++j) deposits[basis.index(span - p + j)] += weight * phi[j];
      }
    }
  }
  std::vector<double> c(n);
  switch (resolve_estimator(estimator, kind)) {
    case Estimator::Auto: break;  // resolved: never Auto
    case Estimator::Lumped:
      for (std::size_t k = 0; k < n; ++k) c[k] = deposits[k] / storage.basis_length[k];
      break;
    case Estimator::Galerkin: galerkin_estimate(storage, deposits.data(), c.data(), 1); break;
    case Estimator::Local:
      build_local_estimator(scene, curve, storage, false);
      local_estimate(storage, deposits.data(), c.data(), 1);
      break;
  }
  // The error inside every non-empty span, its ends approached from inside.
  double worst = 0.0;
  for (std::size_t span = basis.first_span(); span < basis.end_span(); ++span) {
    const double a = knots[span];
    const double b = knots[span + 1];
    if (!(b > a)) continue;
    for (int i = 0; i <= 20; ++i) {
      const double u = a + (b - a) * std::clamp(i / 20.0, 1e-9, 1.0 - 1e-9);
      basis.evaluate_in_span(span, u, phi.data());
      double value = 0.0;
      for (std::size_t j = 0; j <= p; ++j) value += c[basis.index(span - p + j)] * phi[j];
      worst = std::max(worst, std::fabs(value - exact(basis.wrap(u), basis.wrap(0.5 * (a + b)))));
    }
  }
  return worst;
}

// Least-squares slope of log(error) against log(h) for `coarsest` elements halved four times.
template <typename Exact>
double observed_order(const Scene& scene, BasisKind kind, std::span<const MeshNode> extra, Estimator estimator,
                      Exact exact, int coarsest = 8) {
  std::vector<double> x;
  std::vector<double> y;
  // h halved four times by subdivision (auto storage's nested levels): every element, also those
  // of the regions between the nodes, exactly halves.
  for (int subdivisions = 0; subdivisions <= 4; ++subdivisions) {
    x.push_back(-std::log(static_cast<double>(coarsest << subdivisions)));
    y.push_back(std::log(worst_error(scene, scene.curves[0], kind, coarsest, subdivisions, extra, estimator, exact)));
  }
  const double mx = std::accumulate(x.begin(), x.end(), 0.0) / static_cast<double>(x.size());
  const double my = std::accumulate(y.begin(), y.end(), 0.0) / static_cast<double>(y.size());
  double sxy = 0.0;
  double sxx = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sxy += (x[i] - mx) * (y[i] - my);
    sxx += (x[i] - mx) * (x[i] - mx);
  }
  return sxy / sxx;
}
TEST(Basis, EstimatorsDeliverTheBasisOrder) {
  // An open straight line and an open curved cubic (u not proportional to arc length), each with a
  // C0 node (R has a kink there) and a C-1 node (R jumps), and a closed ring (periodic storage) with
  // a smooth R. Galerkin and local must show order p + 1 in the largest error, ends and nodes
  // included; lumped does not (its coefficients sit at the functions' centroids: O(h) at ends).
  const Scene line = testing::scene_from_text(R"({"flatland": 2,
    "materials": {"wall": {"reflectivity": 0.5, "emittance": 1}},
    "curves": [{"id": "line", "material": "wall", "line": [[0,0],[4,0]]}]})");
  const Scene curved = testing::scene_from_text(R"({"flatland": 2,
    "materials": {"wall": {"reflectivity": 0.5, "emittance": 1}},
    "curves": [{"id": "s", "material": "wall", "bezier": [[0,0],[1,2],[3,-1],[4,1]]}]})");
  const std::vector<MeshNode> nodes = {{0.37, Continuity::C0}, {0.71, Continuity::Jump}};
  auto with_nodes = [](double u, double mid) {
    return 1.0 + 0.5 * std::sin(3.0 * u) + 0.8 * std::fabs(u - 0.37) + (mid > 0.71 ? 0.6 : 0.0);
  };
  const Scene ring = ring_scene(2);
  auto on_ring = [&](double u, double) { return smooth_on_ring(ring, u); };
  const std::vector<MeshNode> none;
  for (BasisKind kind : {BasisKind::Constant, BasisKind::Linear, BasisKind::Cubic}) {
    const double expected = degree_of(kind) + 1.0;
    for (Estimator estimator : {Estimator::Galerkin, Estimator::Local}) {
      SCOPED_TRACE(std::string(to_string(kind)) + " " + to_string(estimator));
      // 16 to 256 elements: the three regions the nodes cut the curve into are split evenly, so at
      // 8 a region may hold two elements, too few for the local estimator's cubic (its windows
      // stop at C0 and C-1 nodes); on 8 the cubic local estimate on the curved one showed 3.6.
      EXPECT_NEAR(observed_order(line, kind, nodes, estimator, with_nodes, 16), expected, 0.3);
      EXPECT_NEAR(observed_order(curved, kind, nodes, estimator, with_nodes, 16), expected, 0.3);
      // The ring's eight arcs meet at joints where R(u) is C1 but not C2 (the cubic arcs' speed
      // turns there): the local estimator works between joints, so it needs a few elements per
      // arc before it reaches its order: 8 to 128 per arc.
      EXPECT_NEAR(observed_order(ring, kind, none, estimator, on_ring, 64), expected, 0.3);
    }
  }
  // Lumped: first order at the open curves' ends and nodes, for linear and cubic alike.
  for (BasisKind kind : {BasisKind::Linear, BasisKind::Cubic}) {
    SCOPED_TRACE(to_string(kind));
    EXPECT_LT(observed_order(line, kind, nodes, Estimator::Lumped, with_nodes, 16), 1.3);
    EXPECT_LT(observed_order(curved, kind, nodes, Estimator::Lumped, with_nodes, 16), 1.3);
  }
}

TEST(Basis, LocalEstimatorStaysLocalWithOneElementPerSegment) {
  // At one element per segment every cubic function straddles a joint, so no window fits between
  // two joints. The windows then cross the joints (R(u) is C1 there) and stay beside their
  // function: on the ring with a seam (format 1: clamped storage, C-1 at the closing point) the
  // search for a one-sided window once walked to the curve's ends and extrapolated from there, with
  // weights in the hundreds (noise amplified as much) and errors of 10-30 % in solves.
  const Scene ring = ring_scene(1);
  const Curve& curve = ring.curves[0];
  auto on_ring = [&](double u, double) { return smooth_on_ring(ring, u); };
  const std::vector<MeshNode> none;
  for (BasisKind kind : {BasisKind::Linear, BasisKind::Cubic}) {
    SCOPED_TRACE(to_string(kind));
    CurveStorage storage = build_curve_storage(ring, curve, kind, 8);
    ASSERT_FALSE(storage.basis.is_periodic());
    build_local_estimator(ring, curve, storage, false);
    double worst_amplification = 0.0;
    for (std::size_t k = 0; k < storage.basis.size(); ++k) {
      // sum |w_i| integral(phi_i ds): the factor by which the estimate can amplify a deposit's
      // relative noise (1 for the lumped estimate, whose weight is 1 / integral(phi_k ds)); the
      // one-sided cubic windows at the seam reach 3.8.
      double amplification = 0.0;
      for (std::size_t i = storage.local_first[k]; i < storage.local_first[k + 1]; ++i)
        amplification += std::fabs(storage.local_weight[i]) * storage.basis_length[storage.local_index[i]];
      worst_amplification = std::max(worst_amplification, amplification);
      EXPECT_LT(amplification, 5.0) << "coefficient " << k;
      EXPECT_EQ(storage.local_degree[k], degree_of(kind)) << "coefficient " << k;
    }
    std::printf("%s, 8 elements: noise amplification at most %.3g\n", to_string(kind), worst_amplification);
    // Noise-free, cubic: the local estimate keeps its order across the joints, far below the
    // lumped estimate's error at two and four elements an arc (measured: 0.012 and 3.1e-4 against
    // 0.083 and 0.041). Linear local is not compared: its least-variance window of five hats has a
    // larger O(h^2) constant than lumped's (docs/method.md, "Estimators: measured").
    if (kind == BasisKind::Cubic)
      for (int subdivisions : {1, 2}) {
        const double local = worst_error(ring, curve, kind, 8, subdivisions, none, Estimator::Local, on_ring);
        const double lumped = worst_error(ring, curve, kind, 8, subdivisions, none, Estimator::Lumped, on_ring);
        EXPECT_LT(local, 0.5 * lumped) << (8 << subdivisions) << " elements";
      }
  }
}

TEST(Basis, LocalNodalValuesAreFourthOrder) {
  // Hermite storage (hats) with nodal_values: coefficient k estimates R at its hat's peak from the
  // hats' deposits, exact for cubics, so the largest nodal error falls as h^4; the lumped hat
  // average is O(h^2) inside and worse next to the ends and nodes.
  const Scene curved = testing::scene_from_text(R"({"flatland": 2,
    "materials": {"wall": {"reflectivity": 0.5, "emittance": 1}},
    "curves": [{"id": "s", "material": "wall", "bezier": [[0,0],[1,2],[3,-1],[4,1]]}]})");
  const Curve& curve = curved.curves[0];
  const Cubic& shape = curved.segments[0].geometry.shape;
  const std::vector<MeshNode> nodes = {{0.37, Continuity::C0}, {0.71, Continuity::Jump}};
  auto exact = [](double u, double mid) {
    return 1.0 + 0.5 * std::sin(3.0 * u) + 0.8 * std::fabs(u - 0.37) + (mid > 0.71 ? 0.6 : 0.0);
  };
  auto nodal_error = [&](int elements, bool local) {
    CurveStorage storage = build_curve_storage(curved, curve, BasisKind::Hermite, elements, false, nodes);
    const std::vector<double>& knots = storage.basis.knots();
    const std::size_t n = storage.basis.size();
    std::vector<double> deposits(n, 0.0);
    Values phi{};
    for (std::size_t span = 1; span + 1 < knots.size(); ++span) {
      const double a = knots[span];
      const double b = knots[span + 1];
      if (!(b > a)) continue;
      for (int panel = 0; panel < 16; ++panel) {
        const double half = 0.5 * (b - a) / 16;
        for (std::size_t g = 0; g < gauss::kNodes8.size(); ++g) {
          const double u = a + (b - a) * panel / 16 + half * (1.0 + gauss::kNodes8[g]);
          storage.basis.evaluate_in_span(span, u, phi.data());
          const double weight = gauss::kWeights8[g] * half * length(derivative(shape, u)) * exact(u, 0.5 * (a + b));
          deposits[span - 1] += weight * phi[0];
          deposits[span] += weight * phi[1];
        }
      }
    }
    std::vector<double> c(n);
    if (local) {
      build_local_estimator(curved, curve, storage, true);
      local_estimate(storage, deposits.data(), c.data(), 1);
    } else {
      for (std::size_t k = 0; k < n; ++k) c[k] = deposits[k] / storage.basis_length[k];
    }
    double worst = 0.0;
    for (std::size_t k = 0; k < n; ++k)
      worst = std::max(worst, std::fabs(c[k] - exact(knots[k + 1], 0.5 * (knots[k] + knots[k + 2]))));
    return worst;
  };
  for (bool local : {true, false}) {
    const double coarse = nodal_error(32, local);
    const double fine = nodal_error(128, local);
    const double order = std::log2(coarse / fine) / 2.0;
    if (local) {
      EXPECT_NEAR(order, 4.0, 0.3);
    } else {
      EXPECT_LT(order, 2.0);
    }
  }
}

TEST(Basis, RegionsBetweenNodesAreSplitEvenlyWithoutSlivers) {
  // A curve of two cubics (the second straight, with uneven speed) with extra nodes: one 1e-4 (in
  // u) past the first segment's arc-length midpoint, where an even split of the segment puts an
  // element boundary at every level, two 2e-6 apart, and one on the second segment. At every subdivision every element
  // is at most the level's element length (its segment's length over its elements), and one shorter than half of that
  // is a whole region between fixed nodes: no sliver next to a node. The levels nest node for node, and a region splits
  // evenly in arc length.
  const Scene scene = testing::scene_from_text(R"({"flatland": 2,
    "materials": {"wall": {"reflectivity": 0.5, "emittance": 1}},
    "curves": [{"id": "s", "material": "wall", "bezier": [[0,0],[1,2],[3,-1],[4,1],[4.5,1],[5.5,1],[6,1]]}]})");
  const Curve& curve = scene.curves[0];
  ASSERT_EQ(curve.segment_count, 2u);
  // The arc-length midpoint of the first segment: an element boundary of every even split.
  const double middle =
      scene.segments[0].arc_length.parameter_at(scene.segments[0].geometry.shape, 0.5 * scene.segments[0].length);
  ASSERT_LT(middle + 1e-4, 0.8);
  const std::vector<MeshNode> extra = {
      {middle + 1e-4, Continuity::C0}, {0.8, Continuity::Jump}, {0.800002, Continuity::C0}, {1.3, Continuity::C0}};
  auto arc_length = [&](double u) { return arc_length_at(scene, curve, u); };
  auto is_fixed = [&](double u) {
    if (u == 0.0 || u == 1.0 || u == 2.0) return true;
    for (const MeshNode& node : extra)
      if (u == node.u) return true;
    return false;
  };
  const int elements = 8;
  std::vector<double> previous;
  for (int subdivisions = 0; subdivisions <= 6; ++subdivisions) {
    SCOPED_TRACE("subdivisions " + std::to_string(subdivisions));
    const CurveStorage storage =
        build_curve_storage(scene, curve, BasisKind::Cubic, elements, false, extra, subdivisions);
    std::vector<double> knots;
    for (double u : storage.basis.knots())
      if (knots.empty() || u > knots.back()) knots.push_back(u);
    for (std::size_t k = 1; k < knots.size(); ++k) {
      const auto segment = static_cast<std::uint32_t>(std::min(std::floor(knots[k - 1]), 1.0));
      const double level_element = scene.segments[segment].length /
                                   segment_elements(elements, scene.segments[segment].length, curve.length) /
                                   std::ldexp(1.0, subdivisions);
      const double length = arc_length(knots[k]) - arc_length(knots[k - 1]);
      EXPECT_LE(length, level_element * (1.0 + 1e-9)) << knots[k - 1];
      if (length < 0.5 * level_element) {
        EXPECT_TRUE(is_fixed(knots[k - 1]) && is_fixed(knots[k])) << "a sliver at " << knots[k - 1];
      }
      if (knots[k - 1] >= 1.3) {  // the region after the last node: an even split
        const double region = curve.length - arc_length(1.3);
        EXPECT_NEAR(length, region / std::round(region / length), 1e-12 * curve.length);
      }
    }
    for (double u : previous)
      EXPECT_TRUE(std::binary_search(knots.begin(), knots.end(), u)) << "coarse node " << u << " missing";
    previous = knots;
  }
}

TEST(Basis, NestedLevelsRestrictAndProlongExactly) {
  // Storages built with more subdivisions nest: every coarse function is a nonnegative combination
  // of fine ones, so a coarse spline prolonged into the fine basis is the same function, and the
  // deposits a photon leaves on the coarse functions are the restriction of its fine deposits.
  // Checked pointwise on an open curve with C0 and C-1 nodes and on the periodic ring.
  const Scene curved = testing::scene_from_text(R"({"flatland": 2,
    "materials": {"wall": {"reflectivity": 0.5, "emittance": 1}},
    "curves": [{"id": "s", "material": "wall", "bezier": [[0,0],[1,2],[3,-1],[4,1]]}]})");
  const Scene ring = ring_scene(2);
  const std::vector<MeshNode> nodes = {{0.37, Continuity::C0}, {0.71, Continuity::Jump}};
  std::mt19937_64 random(5);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  for (const Scene* scene : {&curved, &ring}) {
    const Curve& curve = scene->curves[0];
    const std::span<const MeshNode> extra =
        scene == &curved ? std::span<const MeshNode>(nodes) : std::span<const MeshNode>();
    for (BasisKind kind : {BasisKind::Constant, BasisKind::Linear, BasisKind::Cubic}) {
      SCOPED_TRACE(to_string(kind));
      const CurveStorage fine = build_curve_storage(*scene, curve, kind, 4, false, extra, 3);
      for (int level = 0; level < 3; ++level) {
        const CurveStorage coarse = build_curve_storage(*scene, curve, kind, 4, false, extra, level);
        ASSERT_LT(coarse.basis.size(), fine.basis.size());
        const Restriction r = restriction_between(coarse.basis, fine.basis);
        for (double w : r.weight) EXPECT_GE(w, 0.0);
        std::vector<double> b(coarse.basis.size());
        for (double& v : b) v = uniform(random);
        std::vector<double> prolonged(fine.basis.size());
        prolong_coefficients(r, b.data(), prolonged.data(), 1);
        double worst_function = 0.0;
        double worst_deposit = 0.0;
        for (int i = 0; i < 500; ++i) {
          const double u = curve.segment_count * uniform(random);
          worst_function = std::max(
              worst_function, std::fabs(spline_value(coarse.basis, b, u) - spline_value(fine.basis, prolonged, u)));
          // One photon at u: fine deposits phi_fine(u), restricted, against phi_coarse(u).
          std::vector<double> deposit(fine.basis.size(), 0.0);
          Values phi{};
          std::size_t first = fine.basis.evaluate(u, phi.data());
          for (int j = 0; j <= fine.basis.degree(); ++j) deposit[fine.basis.index(first + j)] += phi[j];
          std::vector<double> restricted(coarse.basis.size());
          restrict_deposits(r, deposit.data(), 1, restricted.data());
          std::vector<double> direct(coarse.basis.size(), 0.0);
          first = coarse.basis.evaluate(u, phi.data());
          for (int j = 0; j <= coarse.basis.degree(); ++j) direct[coarse.basis.index(first + j)] += phi[j];
          for (std::size_t k = 0; k < direct.size(); ++k)
            worst_deposit = std::max(worst_deposit, std::fabs(restricted[k] - direct[k]));
        }
        EXPECT_LT(worst_function, 1e-12);
        EXPECT_LT(worst_deposit, 1e-12);
      }
    }
  }
}

TEST(Basis, SamplerInvertsThePieceCdfToRounding) {
  // sample(k, u1, u2) puts u where the share of its piece's mass (a non-empty knot span of phi_k's
  // support) below u is u2. Checked against SplineBasis::evaluate integrated by 3-point
  // Gauss-Legendre (exact for a cubic piece), for every function of a cubic basis with C1, C0 and
  // jump nodes and uneven spans: pieces rising, falling, humped and vanishing at an end to third
  // order. The iteration must finish, not stop near the root: stopped after two Newton steps it
  // errs by 3e-3.
  const std::vector<MeshNode> nodes = {{0.3, Continuity::C1}, {0.45, Continuity::C1}, {1.0, Continuity::Jump},
                                       {1.6, Continuity::C0}, {2.5, Continuity::C1},  {2.9, Continuity::C1}};
  const SplineBasis basis(3, 0.0, 3.0, nodes);
  const BasisSampler sampler(basis);
  const std::vector<double>& knots = basis.knots();
  auto phi = [&](std::size_t k, std::size_t span, double u) {
    Values values{};
    basis.evaluate_in_span(span, u, values.data());
    return k + 3 >= span && k <= span ? values[k + 3 - span] : 0.0;
  };
  auto integral = [&](std::size_t k, std::size_t span, double a, double b) {
    const double half = 0.5 * (b - a);
    const double mid = 0.5 * (a + b);
    const double node = std::sqrt(0.6);
    return half * (5.0 / 9.0 * phi(k, span, mid - half * node) + 8.0 / 9.0 * phi(k, span, mid) +
                   5.0 / 9.0 * phi(k, span, mid + half * node));
  };
  flatland::Rng rng(23, 0, 0);
  double worst = 0.0;
  for (std::size_t k = 0; k < basis.size(); ++k) {
    for (int n = 0; n < 4000; ++n) {
      const double u1 = rng.uniform();
      const double u2 = 0.001 + 0.998 * rng.uniform();
      const double u = sampler.sample(k, u1, u2);
      std::size_t span = k;  // the non-empty span of k's support holding u
      while (span < k + 3 && !(knots[span + 1] > knots[span] && u < knots[span + 1])) ++span;
      ASSERT_GT(knots[span + 1], knots[span]);
      const double share = integral(k, span, knots[span], u) / integral(k, span, knots[span], knots[span + 1]);
      worst = std::max(worst, std::fabs(share - u2));
    }
  }
  EXPECT_LT(worst, 1e-12);
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

// Chi-square of n samples of every basis function of a clamped basis against the integral of
// phi_k over each of 24 bins of its support, computed by the midpoint rule from
// SplineBasis::evaluate (not from the sampler); bins with small expectations are merged.
void expect_samples_follow_every_function(const SplineBasis& basis, Draw how, std::uint64_t seed) {
  const BasisSampler sampler(basis);
  const auto p = static_cast<std::size_t>(basis.degree());
  flatland::Rng rng(seed, 0, 0);
  const int n = 100'000;
  const int bins = 24;
  for (std::size_t k = 0; k < basis.size(); ++k) {
    const double a = basis.knots()[k];
    const double b = basis.knots()[k + p + 1];
    std::vector<double> observed(bins, 0.0);
    for (int i = 0; i < n; ++i) {
      const double u = draw(sampler, k, how, rng);
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
        if (k >= first && k <= first + p) expected[bin] += phi[k - first];
      }
      total += expected[bin];
    }
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
        << "degree " << p << ", basis function " << k << (how == Draw::Simplex ? ", simplex" : ", inversion");
  }
}

TEST(Basis, SamplerFollowsTheBasisFunction) {
  // Every degree, with a C1 node, a jump and a C0 node (repeated knots inside supports and at
  // their ends), both draws.
  const std::vector<MeshNode> nodes = {
      {0.5, Continuity::C1}, {1.0, Continuity::Jump}, {1.6, Continuity::C0}, {2.5, Continuity::C1}};
  for (int degree = 0; degree <= 3; ++degree) {
    const SplineBasis basis(degree, 0.0, 3.0, nodes);
    expect_samples_follow_every_function(basis, Draw::Inversion, 21 + static_cast<std::uint64_t>(degree));
    expect_samples_follow_every_function(basis, Draw::Simplex, 31 + static_cast<std::uint64_t>(degree));
  }
}

TEST(Basis, SimplexDrawHasTheKnotsMeanAndStaysOnTheSupport) {
  // Curry and Schoenberg's closed form: the normalised B-spline on knots t_0 .. t_(p+1) has mean
  // (t_0 + .. + t_(p+1)) / (p + 2) (and the simplex draw is built from that representation, so
  // this checks the sorting and the spacings, independently of the chi-square above). The
  // standard error of the sample mean is at most (t_(p+1) - t_0) / sqrt(12 n); 5 of them.
  const std::vector<MeshNode> nodes = {
      {0.25, Continuity::C1}, {0.3, Continuity::C1}, {1.0, Continuity::C0}, {2.9, Continuity::C1}};
  for (int degree = 0; degree <= 3; ++degree) {
    const SplineBasis basis(degree, 0.0, 3.0, nodes);
    const BasisSampler sampler(basis);
    const auto p = static_cast<std::size_t>(degree);
    flatland::Rng rng(41, static_cast<std::uint64_t>(degree), 0);
    const int n = 200'000;
    for (std::size_t k = 0; k < basis.size(); ++k) {
      const double* t = basis.knots().data() + k;
      double mean = 0.0;
      for (std::size_t i = 0; i <= p + 1; ++i) mean += t[i];
      mean /= static_cast<double>(p + 2);
      double sum = 0.0;
      for (int i = 0; i < n; ++i) {
        const double u = draw(sampler, k, Draw::Simplex, rng);
        ASSERT_GE(u, t[0]);
        ASSERT_LE(u, t[p + 1]);
        sum += u;
      }
      EXPECT_NEAR(sum / n, mean, 5.0 * (t[p + 1] - t[0]) / std::sqrt(12.0 * n))
          << "degree " << degree << ", basis function " << k;
    }
    // The extreme uniforms land on the support's ends, not beyond.
    for (std::size_t k = 0; k < basis.size(); ++k) {
      EXPECT_EQ(sampler.sample_simplex(k, {0.0, 0.0, 0.0, 0.0}), basis.knots()[k + p + 1]);
      const double top = std::nextafter(1.0, 0.0);
      const double u = sampler.sample_simplex(k, {top, top, top, top});
      EXPECT_GE(u, basis.knots()[k]);
      EXPECT_LT(u - basis.knots()[k], 1e-14 * 3.0);  // 3: the basis's extent
    }
  }
}

}  // namespace
}  // namespace flatland
