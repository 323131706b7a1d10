// Importance toward a region of interest (importance.hpp, and the Solver's plan of important
// sources): the region's curves, the adjoint scene, the side importance against form factors, the
// region's expectation and variance, the books, the power no photon took, and determinism.
#include "flatland/transport/importance.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/transport/solver.hpp"
#include "test_support.hpp"

namespace flatland {
namespace {

using testing::make_solver;

std::uint32_t curve_index(const Scene& scene, const std::string& id) {
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c)
    if (scene.curves[c].id == id) return c;
  ADD_FAILURE() << "no curve " << id;
  return 0;
}

// L_P F_PQ for two segments that see each other whole: Hottel's crossed strings, half the
// crossed strings' lengths less the uncrossed ones'.
double crossed_strings(Vec2 p1, Vec2 p2, Vec2 q1, Vec2 q2) {
  return 0.5 * std::fabs((length(p1 - q2) + length(p2 - q1)) - (length(p1 - q1) + length(p2 - q2)));
}

TEST(Importance, CurvesAreNamedByTheirIdsAndMustHoldLight) {
  const Scene rooms = testing::scene_from_file("scenes2d/row_of_rooms.json");
  SolverSettings settings;
  settings.importance = {"desk", "floor_1"};
  Result<std::vector<std::uint32_t>> region = importance_curves(rooms, settings);
  ASSERT_TRUE(region) << region.error().message;
  EXPECT_EQ(*region, (std::vector<std::uint32_t>{curve_index(rooms, "desk"), curve_index(rooms, "floor_1")}));

  // A lamp that reflects nothing has B = E exactly: nothing to make accurate.
  settings.importance = {"desk", "lamp_1"};
  region = importance_curves(rooms, settings);
  ASSERT_FALSE(region);
  EXPECT_NE(region.error().message.find("importance: curve 'lamp_1' reflects no light"), std::string::npos)
      << region.error().message;

  settings.importance = {"dsk"};
  region = importance_curves(rooms, settings);
  ASSERT_FALSE(region);
  EXPECT_EQ(region.error().message, "importance: " + rooms.source + " has no curve 'dsk'; did you mean 'desk'?");

  const Scene mirrors = testing::scene_from_file("scenes2d/mirror_room.json");
  settings.importance = {"mirror"};
  region = importance_curves(mirrors, settings);
  ASSERT_FALSE(region);
  EXPECT_NE(region.error().message.find("importance: curve 'mirror' keeps no diffuse light"), std::string::npos)
      << region.error().message;
  // Solver::create refuses them before any work, and walks refuse importance at all.
  EXPECT_FALSE(Solver::create(mirrors, settings).ok());
  settings.importance = {"walls"};
  settings.transport = Transport::Walk;
  const Status walks = validate(settings);
  ASSERT_FALSE(walks);
  EXPECT_EQ(walks.error().message.rfind("importance: ", 0), 0u);
  EXPECT_NE(walks.error().message.find("use transport shooting"), std::string::npos);
  // Nor do Jacobi iterations, which keep no pool between them.
  settings.transport = Transport::Jacobi;
  const Status jacobi = validate(settings);
  ASSERT_FALSE(jacobi);
  EXPECT_EQ(jacobi.error().message.rfind("importance: ", 0), 0u);
  EXPECT_NE(jacobi.error().message.find("use transport shooting"), std::string::npos);
}

TEST(Importance, TheAdjointSceneLightsTheRegionAlone) {
  const Scene scene = testing::scene_from_file("scenes2d/row_of_rooms.json");
  const std::uint32_t desk = curve_index(scene, "desk");
  const Scene adjoint = adjoint_scene(scene, {desk});
  ASSERT_EQ(adjoint.curves.size(), scene.curves.size());
  for (std::uint32_t c = 0; c < adjoint.curves.size(); ++c) {
    const Curve& curve = adjoint.curves[c];
    const Material& material = adjoint.material_of(curve);
    EXPECT_EQ(adjoint.is_emitter(curve), c == desk) << curve.id;
    // Reflectivities as they were, but none below the tally's 1e-9 (the lamps reflect nothing).
    const double rho = scene.material_of(scene.curves[c]).reflectivity[0];
    EXPECT_EQ(material.reflectivity[0], std::max(rho, 1e-9)) << curve.id;
  }
  EXPECT_EQ(adjoint.curves[desk].emittance[0], 1.0);
  EXPECT_EQ(adjoint.material_of(adjoint.curves[desk]).emission.kind, Emission::Kind::Diffuse);
  // The desk's front (its only side) emits an emittance of 1 over its length.
  EXPECT_NEAR(adjoint.emitted_power(), scene.curves[desk].length, 1e-12);
}

// A sixteenth of the budget within [2^14, 2^20], the least with a target error (a cap's sixteenth
// could be far more than the solve shoots).
TEST(Importance, TheAdjointSolveTakesASixteenthOfTheBudget) {
  SolverSettings settings;
  settings.photons = 1'000'000;
  EXPECT_EQ(importance_photons(settings), 62'500u);
  settings.photons = 1'000;
  EXPECT_EQ(importance_photons(settings), 16'384u);
  settings.photons = 1'000'000'000;
  EXPECT_EQ(importance_photons(settings), 1'048'576u);
  settings.target_error = 1e-3;
  EXPECT_EQ(importance_photons(settings), 16'384u);
}

// Three black plates in the open: the region A at y = 0 facing up, B1 above it facing down and B2
// beside B1 (the scene's lamp, far off and facing away, is dark in the adjoint). With A glowing, B receives L_A F_AB =
// L_B F_BA, so W_B = F_BA: the share of B's power that reaches A. The adjoint solve tallies B's hits of its 2^20
// photons (p = F_AB of them), with a relative standard deviation below sqrt((1 - p) / (N p)) (independent photons; the
// Sobol' net does better); the ratio W_B2 / W_B1 is held to 5 of those, combined.
TEST(Importance, SideImportanceIsTheFormFactorToTheRegion) {
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 2,
    "materials": {"black": {"reflectivity": 0.0}, "lamp": {"emittance": 1.0}},
    "curves": [
      {"id": "a", "material": "black", "line": [[0, 0], [1, 0]]},
      {"id": "b1", "material": "black", "line": [[1, 1], [0, 1]]},
      {"id": "b2", "material": "black", "line": [[3, 1], [2, 1]]},
      {"id": "lamp", "material": "lamp", "line": [[50, 50], [51, 50]]}]})");
  SolverSettings settings;
  settings.importance = {"a"};
  const std::uint64_t photons = std::uint64_t{1} << 20;
  Result<ImportanceSolve> solve = solve_importance(scene, {0}, settings, photons, nullptr);
  ASSERT_TRUE(solve) << solve.error().message;
  const std::vector<double>& w = solve->side_importance;
  ASSERT_EQ(w.size(), 8u);
  const double g1 = crossed_strings({0, 0}, {1, 0}, {1, 1}, {0, 1});
  const double g2 = crossed_strings({0, 0}, {1, 0}, {3, 1}, {2, 1});
  ASSERT_GT(g1, g2);
  // Relative to the largest: B1's is 1, B2's the ratio; A sees none of its own light (bar the
  // tally's 1e-9 reflections). The weights are their square roots, A's held to the floor.
  EXPECT_EQ(w[2], 1.0);
  const double n = static_cast<double>(photons);
  const double s1 = std::sqrt((1.0 - g1) / (n * g1));
  const double s2 = std::sqrt((1.0 - g2) / (n * g2));
  EXPECT_NEAR(w[4], g2 / g1, 5.0 * std::hypot(s1, s2) * g2 / g1);
  EXPECT_LT(w[0], 1e-8);
  EXPECT_EQ(w[1], 0.0);  // back sides hold no light
  const std::vector<double>& weight = solve->side_weight;
  ASSERT_EQ(weight.size(), 8u);
  EXPECT_EQ(weight[2], 1.0);
  EXPECT_EQ(weight[4], std::sqrt(w[4]));
  EXPECT_EQ(weight[0], kImportanceFloor);
  EXPECT_EQ(weight[1], 0.0);
  EXPECT_EQ(solve->photons, photons);
}

// Two rooms with black walls and floors: the desk's top is lit by the left lamp alone (the
// partition hides the bright lamp), so the power on it is E L F by crossed strings. The weight is
// 1 for the left lamp and the floor, 1/64, for the bright one: about 94 % of the photons leave
// the left lamp instead of 20 %, and the variance of the top's power falls to about a fifth. Over
// 16 seeds each, both means lie within 4 standard errors of the closed form, and the variance with
// importance is below the variance without (at a true ratio of about 0.2, an F(15, 15) ratio
// above 1 has a chance below 0.1 %).
TEST(Importance, TheRegionKeepsItsExpectationAndLosesVariance) {
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 2,
    "materials": {
      "black": {"reflectivity": 0.0},
      "lamp": {"reflectivity": 0.0, "emittance": 1.0},
      "bright": {"reflectivity": 0.0, "emittance": 4.0},
      "desk": {"reflectivity": 0.5}},
    "curves": [
      {"id": "floor", "material": "black", "line": [[0, 0], [9, 0]]},
      {"id": "walls", "material": "black", "line": [[9, 0], [9, 3], [0, 3], [0, 0]]},
      {"id": "partition", "material": "black", "sides": "both", "line": [[4.5, 0.9], [4.5, 3]]},
      {"id": "lamp", "material": "lamp", "line": [[2.6, 2.8], [1.9, 2.8]]},
      {"id": "bright", "material": "bright", "line": [[7.1, 2.8], [6.4, 2.8]]},
      {"id": "desk", "material": "desk", "line": [[0.6, 0], [0.6, 0.75], [1.8, 0.75], [1.8, 0]]}]})");
  const std::uint32_t desk = curve_index(scene, "desk");
  const double exact = 1.0 * crossed_strings({2.6, 2.8}, {1.9, 2.8}, {0.6, 0.75}, {1.8, 0.75});
  const auto top_power = [&](bool importance, std::uint64_t seed) {
    SolverSettings settings;
    settings.photons = 20'000;
    settings.seed = seed;
    settings.basis = BasisKind::Constant;
    settings.estimator = Estimator::Lumped;
    settings.elements = 1;  // one element a segment: the top is coefficient 1
    settings.sampler = SamplerKind::Random;
    if (importance) settings.importance = {"desk"};
    Solver solver = make_solver(scene, settings);
    solver.run();
    EXPECT_NE(solver.stop_reason(), StopReason::BooksUnbalanced);
    const std::vector<double> b = solver.radiosity_coefficients(desk, Side::Front);
    EXPECT_EQ(b.size(), 3u);
    return b.size() == 3 ? b[1] * 1.2 / 0.5 : 0.0;  // b = rho H / L
  };
  constexpr int kSeeds = 16;
  double mean[2] = {};
  double variance[2] = {};
  for (int with = 0; with < 2; ++with) {
    std::vector<double> values;
    for (int seed = 1; seed <= kSeeds; ++seed) values.push_back(top_power(with == 1, static_cast<std::uint64_t>(seed)));
    for (double v : values) mean[with] += v / kSeeds;
    for (double v : values) variance[with] += (v - mean[with]) * (v - mean[with]) / (kSeeds - 1);
    EXPECT_NEAR(mean[with], exact, 4.0 * std::sqrt(variance[with] / kSeeds)) << (with ? "importance" : "none");
  }
  EXPECT_LT(variance[1], variance[0]);
  EXPECT_GT(variance[1], 0.0);
}

// A lamp of 1e-7 the power of the other, far from the region: no photon of the first round
// would choose it (its share of the choice is about 1e-9). Kept, its light would later leave as
// reflected light, so that round is planned without importance, as shooting always plans it:
// the faint lamp's power leaves the pool with the round.
TEST(Importance, ARoundOfEmittedLightKeepsNothing) {
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 2,
    "materials": {
      "wall": {"reflectivity": 0.5},
      "lamp": {"reflectivity": 0.0, "emittance": 1.0},
      "faint": {"reflectivity": 0.0, "emittance": 1e-7}},
    "curves": [
      {"id": "floor", "material": "wall", "line": [[0, 0], [4, 0]]},
      {"id": "lamp", "material": "lamp", "line": [[1.5, 2], [0.5, 2]]},
      {"id": "faint", "material": "faint", "line": [[40, 30], [39, 30]]}]})");
  SolverSettings settings;
  settings.photons = 50'000;
  settings.basis = BasisKind::Constant;
  settings.elements = 1;
  settings.importance = {"floor"};
  Solver solver = make_solver(scene, settings);
  ASSERT_TRUE(solver.step_round());
  const std::vector<double> unshot = solver.unshot_coefficients(curve_index(scene, "faint"), Side::Front);
  ASSERT_EQ(unshot.size(), 1u);
  EXPECT_EQ(unshot[0], 0.0);
  EXPECT_NEAR(solver.books().imbalance(), 0.0, 1e-12 * solver.books().emitted);
}

// A tall wall far to the left takes a few per cent of the lamp's light in the first round, but
// hardly any of its own light reaches the floor (the region): its weight is the floor's 1/64, and
// in the second round of 256 photons it often draws none. Then its unshot power must still be in
// the pool after that round (what it kept, plus rho times what it received). Over 16 seeds, some
// second rounds leave it out (checked: the test would be empty otherwise), and every such round
// keeps its power; the books balance throughout.
TEST(Importance, PowerNoPhotonTookStaysInThePool) {
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 2,
    "materials": {
      "floor": {"reflectivity": 0.5},
      "wall": {"reflectivity": 0.8},
      "lamp": {"reflectivity": 0.0, "emittance": 1.0}},
    "curves": [
      {"id": "floor", "material": "floor", "line": [[0, 0], [2, 0]]},
      {"id": "side", "material": "wall", "line": [[2.5, 0], [2.5, 2]]},
      {"id": "lamp", "material": "lamp", "line": [[1.5, 2], [0.5, 2]]},
      {"id": "far", "material": "wall", "line": [[-300, 100], [-300, -100]]}]})");
  const std::uint32_t far = curve_index(scene, "far");
  // The far wall's unshot power: its unshot radiosity times each element's length.
  const auto unshot_power = [&](const Solver& solver) {
    const std::vector<double> unshot = solver.unshot_coefficients(far, Side::Front);
    const std::vector<double>& lengths = solver.storage(far).basis_length;
    EXPECT_EQ(unshot.size(), lengths.size());
    double power = 0.0;
    for (std::size_t k = 0; k < unshot.size() && k < lengths.size(); ++k) power += unshot[k] * lengths[k];
    return power;
  };
  int left_out = 0;
  for (std::uint64_t seed = 1; seed <= 16; ++seed) {
    SolverSettings settings;
    settings.photons = 2'000;
    settings.seed = seed;
    settings.basis = BasisKind::Constant;
    settings.estimator = Estimator::Lumped;
    settings.elements = 1;
    settings.importance = {"floor"};
    Solver solver = make_solver(scene, settings);
    ASSERT_TRUE(solver.step_round());
    const double before = unshot_power(solver);
    ASSERT_GT(before, 0.0) << seed;
    // The second round, whole, with its paths: one photon opens it and tells its size.
    std::vector<PhotonPath> paths;
    ASSERT_EQ(solver.step_photons(1, nullptr, &paths, std::size_t{1} << 20), 1u);
    const std::uint64_t round = solver.round_photons();
    ASSERT_GT(round, 1u);
    ASSERT_EQ(solver.step_photons(round - 1, nullptr, &paths, std::size_t{1} << 20), round - 1);
    ASSERT_EQ(solver.rounds(), 2u);
    int from_far = 0;
    for (const PhotonPath& path : paths) from_far += path.source_curve == far ? 1 : 0;
    const EnergyBooks books = solver.books();
    EXPECT_NEAR(books.imbalance(), 0.0, 1e-12 * books.emitted) << seed;
    if (from_far > 0) continue;
    ++left_out;
    const double after = unshot_power(solver);
    EXPECT_GE(after, before * (1.0 - 1e-12)) << seed;
  }
  EXPECT_GT(left_out, 0);
}

TEST(Importance, SameBitsOnAnyThreadCountAndInSteps) {
  const Scene scene = testing::scene_from_file("scenes2d/row_of_rooms.json");
  SolverSettings settings;
  settings.photons = 100'000;
  settings.seed = 5;
  settings.importance = {"desk", "floor_1"};
  std::vector<testing::SolutionData> dumps;
  for (unsigned threads : {1u, 2u, 3u}) {
    settings.threads = threads;
    Solver solver = make_solver(scene, settings);
    solver.run();
    dumps.push_back(testing::solution_data(solver));
  }
  EXPECT_EQ(dumps[0], dumps[1]);
  EXPECT_EQ(dumps[0], dumps[2]);
  settings.threads = 2;
  Solver stepped = make_solver(scene, settings);
  while (stepped.step_photons(777) > 0) {
  }
  EXPECT_EQ(testing::solution_data(stepped), dumps[0]);
  // Importance changes the answer's noise, not nothing.
  settings.importance.clear();
  Solver plain = make_solver(scene, settings);
  plain.run();
  EXPECT_NE(testing::solution_data(plain).radiosity, dumps[0].radiosity);
}

// Every example scene (a shooting transport, every storage), with the first curve that holds
// light as the region: the solve ends as a solve does and the books balance.
TEST(Importance, BooksBalanceOnEveryExampleSceneAndStorage) {
  int scenes = 0;
  for (const auto& entry : std::filesystem::directory_iterator(testing::source_path("scenes2d"))) {
    if (entry.path().extension() != ".json") continue;
    const Scene scene = testing::scene_from_file("scenes2d/" + entry.path().filename().string());
    std::string region;
    for (const Curve& curve : scene.curves)
      if (region.empty() && scene.reflects_light(curve)) region = curve.id;
    ASSERT_FALSE(region.empty()) << entry.path();
    ++scenes;
    for (BasisKind basis : {BasisKind::Constant, BasisKind::Linear, BasisKind::Cubic, BasisKind::Hermite}) {
      SolverSettings settings;
      settings.photons = 50'000;
      settings.basis = basis;
      settings.importance = {region};
      if (basis == BasisKind::Linear) settings.sampling = PositionSampling::Uniform;
      if (basis == BasisKind::Cubic) settings.estimator = Estimator::Galerkin;
      Solver solver = make_solver(scene, settings);
      solver.run();
      EXPECT_TRUE(solver.stop_reason() == StopReason::Converged || solver.stop_reason() == StopReason::BudgetSpent)
          << entry.path() << ": " << to_string(solver.stop_reason()) << " " << solver.books_error();
      const EnergyBooks books = solver.books();
      EXPECT_NEAR(books.imbalance(), 0.0, 1e-9 * books.emitted) << entry.path() << " " << to_string(basis);
      EXPECT_GT(solver.importance_photons(), 0u);
    }
  }
  EXPECT_GE(scenes, 5);
}

}  // namespace
}  // namespace flatland
