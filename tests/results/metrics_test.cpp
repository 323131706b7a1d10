#include "flatland/results/metrics.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <optional>

namespace flatland {
namespace {

// A result document with one grey curve of length 2 and the given samples of B.
nlohmann::json document(const std::vector<double>& b, const std::string& id = "floor") {
  nlohmann::json samples = nlohmann::json::array();
  for (std::size_t j = 0; j < b.size(); ++j)
    samples.push_back(
        {{"s", (static_cast<double>(j) + 0.5) * 2.0 / static_cast<double>(b.size())}, {"x", 0}, {"y", 0}, {"B", b[j]}});
  return {{"flatland_result", 1}, {"curves", {{{"id", id}, {"length", 2.0}, {"samples", samples}}}}};
}

TEST(Metrics, IdenticalResultsHaveZeroError) {
  const nlohmann::json a = document({1, 2, 3, 4});
  const Result<Comparison> c = compare_results(a, a);
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_EQ(c->scene.l1, 0.0);
  EXPECT_EQ(c->scene.l2, 0.0);
  EXPECT_EQ(c->scene.linf, 0.0);
}

TEST(Metrics, NormsMatchHandComputedValues) {
  // B = R + (0.1, -0.1, 0, 0.2) with R = (1, 2, 3, 4): every cell 0.5 long.
  const Result<Comparison> c = compare_results(document({1.1, 1.9, 3, 4.2}), document({1, 2, 3, 4}));
  ASSERT_TRUE(c.ok());
  EXPECT_NEAR(c->scene.l1, 0.4 / 10.0, 1e-15);
  EXPECT_NEAR(c->scene.l2, std::sqrt(0.06 / 30.0), 1e-15);
  EXPECT_NEAR(c->scene.linf, 0.2 / 4.0, 1e-15);
  // A uniform 10 % excess is 10 % in every norm.
  const Result<Comparison> scaled = compare_results(document({1.1, 2.2, 3.3, 4.4}), document({1, 2, 3, 4}));
  EXPECT_NEAR(scaled->scene.l1, 0.1, 1e-14);
  EXPECT_NEAR(scaled->scene.l2, 0.1, 1e-14);
  EXPECT_NEAR(scaled->scene.linf, 0.1, 1e-14);
}

// Norms are ratios: scaling B and the reference by 1e300 (or 1e-300) changes nothing, although
// the squares of such values overflow (or underflow) a double.
TEST(Metrics, ExtremeMagnitudesGiveTheSameNorms) {
  const Result<Comparison> unit = compare_results(document({1.1, 1.9, 3, 4.2}), document({1, 2, 3, 4}));
  ASSERT_TRUE(unit.ok());
  for (const double scale : {1e300, 1e-300, -1e300}) {
    const Result<Comparison> c = compare_results(document({1.1 * scale, 1.9 * scale, 3 * scale, 4.2 * scale}),
                                                 document({scale, 2 * scale, 3 * scale, 4 * scale}));
    ASSERT_TRUE(c.ok()) << c.error().message;
    EXPECT_NEAR(c->scene.l1, unit->scene.l1, 1e-12) << scale;
    EXPECT_NEAR(c->scene.l2, unit->scene.l2, 1e-12) << scale;
    EXPECT_NEAR(c->scene.linf, unit->scene.linf, 1e-12) << scale;
  }
  // Opposite extremes: the error is finite (2 max|R| at most).
  const Result<Comparison> opposite = compare_results(document({-1e308, -1e308}), document({1e308, 1e308}));
  ASSERT_TRUE(opposite.ok());
  EXPECT_NEAR(opposite->scene.l2, 2.0, 1e-12);
  EXPECT_NEAR(opposite->scene.linf, 2.0, 1e-12);
}

TEST(Metrics, DifferentScenesAreErrors) {
  EXPECT_FALSE(compare_results(document({1, 2}), document({1, 2, 3})).ok());
  EXPECT_FALSE(compare_results(document({1, 2}, "floor"), document({1, 2}, "wall")).ok());
  nlohmann::json longer = document({1, 2});
  longer["curves"][0]["length"] = 3.0;
  EXPECT_FALSE(compare_results(document({1, 2}), longer).ok());
  EXPECT_FALSE(compare_results(nlohmann::json::object(), document({1})).ok());
}

// A curve of length 2 with samples of B and, when `e` is not empty, of the emitted part E.
nlohmann::json curve(const std::string& id, const std::vector<double>& b, const std::vector<double>& e = {},
                     double emittance = 0.0) {
  nlohmann::json samples = nlohmann::json::array();
  for (std::size_t j = 0; j < b.size(); ++j) {
    samples.push_back(
        {{"s", (static_cast<double>(j) + 0.5) * 2.0 / static_cast<double>(b.size())}, {"x", 0}, {"y", 0}, {"B", b[j]}});
    if (!e.empty()) samples.back()["E"] = e[j];
  }
  return {{"id", id}, {"length", 2.0}, {"emittance", emittance}, {"samples", samples}};
}

nlohmann::json scene_of(const std::vector<nlohmann::json>& curves) {
  return {{"flatland_result", 1}, {"curves", curves}};
}

// The reflected part R = (1, 2, 3, 4) under an emitted E = 10, and a result off by
// (0.1, -0.1, 0, 0.2): relative to R the errors are those of NormsMatchHandComputedValues; relative
// to B = E + R = (11, 12, 13, 14) they are (by hand) 0.4 / 50, sqrt(0.06 / 630), 0.2 / 14.
TEST(Metrics, ReflectedPartLeavesTheEmittedLightOut) {
  const std::vector<double> e(4, 10.0);
  const nlohmann::json result = scene_of({curve("lamp", {11.1, 11.9, 13, 14.2}, e, 10.0)});
  const nlohmann::json reference = scene_of({curve("lamp", {11, 12, 13, 14}, e, 10.0)});
  const Result<Comparison> reflected = compare_results(result, reference, Measure::Reflected);
  ASSERT_TRUE(reflected.ok()) << reflected.error().message;
  EXPECT_EQ(reflected->measure, Measure::Reflected);
  EXPECT_NEAR(reflected->scene.l1, 0.4 / 10.0, 1e-14);
  EXPECT_NEAR(reflected->scene.l2, std::sqrt(0.06 / 30.0), 1e-14);
  EXPECT_NEAR(reflected->scene.linf, 0.2 / 4.0, 1e-14);
  EXPECT_TRUE(reflected->curves[0].measured);
  EXPECT_NEAR(reflected->curves[0].norms.l2, std::sqrt(0.06 / 30.0), 1e-14);
  // sqrt(integral R^2 ds), cells 0.5 long: sqrt(30 / 2); and of B: sqrt(630 / 2).
  EXPECT_NEAR(reflected->reference_l2, std::sqrt(15.0), 1e-13);
  const Result<Comparison> total = compare_results(result, reference, Measure::Total);
  ASSERT_TRUE(total.ok());
  EXPECT_NEAR(total->scene.l1, 0.4 / 50.0, 1e-15);
  EXPECT_NEAR(total->scene.l2, std::sqrt(0.06 / 630.0), 1e-15);
  EXPECT_NEAR(total->scene.linf, 0.2 / 14.0, 1e-15);
  EXPECT_NEAR(total->reference_l2, std::sqrt(315.0), 1e-12);
  // The default is the total B, as before (solve --reference, the viewer, the reference's estimate).
  EXPECT_EQ(compare_results(result, reference)->scene.l2, total->scene.l2);
}

// E varies along an emitter with a profile: the samples' own E is subtracted, point by point.
TEST(Metrics, ReflectedPartUsesEachSamplesE) {
  const std::vector<double> e = {10, 20, 30, 40};
  const nlohmann::json result = scene_of({curve("lamp", {11.1, 21.9, 33, 44.2}, e, 1.0)});
  const nlohmann::json reference = scene_of({curve("lamp", {11, 22, 33, 44}, e, 1.0)});
  const Result<Comparison> c = compare_results(result, reference, Measure::Reflected);
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_NEAR(c->scene.l2, std::sqrt(0.06 / 30.0), 1e-14);
  // Colour: E and B per channel; the blue channel has no reflected light, and counts zero.
  nlohmann::json colour = scene_of({curve("lamp", {0, 0}, {}, 0.0)});
  colour["curves"][0]["emittance"] = {1.0, 1.0, 1.0};
  colour["curves"][0]["samples"][0]["B"] = {1.5, 1.25, 1.0};
  colour["curves"][0]["samples"][1]["B"] = {1.5, 1.25, 1.0};
  for (auto& sample : colour["curves"][0]["samples"]) sample["E"] = {1.0, 1.0, 1.0};
  nlohmann::json brighter = colour;
  brighter["curves"][0]["samples"][0]["B"] = {1.55, 1.25, 1.0};
  // Errors (0.05, 0, 0) and (0, 0, 0) over reflected (0.5, 0.25, 0) twice: L1 0.05 / 1.5.
  const Result<Comparison> rgb = compare_results(brighter, colour, Measure::Reflected);
  ASSERT_TRUE(rgb.ok()) << rgb.error().message;
  EXPECT_NEAR(rgb->scene.l1, 0.05 / 1.5, 1e-13);
  EXPECT_NEAR(rgb->scene.linf, 0.05 / 0.5, 1e-13);
}

// A black lamp reflects nothing: it has no relative error of B - E of its own, and adds nothing to
// the scene's, which is the receiver's alone.
TEST(Metrics, ACurveThatReflectsNothingIsUnmeasured) {
  const nlohmann::json lamp = curve("lamp", {5, 5, 5, 5}, {5, 5, 5, 5}, 5.0);
  const nlohmann::json result = scene_of({lamp, curve("floor", {1.1, 1.9, 3, 4.2})});
  const nlohmann::json reference = scene_of({lamp, curve("floor", {1, 2, 3, 4})});
  const Result<Comparison> c = compare_results(result, reference, Measure::Reflected);
  ASSERT_TRUE(c.ok()) << c.error().message;
  EXPECT_FALSE(c->curves[0].measured);
  EXPECT_TRUE(std::isnan(c->curves[0].norms.l2));
  EXPECT_TRUE(c->curves[1].measured);
  EXPECT_NEAR(c->scene.l2, std::sqrt(0.06 / 30.0), 1e-14);
  // B - E at round-off (E computed twice) is no reflected light either.
  nlohmann::json rounded = reference;
  for (auto& sample : rounded["curves"][0]["samples"]) sample["B"] = 5.0 * (1.0 + 4e-16);
  const Result<Comparison> r = compare_results(result, rounded, Measure::Reflected);
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(r->curves[0].measured);
  EXPECT_NEAR(r->scene.l2, std::sqrt(0.06 / 30.0), 1e-14);
  // Under Total the lamp is measured as before.
  EXPECT_TRUE(compare_results(result, reference, Measure::Total)->curves[0].measured);
}

TEST(Metrics, NoReflectedLightAnywhereIsAnError) {
  const nlohmann::json lamps = scene_of({curve("lamp", {5, 5}, {5, 5}, 5.0), curve("dark", {0, 0})});
  const Result<Comparison> c = compare_results(lamps, lamps, Measure::Reflected);
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.error().message.find("B - E is zero everywhere"), std::string::npos) << c.error().message;
  EXPECT_TRUE(compare_results(lamps, lamps, Measure::Total).ok());
}

// E is read from the samples; an emitter without them (an older result) cannot be measured, a curve
// whose emittance is zero or absent needs none.
TEST(Metrics, EmittersNeedTheirE) {
  const nlohmann::json old = scene_of({curve("lamp", {11, 12}, {}, 10.0)});
  const Result<Comparison> c = compare_results(old, old, Measure::Reflected);
  ASSERT_FALSE(c.ok());
  EXPECT_NE(c.error().message.find("\"E\""), std::string::npos) << c.error().message;
  EXPECT_NE(c.error().message.find("lamp"), std::string::npos) << c.error().message;
  // The reference's E serves both documents.
  const nlohmann::json with_e = scene_of({curve("lamp", {11, 12}, {10, 10}, 10.0)});
  const Result<Comparison> mixed = compare_results(old, with_e, Measure::Reflected);
  ASSERT_TRUE(mixed.ok()) << mixed.error().message;
  EXPECT_EQ(mixed->scene.l2, 0.0);
  const Result<Comparison> plain =
      compare_results(document({1.1, 1.9, 3, 4.2}), document({1, 2, 3, 4}), Measure::Reflected);
  ASSERT_TRUE(plain.ok()) << plain.error().message;
  EXPECT_NEAR(plain->scene.l2, std::sqrt(0.06 / 30.0), 1e-15);
}

// Noise-free power laws give their exponent; the fit is least squares on log-log axes.
TEST(Metrics, PowerLawExponentOfExactPowerLaws) {
  for (const double k : {-0.5, -0.75, -4.0 / 9.0, -2.0, 1.0}) {
    std::vector<double> x, y;
    for (const double n : {1e4, 3e4, 1e5, 3e5, 1e6, 1e7, 1e12}) {
      x.push_back(n);
      y.push_back(3.0 * std::pow(n, k));
    }
    const std::optional<double> fitted = power_law_exponent(x, y);
    ASSERT_TRUE(fitted.has_value()) << k;
    EXPECT_NEAR(*fitted, k, 1e-12) << k;
  }
  // Off a line, by hand: ln x = 0, 1, 2 and ln y = 0, -1, -1 give the slope -1 / 2.
  const double e = std::exp(1.0);
  EXPECT_NEAR(*power_law_exponent({1.0, e, e * e}, {1.0, 1.0 / e, 1.0 / e}), -0.5, 1e-14);
  // Several seeds per budget: the fit goes through their log-means, slope -1/2 here.
  EXPECT_NEAR(*power_law_exponent({1e4, 1e4, 1e6, 1e6}, {0.005, 0.02, 0.0005, 0.002}), -0.5, 1e-12);
  // Points with no logarithm are left out; one distinct x determines no line.
  EXPECT_NEAR(*power_law_exponent({0.0, 1e2, 1e4, -1.0}, {1.0, 1e-1, 1e-2, 5.0}), -0.5, 1e-14);
  EXPECT_FALSE(power_law_exponent({1e4, 1e4, 1e4}, {0.1, 0.2, 0.3}).has_value());
  EXPECT_FALSE(power_law_exponent({1e4}, {0.1}).has_value());
  EXPECT_FALSE(power_law_exponent({1e4, 1e5}, {0.0, 0.1}).has_value());
  EXPECT_FALSE(power_law_exponent({}, {}).has_value());
}

}  // namespace
}  // namespace flatland
