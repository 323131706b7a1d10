// The final gather (reference/final_gather.hpp): fed the reference's own element values it is the
// reference; on direct light it is exact; in a closed uniform enclosure its error is at most rho
// times the largest error of what it gathers (the form factors from any point sum to 1); the
// same bits on any thread count; it refuses what the reference refuses, in its own words.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "flatland/reference/final_gather.hpp"
#include "flatland/reference/reference.hpp"
#include "test_support.hpp"

namespace flatland {
namespace {

Solver solved(const Scene& scene, std::uint64_t photons, unsigned threads = 0) {
  SolverSettings settings;
  settings.photons = photons;
  settings.threads = threads;
  settings.tolerance = 1e-6;
  Result<Solver> solver = Solver::create(scene, settings);
  EXPECT_TRUE(solver) << (solver ? "" : solver.error().message);
  solver->run();
  return std::move(*solver);
}

FinalGather made(const Scene& scene, double h, unsigned threads = 0) {
  Result<FinalGather> gather = FinalGather::create(scene, {h, threads, nullptr});
  EXPECT_TRUE(gather) << (gather ? "" : gather.error().message);
  return std::move(*gather);
}

ReferenceSettings elements_of_length(double h) {
  ReferenceSettings settings;
  settings.max_element_length = h;
  return settings;
}

constexpr const char* kRoom = R"({"flatland": 2,
  "materials": {"wall": {"reflectivity": 0.7}, "lamp": {"reflectivity": 0, "emittance": 2},
                "box": {"reflectivity": [0.2, 0.5, 0.8]}},
  "curves": [
    {"id": "walls", "material": "wall", "line": [[0, 0], [3, 0], [3, 2], [0, 2], [0, 0]]},
    {"id": "lamp", "material": "lamp", "line": [[1.8, 1.9], [1.2, 1.9]]},
    {"id": "box", "material": "box", "bezier": [[1, 0], [1, 0.8], [2, 0.8], [2, 0]]}]})";

// Fed the reference's element radiosities, the gather's elements give back the reference's own
// final gather, bit for bit: the same elements, sweep and sum.
TEST(FinalGather, OfTheReferencesElementValuesIsTheReference) {
  const Scene scene = testing::scene_from_text(kRoom);
  ReferenceSettings settings;
  settings.max_element_length = 0.05;
  Result<ReferenceSolution> reference = solve_reference(scene, settings);
  ASSERT_TRUE(reference) << reference.error().message;
  Result<ReferenceSolution> elements = reference_elements(scene, settings, "a final gather", "");
  ASSERT_TRUE(elements) << elements.error().message;
  ASSERT_EQ(elements->elements(), reference->elements());
  std::array<std::vector<double>, 3> b;
  for (int c = 0; c < scene.channels; ++c)
    for (std::uint32_t j = 0; j < reference->elements(); ++j)
      for (const Side side : {Side::Front, Side::Back})
        b[static_cast<std::size_t>(c)].push_back(reference->element_radiosity(j, side)[static_cast<std::size_t>(c)]);
  elements->set_element_radiosity(b);
  for (std::uint32_t curve = 0; curve < scene.curves.size(); ++curve)
    for (const double u : {0.0, 0.13, 0.5, 0.77, 1.0}) {
      const double at = u * scene.curves[curve].segment_count;
      const Spectrum expected = reference->radiosity(curve, Side::Front, at);
      const Spectrum got = elements->radiosity(curve, Side::Front, at);
      for (int c = 0; c < scene.channels; ++c)
        EXPECT_EQ(got[static_cast<std::size_t>(c)], expected[static_cast<std::size_t>(c)])
            << scene.curves[curve].id << " u " << at;
    }
}

// The penumbra scene's receiver sees only the emitter (B - E is all direct light), so the gather
// of any solution is the reference's final gather: the Monte Carlo noise is gone entirely.
TEST(FinalGather, DirectLightCarriesNoNoise) {
  const Scene scene = testing::scene_from_file("scenes2d/penumbra.json");
  ReferenceSettings settings;
  settings.max_element_length = scene.scale / 100.0;
  Result<ReferenceSolution> reference = solve_reference(scene, settings);
  ASSERT_TRUE(reference) << reference.error().message;
  const Solver solver = solved(scene, 20'000);
  const FinalGather gather = made(scene, settings.max_element_length);
  const SampledResult result = gather.gather_result(solver, 40);
  double largest = 0.0;
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c)
    for (const ResultSample& sample : result.curves[c].samples) largest = std::max(largest, sample.B[0]);
  ASSERT_GT(largest, 0.0);
  const SampledResult exact = sample_radiosity(
      scene, 40, [&](std::uint32_t c, Side side, double u) { return reference->radiosity(c, side, u); });
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c)
    for (std::size_t j = 0; j < exact.curves[c].samples.size(); ++j)
      EXPECT_NEAR(result.curves[c].samples[j].B[0], exact.curves[c].samples[j].B[0], 1e-12 * largest)
          << scene.curves[c].id << " sample " << j;
  ASSERT_TRUE(result.stats && result.stats->estimated_error);
  EXPECT_EQ(result.final_gather, settings.max_element_length);
}

// In a closed enclosure the form factors from any point sum to 1, so B_g - B = rho sum_j F_j
// (b_j - B): the gathered error is at most rho times the largest error of the element values,
// whatever the noise. (The element values are the solution's B at the elements' midpoints, which
// the dense samples below include.)
TEST(FinalGather, EnclosureErrorAtMostRhoTimesTheLargestGathered) {
  const double rho = 0.5;
  const Scene scene = testing::scene_from_text(testing::circle_enclosure(rho, 1.0));
  const Solver solver = solved(scene, 20'000);
  const double h = 0.05;
  const FinalGather gather = made(scene, h);
  Result<ReferenceSolution> elements = reference_elements(scene, elements_of_length(h), "a final gather", "");
  ASSERT_TRUE(elements);
  double largest = 0.0;  // of the values gathered
  for (const ReferenceElement& e : elements->element_list())
    largest = std::max(largest, std::fabs(solver.radiosity(0, Side::Front, e.u_mid)[0] - 2.0));
  ASSERT_GT(largest, 1e-6) << "a solve of 2e4 photons is not exact";
  const SampledResult result = gather.gather_result(solver, 200);
  double gathered = 0.0;
  for (const ResultSample& sample : result.curves[0].samples)
    gathered = std::max(gathered, std::fabs(sample.B[0] - 2.0));
  EXPECT_LE(gathered, rho * largest * (1.0 + 1e-9));
  EXPECT_LT(gathered, 0.5 * largest);
}

// The weights are found per point, each on its own: the same bits on one thread and on two.
TEST(FinalGather, SameBitsOnAnyThreadCount) {
  const Scene scene = testing::scene_from_text(kRoom);
  const Solver solver = solved(scene, 20'000, 1);
  const SampledResult one = made(scene, 0.05, 1).gather_result(solver, 30);
  const SampledResult two = made(scene, 0.05, 2).gather_result(solver, 30);
  for (std::size_t c = 0; c < one.curves.size(); ++c)
    for (std::size_t j = 0; j < one.curves[c].samples.size(); ++j)
      for (std::size_t ch = 0; ch < 3; ++ch)
        EXPECT_EQ(std::bit_cast<std::uint64_t>(one.curves[c].samples[j].B[ch]),
                  std::bit_cast<std::uint64_t>(two.curves[c].samples[j].B[ch]));
  EXPECT_EQ(one.stats->estimated_error->bound.l1, two.stats->estimated_error->bound.l1);
}

// The bound of a gathered result has the gather's own part (elements of h against 2h), and its
// noise part is the gathered replicates' spread, below the storage's own.
TEST(FinalGather, EstimateHasTheGathersParts) {
  const Scene scene = testing::scene_from_text(kRoom);
  const Solver solver = solved(scene, 50'000);
  const SampledResult result = made(scene, 0.05).gather_result(solver, 50);
  const ErrorEstimate& gathered = *result.stats->estimated_error;
  const ErrorEstimate plain = estimate_error(solver, {0.95, 50});
  ASSERT_TRUE(gathered.available && plain.available);
  EXPECT_GT(gathered.gather.l1, 0.0);
  EXPECT_EQ(plain.gather.l1, 0.0);
  EXPECT_LT(gathered.noise.l1, plain.noise.l1);
}

TEST(FinalGather, RefusesWhatTheReferenceRefusesInItsOwnWords) {
  const Scene scene = testing::scene_from_file("scenes2d/prism.json");
  Result<FinalGather> gather = FinalGather::create(scene, {});
  ASSERT_FALSE(gather);
  EXPECT_NE(gather.error().message.find("a final gather handles diffuse surfaces"), std::string::npos)
      << gather.error().message;
  EXPECT_NE(gather.error().message.find("--gather none"), std::string::npos);
  EXPECT_EQ(gather.error().message.find("reference solver"), std::string::npos);
}

}  // namespace
}  // namespace flatland

namespace flatland {
namespace {

// --gather auto gathers where it can at a bounded cost, and says why not elsewhere; samples
// refuses what it cannot gather; none never gathers.
TEST(FinalGather, AutoGathersWhereItCanAndSaysWhyNot) {
  const Scene room = testing::scene_from_text(kRoom);
  const Scene prism = testing::scene_from_file("scenes2d/prism.json");
  SolverSettings settings;
  ASSERT_EQ(settings.gather, GatherMode::Auto) << "the default";
  Result<GatherChoice> chosen = choose_gather(room, settings, 100);
  ASSERT_TRUE(chosen);
  EXPECT_NE(chosen->gather, nullptr);
  EXPECT_TRUE(chosen->skipped.empty());
  chosen = choose_gather(prism, settings, 100);
  ASSERT_TRUE(chosen);
  EXPECT_EQ(chosen->gather, nullptr);
  EXPECT_NE(chosen->skipped.find("'prism' (dielectric)"), std::string::npos) << chosen->skipped;
  EXPECT_EQ(chosen->skipped.find("--gather none"), std::string::npos) << "auto says why, not what to type";
  // A million samples per curve would sweep far more than auto allows at once.
  chosen = choose_gather(room, settings, 1'000'000);
  ASSERT_TRUE(chosen);
  EXPECT_EQ(chosen->gather, nullptr);
  EXPECT_NE(chosen->skipped.find("--gather samples gathers all the same"), std::string::npos) << chosen->skipped;
  settings.gather = GatherMode::Samples;
  EXPECT_FALSE(choose_gather(prism, settings, 100));
  chosen = choose_gather(room, settings, 1'000'000);
  ASSERT_TRUE(chosen);
  EXPECT_NE(chosen->gather, nullptr);
  settings.gather = GatherMode::None;
  chosen = choose_gather(room, settings, 100);
  ASSERT_TRUE(chosen);
  EXPECT_EQ(chosen->gather, nullptr);
  EXPECT_TRUE(chosen->skipped.empty());
}

}  // namespace
}  // namespace flatland
