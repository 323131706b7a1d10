// flatland/sampled_result: a result as data, and its JSON edge.
#include "flatland/results/sampled_result.hpp"

#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include "flatland/results/metrics.hpp"
#include "flatland/results/result_io.hpp"
#include "test_support.hpp"

namespace flatland {
namespace {

Solver solved(const Scene& scene, std::uint64_t seed, std::uint64_t photons = 50'000) {
  SolverSettings settings;
  settings.photons = photons;
  settings.seed = seed;
  Result<Solver> solver = Solver::create(scene, settings);
  EXPECT_TRUE(solver.ok());
  solver->run();
  return std::move(solver).value();
}

void expect_same_spectrum(const Spectrum& a, const Spectrum& b, int channels) {
  for (int ch = 0; ch < channels; ++ch) EXPECT_EQ(a[static_cast<std::size_t>(ch)], b[static_cast<std::size_t>(ch)]);
}

// The samples are the solver's radiosity at the sample points, E the emittance there, and the
// spline the solver's storage; the document result_to_json writes holds exactly these curves.
TEST(SampledResult, SolverResultsHoldTheSolversNumbers) {
  // Colour, two-sided curves, an emitter (default), and a grey scene of cubics (curved room).
  for (const char* file : {"scenes2d/default.json", "scenes2d/curved_room.json"}) {
    SCOPED_TRACE(file);
    const Scene scene = testing::scene_from_file(file);
    const Solver solver = solved(scene, 3);
    const SampledResult result = sample_solver(solver, 7);
    EXPECT_EQ(result.channels, scene.channels);
    ASSERT_EQ(result.curves.size(), scene.curves.size());
    for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
      const Curve& curve = scene.curves[c];
      const ResultCurve& out = result.curves[c];
      EXPECT_EQ(out.id, curve.id);
      EXPECT_EQ(out.length, curve.length);
      ASSERT_EQ(out.samples.size(), 7u);
      for (std::size_t j = 0; j < out.samples.size(); ++j) {
        const ResultSample& sample = out.samples[j];
        EXPECT_DOUBLE_EQ(sample.s, (static_cast<double>(j) + 0.5) * curve.length / 7.0);
        const CurvePoint point = point_at_arc_length(scene, curve, sample.s);
        EXPECT_EQ(sample.x, point.position.x);
        const Side main = curve.sides == Sides::Back ? Side::Back : Side::Front;
        expect_same_spectrum(sample.B, solver.radiosity(c, main, point.u), scene.channels);
        EXPECT_EQ(sample.B_back.has_value(), curve.sides == Sides::Both);
        if (sample.B_back) {
          expect_same_spectrum(*sample.B_back, solver.radiosity(c, Side::Back, point.u), scene.channels);
        }
        EXPECT_EQ(sample.E.has_value(), scene.is_emitter(curve));
      }
      ASSERT_TRUE(out.spline.has_value());
      EXPECT_EQ(out.spline->knots, solver.storage(c).basis.knots());
      EXPECT_EQ(out.spline->coefficients,
                solver.radiosity_coefficients(c, curve.sides == Sides::Back ? Side::Back : Side::Front));
    }
    ASSERT_TRUE(result.stats.has_value());
    EXPECT_EQ(result.stats->photons, solver.photons_shot());
    EXPECT_EQ(result.stats->rounds, solver.rounds());
    EXPECT_EQ(result.stats->books.emitted, solver.books().emitted);
    const nlohmann::json document = result_to_json(solver, 7);
    EXPECT_EQ(document["curves"], curves_to_json(result));
    EXPECT_EQ(document["stats"], stats_to_json(*result.stats));
  }
}

// Written and read back, the samples come back bit for bit (JSON numbers round-trip doubles).
TEST(SampledResult, JsonRoundTripKeepsEverySample) {
  for (const char* file : {"scenes2d/default.json", "scenes2d/penumbra.json"}) {
    SCOPED_TRACE(file);
    const Scene scene = testing::scene_from_file(file);
    const SampledResult written = sample_solver(solved(scene, 5), 11);
    const nlohmann::json document = nlohmann::json::parse(json_text(result_to_json(solved(scene, 5), 11)));
    const Result<SampledResult> read = sampled_from_json(document, "the result");
    ASSERT_TRUE(read.ok()) << read.error().message;
    EXPECT_EQ(read->channels, written.channels);
    ASSERT_EQ(read->curves.size(), written.curves.size());
    for (std::size_t c = 0; c < written.curves.size(); ++c) {
      const ResultCurve& a = written.curves[c];
      const ResultCurve& b = read->curves[c];
      EXPECT_EQ(b.id, a.id);
      EXPECT_EQ(b.length, a.length);
      EXPECT_EQ(b.sides, a.sides);
      EXPECT_EQ(b.segments, a.segments);
      ASSERT_TRUE(b.emittance.has_value());
      expect_same_spectrum(*b.emittance, *a.emittance, written.channels);
      ASSERT_EQ(b.samples.size(), a.samples.size());
      for (std::size_t j = 0; j < a.samples.size(); ++j) {
        EXPECT_EQ(b.samples[j].s, a.samples[j].s);
        EXPECT_EQ(b.samples[j].y, a.samples[j].y);
        expect_same_spectrum(b.samples[j].B, a.samples[j].B, written.channels);
        EXPECT_EQ(b.samples[j].B_back.has_value(), a.samples[j].B_back.has_value());
        EXPECT_EQ(b.samples[j].E.has_value(), a.samples[j].E.has_value());
        if (a.samples[j].E && b.samples[j].E) expect_same_spectrum(*b.samples[j].E, *a.samples[j].E, written.channels);
      }
    }
  }
}

// Comparing the data gives the numbers comparing the documents gives, under both measures.
TEST(SampledResult, ComparisonOfDataEqualsComparisonOfDocuments) {
  const Scene scene = testing::scene_from_file("scenes2d/default.json");
  const Solver a = solved(scene, 1);
  const Solver b = solved(scene, 2, 200'000);
  for (const Measure measure : {Measure::Total, Measure::Reflected}) {
    const Result<Comparison> data = compare_sampled(sample_solver(a, 40), sample_solver(b, 40), measure);
    const Result<Comparison> documents = compare_results(result_to_json(a, 40), result_to_json(b, 40), measure);
    ASSERT_TRUE(data.ok()) << data.error().message;
    ASSERT_TRUE(documents.ok()) << documents.error().message;
    EXPECT_GT(data->scene.l2, 0.0);
    EXPECT_EQ(data->scene.l1, documents->scene.l1);
    EXPECT_EQ(data->scene.l2, documents->scene.l2);
    EXPECT_EQ(data->scene.linf, documents->scene.linf);
    ASSERT_EQ(data->curves.size(), documents->curves.size());
    for (std::size_t c = 0; c < data->curves.size(); ++c) {
      EXPECT_EQ(data->curves[c].measured, documents->curves[c].measured);
      if (data->curves[c].measured) {
        EXPECT_EQ(data->curves[c].norms.l2, documents->curves[c].norms.l2);
      }
    }
  }
}

// Documents that are not results, or whose values are malformed, are one-line errors naming the
// place; nothing throws.
TEST(SampledResult, MalformedDocumentsAreErrors) {
  auto error_of = [](const nlohmann::json& document) {
    const Result<SampledResult> r = sampled_from_json(document, "the reference", " (reference)");
    return r.ok() ? std::string("accepted") : r.error().message;
  };
  EXPECT_NE(error_of(nlohmann::json::array()).find("the reference is not a flatland result"), std::string::npos);
  const nlohmann::json sample = {{"s", 0.5}, {"B", 1.0}};
  const nlohmann::json good = {{"flatland_result", 1},
                               {"curves", {{{"id", "floor"}, {"length", 1.0}, {"samples", {sample}}}}}};
  EXPECT_EQ(error_of(good), "accepted");
  nlohmann::json no_length = good;
  no_length["curves"][0].erase("length");
  EXPECT_NE(error_of(no_length).find("malformed result"), std::string::npos);
  nlohmann::json mixed = good;
  mixed["curves"][0]["samples"].push_back({{"s", 0.7}, {"B", {1.0, 2.0, 3.0}}});
  EXPECT_NE(error_of(mixed).find("curves[0] (\"floor\").samples[1].B (reference): a colour value in a grey result"),
            std::string::npos)
      << error_of(mixed);
  nlohmann::json text = good;
  text["curves"][0]["samples"][0]["B"] = "bright";
  EXPECT_NE(error_of(text).find("expected a number or [r, g, b]"), std::string::npos);
  // In a colour document whose first B is malformed, that B is named, not the curve's emittance
  // read as grey before it (the channels come from the first B that is a number or an array).
  nlohmann::json colour = good;
  colour["curves"][0]["emittance"] = {1.0, 0.5, 0.25};
  colour["curves"][0]["samples"] = {{{"s", 0.3}, {"B", "bright"}}, {{"s", 0.7}, {"B", {1.0, 2.0, 3.0}}}};
  EXPECT_NE(error_of(colour).find("samples[0].B (reference): expected a number or [r, g, b]"), std::string::npos)
      << error_of(colour);
  // Found by fuzz_result (fuzz/corpus/result/regression-segments-beyond-int.json): a segment count
  // beyond an int was converted anyway (undefined behaviour).
  for (const nlohmann::json& count :
       {nlohmann::json(11e100), nlohmann::json(-1), nlohmann::json(2.5), nlohmann::json("4")}) {
    nlohmann::json segments = good;
    segments["curves"][0]["segments"] = count;
    EXPECT_NE(error_of(segments).find(".segments: expected a whole number"), std::string::npos) << error_of(segments);
  }
  nlohmann::json no_b = good;
  no_b["curves"][0]["samples"][0].erase("B");
  EXPECT_NE(error_of(no_b).find("malformed result"), std::string::npos);
}

}  // namespace
}  // namespace flatland
