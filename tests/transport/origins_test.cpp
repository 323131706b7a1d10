// The samplers of photon origins: each Sample, pseudo-random and from Sobol' points, follows the
// density its Pdf states, and both match a density computed here independently (arc length by
// bisection of point_at_arc_length, the emittance profile, the B-spline basis, the Hermite
// reconstruction's values) by quadrature over bins of arc length.
#include "flatland/transport/origins.hpp"

#include <cmath>
#include <functional>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/geometry/bezier.hpp"
#include "test_support.hpp"

namespace flatland {
namespace {

// An open curve of two cubic segments of different shapes (their speeds vary by about 2x and their
// speed bounds are not in proportion to their lengths, so the rejection against the speed bound
// matters), joined with a continuous tangent and speed (no storage node there: the densities
// below are smooth enough for Simpson's rule), with a smooth emittance profile; and an open line
// of two segments.
constexpr const char* kScene = R"({"flatland": 2,
  "materials": {"lamp": {"reflectivity": 0.5, "emittance": 1}},
  "curves": [
    {"id": "arc", "material": "lamp",
     "bezier": [[0, 0], [0.2, 1.2], [1.0, 1.4], [1.5, 1.0], [2.0, 0.6], [2.2, 0.2], [3.0, 0.0]],
     "emittance_profile": [0.2, 1.0, 1.6, 0.9, 0.4, 1.2, 0.5]},
    {"id": "line", "material": "lamp", "line": [[0, -1], [1, -1.5], [3, -1.2]]}
  ]})";

struct Fixture {
  Scene scene;
  std::vector<Vec2> line_tangents;
  std::vector<DiscreteDistribution> segment_choice;

  Fixture() {
    Result<Scene> parsed = parse_scene(kScene, "origins_test");
    EXPECT_TRUE(parsed) << parsed.error().message;
    scene = std::move(*parsed);
    line_tangents = flatland::line_tangents(scene);
    for (const Curve& curve : scene.curves) segment_choice.push_back(flatland::segment_choice(scene, curve));
  }
};

// Arc length from the curve's start to an origin.
double arc_length_of(const Scene& scene, const Curve& curve, const Origin& origin) {
  const std::uint32_t local = origin.segment - curve.first_segment;
  return curve.segment_start[local] + arc_length(scene.segments[origin.segment].geometry.shape, 0.0, origin.t);
}

// The curve parameter u at arc length s.
double parameter_at(const Scene& scene, const Curve& curve, double s) {
  const CurvePoint point = point_at_arc_length(scene, curve, s);
  return point.segment_in_curve + point.t;
}

// Probabilities of `bins` equal bins of arc length under the density f(s) (not normalised), by
// Simpson's rule on 64 panels per bin.
std::vector<double> bin_probabilities(double length, int bins, const std::function<double(double)>& f) {
  std::vector<double> p(static_cast<std::size_t>(bins));
  double total = 0.0;
  const int panels = 64;
  for (int b = 0; b < bins; ++b) {
    const double s0 = length * b / bins;
    const double h = length / bins / panels;
    double sum = 0.0;
    for (int i = 0; i <= panels; ++i) {
      const double w = (i == 0 || i == panels) ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0);
      sum += w * f(s0 + i * h);
    }
    p[static_cast<std::size_t>(b)] = sum * h / 3.0;
    total += p[static_cast<std::size_t>(b)];
  }
  for (double& x : p) x /= total;
  return p;
}

// Draws `n` origins (pseudo-random, or from consecutive Sobol' points whose kPlace coordinate is
// left whole by a single source) and tests their arc-length histogram against `expected`.
void expect_follows(const Scene& scene, const Curve& curve, const std::vector<double>& expected,
                    const std::function<Origin(OriginDraws&)>& sample, bool quasi, const char* what) {
  constexpr int kSamples = 200000;
  const int bins = static_cast<int>(expected.size());
  Rng rng(7, 0, 0);
  const ScrambledSobol sobol(7, 0);
  SobolCursor cursor(sobol);
  std::vector<double> observed(expected.size(), 0.0);
  for (int i = 0; i < kSamples; ++i) {
    OriginDraws draws{rng};
    if (quasi) {
      cursor.seek(static_cast<std::uint32_t>(i));
      draws.point = &cursor;
      draws.place = cursor.sample(kPlace);
    }
    const Origin origin = sample(draws);
    const double s = arc_length_of(scene, curve, origin);
    // The position and tangent are the curve's at (segment, t).
    const Cubic& shape = scene.segments[origin.segment].geometry.shape;
    ASSERT_LT(length(origin.position - evaluate(shape, origin.t)), 1e-12) << what;
    ASSERT_NEAR(dot(origin.tangent, unit_tangent(shape, origin.t, scene.scale)), 1.0, 1e-12) << what;
    const int bin = std::min(bins - 1, static_cast<int>(s / curve.length * bins));
    observed[static_cast<std::size_t>(bin)] += 1.0;
  }
  std::vector<double> counts(expected);
  for (double& c : counts) c *= kSamples;
  // Bins outside the density's support must stay empty; neighbouring bins with small expectations
  // (the support's ends) are merged until each expects at least 20.
  std::vector<double> merged_observed;
  std::vector<double> merged_expected;
  double o = 0.0;
  double e = 0.0;
  for (std::size_t b = 0; b < counts.size(); ++b) {
    if (counts[b] == 0.0) {
      EXPECT_EQ(observed[b], 0.0) << what << ": bin " << b << " lies outside the support";
      continue;
    }
    o += observed[b];
    e += counts[b];
    if (e >= 20.0) {
      merged_observed.push_back(o);
      merged_expected.push_back(e);
      o = e = 0.0;
    }
  }
  if (e > 0.0) {
    merged_observed.back() += o;
    merged_expected.back() += e;
  }
  const int cells = static_cast<int>(merged_expected.size());
  ASSERT_GE(cells, 8) << what;
  EXPECT_LT(testing::chi_square(merged_observed, merged_expected), testing::chi_square_critical(cells - 1))
      << what << (quasi ? " (Sobol')" : " (pseudo-random)");
}

TEST(Origins, UniformFollowsArcLength) {
  Fixture f;
  for (std::uint32_t c = 0; c < 2; ++c) {
    const Curve& curve = f.scene.curves[c];
    const std::vector<double> expected = bin_probabilities(curve.length, 40, [](double) { return 1.0; });
    for (bool quasi : {false, true}) {
      expect_follows(
          f.scene, curve, expected,
          [&](OriginDraws& draws) {
            return sample_uniform_origin(f.scene, curve, f.segment_choice[c], f.line_tangents, draws);
          },
          quasi, curve.id.c_str());
    }
    EXPECT_DOUBLE_EQ(uniform_origin_pdf(curve) * curve.length, 1.0);
  }
}

TEST(Origins, ProfiledFollowsTheEmittance) {
  Fixture f;
  const Curve& curve = f.scene.curves[0];
  auto emittance = [&](double s) { return emittance_factor(curve, parameter_at(f.scene, curve, s)); };
  const std::vector<double> expected = bin_probabilities(curve.length, 40, emittance);
  for (bool quasi : {false, true}) {
    expect_follows(
        f.scene, curve, expected,
        [&](OriginDraws& draws) { return sample_profiled_origin(f.scene, curve, f.segment_choice[0], draws); }, quasi,
        "profile");
  }
  // The Pdf: E(u) over the integral of E ds, here by Simpson's rule on 4096 panels.
  const int panels = 4096;
  double integral = 0.0;
  for (int i = 0; i <= panels; ++i) {
    const double w = (i == 0 || i == panels) ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0);
    integral += w * emittance(curve.length * i / panels);
  }
  integral *= curve.length / panels / 3.0;
  for (double u : {0.1, 0.7, 1.3, 1.9})
    EXPECT_NEAR(profiled_origin_pdf(curve, u), emittance_factor(curve, u) / integral,
                1e-6 * emittance_factor(curve, u) / integral)
        << u;
}

TEST(Origins, CoefficientFollowsItsBasisFunctionInArcLength) {
  Fixture f;
  const Curve& curve = f.scene.curves[0];
  const CurveStorage storage = build_curve_storage(f.scene, curve, BasisKind::Cubic, 6);
  std::vector<Vec2> unused;
  for (std::size_t k : {std::size_t{0}, std::size_t{2}, storage.basis.size() / 2, storage.basis.size() - 1}) {
    auto phi = [&](double s) {
      double values[SplineBasis::kMaxDegree + 1];
      const double u = parameter_at(f.scene, curve, s);
      const std::size_t first = storage.basis.evaluate(u, values);
      return k >= first && k <= first + 3 ? values[k - first] : 0.0;
    };
    // 120 bins: 20 over the shortest support (one element of six).
    const std::vector<double> expected = bin_probabilities(curve.length, 120, phi);
    for (bool quasi : {false, true}) {
      expect_follows(
          f.scene, curve, expected,
          [&](OriginDraws& draws) {
            return sample_coefficient_origin(f.scene, curve, storage, k, f.line_tangents, draws);
          },
          quasi, "coefficient");
    }
    // The Pdf: phi_k per unit arc length over its integral (basis_length, checked against the
    // quadrature here).
    double integral = 0.0;
    const int panels = 4096;
    for (int i = 0; i <= panels; ++i) {
      const double w = (i == 0 || i == panels) ? 1.0 : (i % 2 == 1 ? 4.0 : 2.0);
      integral += w * phi(curve.length * i / panels);
    }
    integral *= curve.length / panels / 3.0;
    EXPECT_NEAR(storage.basis_length[k], integral, 1e-6 * integral) << k;
    for (double s : {0.3, 1.1, 2.0, 3.2}) {
      if (s >= curve.length) continue;
      EXPECT_NEAR(coefficient_origin_pdf(storage, k, parameter_at(f.scene, curve, s)), phi(s) / integral,
                  1e-5 * (1.0 + phi(s) / integral))
          << k << " " << s;
    }
  }
}

TEST(Origins, HermiteFollowsTheReconstruction) {
  Fixture f;
  const Curve& curve = f.scene.curves[0];
  HermiteInput input;
  const double L = curve.length;
  input.u = {0.0, 0.3 * L, 0.55 * L, L};
  input.left = {0.0, 2.0, 0.5, 1.0};
  input.right = {1.0, 2.0, 1.5, 0.0};
  input.continuity = {Continuity::C1, Continuity::C1, Continuity::Jump, Continuity::C1};
  const HermiteReconstruction density(input);
  const std::vector<double> expected =
      bin_probabilities(L, 40, [&](double s) { return density.evaluate(std::min(s, L)); });
  for (bool quasi : {false, true}) {
    expect_follows(
        f.scene, curve, expected,
        [&](OriginDraws& draws) { return sample_hermite_origin(f.scene, curve, density, draws); }, quasi, "hermite");
  }
  for (double s : {0.1 * L, 0.4 * L, 0.9 * L})
    EXPECT_NEAR(hermite_origin_pdf(density, s), density.evaluate(s) / density.integral(), 1e-12) << s;
}

}  // namespace
}  // namespace flatland
