#include "flatland/transport/control_variate.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/reference/coarse_answer.hpp"
#include "flatland/transport/error_estimate.hpp"
#include "flatland/transport/solver.hpp"
#include "test_support.hpp"
#include "transport/closed_forms.hpp"

namespace flatland {
namespace {

using namespace closed_forms;
using testing::make_solver;

SolverSettings variate_settings(BasisKind basis = BasisKind::Cubic) {
  SolverSettings settings;
  settings.control_variate = ControlVariate::Coarse;
  settings.basis = basis;
  return settings;
}

// In a closed furnace of uniform E and rho the coarse answer is exact, b_c = E / (1 - rho) (the
// reference's gather sees the whole enclosure, its own arc included), so D = E + rho G - b_c is zero
// to the reference's solve tolerance (1e-10): whatever the photons shoot of it (the tolerance is a
// share of D's own power) moves B by less than 1e-9 of itself, and B is E / (1 - rho) everywhere.
// The books: nothing escapes, the coarse light's absorption is all the emitted power.
void check_furnace(double rho, BasisKind basis) {
  const Scene scene = testing::scene_from_text(testing::circle_enclosure(rho, 1.0));
  SolverSettings settings = variate_settings(basis);
  settings.photons = 100'000;
  settings.elements = 16;
  Solver solver = make_solver(scene, settings);
  solver.run();
  EXPECT_EQ(solver.stop_reason(), StopReason::Converged);
  EXPECT_LT(solver.control_variate_source_fraction(), 1e-9);
  const double exact = 1.0 / (1.0 - rho);
  for (int j = 0; j < 200; ++j) {
    const CurvePoint point = point_at_arc_length(scene, scene.curves[0], (j + 0.5) * scene.curves[0].length / 200);
    EXPECT_NEAR(solver.radiosity(0, Side::Front, point.u)[0], exact, 1e-8 * exact) << "at sample " << j;
  }
  const EnergyBooks books = solver.books();
  EXPECT_NEAR(books.imbalance(), 0.0, 1e-12 * books.emitted);
  EXPECT_NEAR(books.escaped, 0.0, 1e-9 * books.emitted);
  EXPECT_NEAR(books.absorbed, books.emitted, 1e-8 * books.emitted);
  EXPECT_GT(solver.control_variate_elements(), 0u);
}

TEST(ControlVariate, IsExactInAFurnace) {
  for (BasisKind basis : {BasisKind::Constant, BasisKind::Linear, BasisKind::Cubic}) {
    SCOPED_TRACE(to_string(basis));
    check_furnace(0.5, basis);
    check_furnace(0.9, basis);
  }
}

// On the one-bounce penumbra (a black lamp, a black occluder, a reflecting floor) the floor's light
// is all direct: b_c on the lamp is E exactly, so G = K b_c is the floor's true irradiance H, and D
// on the floor (its own light less its coarse constant) leaves upwards and never comes back to it.
// The floor's lumped coefficients are then rho integral(phi_k H ds) / integral(phi_k ds) with no
// noise at all: the closed form, to the quadrature's accuracy, and the same for any seed (up to the
// lamp's D, E less its constant, which is zero to rounding).
TEST(ControlVariate, GivesThePenumbraWithoutNoise) {
  const PenumbraSetup setup;
  const Scene scene = testing::scene_from_text(setup.scene_text());
  for (BasisKind basis : {BasisKind::Constant, BasisKind::Linear, BasisKind::Cubic}) {
    SCOPED_TRACE(to_string(basis));
    std::vector<std::vector<double>> floors;
    for (std::uint64_t seed : {1u, 2u}) {
      SolverSettings settings = variate_settings(basis);
      settings.photons = 100'000;
      settings.elements = 24;
      settings.estimator = Estimator::Lumped;
      settings.seed = seed;
      Solver solver = make_solver(scene, settings);
      solver.run();
      EXPECT_NE(solver.stop_reason(), StopReason::BooksUnbalanced) << solver.books_error();
      const CurveStorage& storage = solver.storage(1);
      const std::vector<double> expected = expected_floor_power(setup, storage);
      const std::vector<double> b = solver.radiosity_coefficients(1, Side::Front);
      ASSERT_EQ(b.size(), storage.basis.size());
      for (std::size_t k = 0; k < b.size(); ++k)
        EXPECT_NEAR(b[k], setup.rho * expected[k] / storage.basis_length[k], 1e-7) << "coefficient " << k;
      floors.push_back(b);
    }
    for (std::size_t k = 0; k < floors[0].size(); ++k) EXPECT_NEAR(floors[0][k], floors[1][k], 1e-12) << k;
  }
}

// Past a round occluder (eight cubic arcs) the floor's light is direct again, and the same argument
// leaves no noise on it: what is left is how well G, the transport of b_c, follows the curves the
// photons meet. Gathered over the coarse chords themselves (a 50th of the scene's size, a sagitta of
// 2.5e-3 on the occluder's radius of 0.3), the floor's relative L2 error was 3.2e-3 whatever the
// photons; over chords 8 times finer (a sagitta 64 times smaller) it is 4e-5. The bound, 5e-4,
// fails the first and leaves room for the cubic storage's own error on the floor's penumbrae.
TEST(ControlVariate, FollowsTheCurvesThePhotonsMeet) {
  const Scene scene = testing::scene_from_file("scenes2d/tests/reference_round_occluder.json");
  SolverSettings settings = variate_settings();
  settings.photons = 100'000;
  settings.elements = 64;
  Solver solver = make_solver(scene, settings);
  solver.run();
  ASSERT_NE(solver.stop_reason(), StopReason::BooksUnbalanced) << solver.books_error();
  // The floor's relative L2 and L1 errors along its arc length.
  const Curve& floor = scene.curves[2];
  double squared_error = 0.0, squared = 0.0, absolute = 0.0, total = 0.0;
  for (int j = 0; j < 400; ++j) {
    const CurvePoint point = point_at_arc_length(scene, floor, (j + 0.5) * floor.length / 400);
    const double exact = round_occluder_floor(scene, 1, point.position.x, 0.5);
    const double b = solver.radiosity(2, Side::Front, point.u)[0];
    squared_error += (b - exact) * (b - exact);
    squared += exact * exact;
    absolute += std::fabs(b - exact);
    total += std::fabs(exact);
  }
  EXPECT_LT(std::sqrt(squared_error / squared), 5e-4);
  // That bias is all the floor's error (no noise is left on direct light), so the estimated error
  // must hold it: the variate's own part (G over the coarse chords against the finer ones, scaled by
  // 1 / 63) joins the storage part. Without it the bound was 0.17 to 0.40 of the true error.
  const ErrorEstimate estimate = estimate_error(solver, {0.95, 100});
  ASSERT_TRUE(estimate.available && estimate.bounded);
  EXPECT_LE(absolute / total, estimate.bound.l1);
}

// The lit ring (E(phi) = 1 + 0.8 sin(phi), rho = 0.5; B in closed form by Fourier series): the mean
// over 10 seeds of B's Fourier coefficients a0 and b1 must match the closed form within 5 standard
// errors from the seeds' spread (Student's t, 9 degrees of freedom), plus 1e-6 of a0 for the 2000
// midpoints of the quadrature below. The control variate takes almost all the noise away, so this
// also bounds any bias it would add (the storage's hold of D, the projections' quadrature) by the
// remaining noise.
TEST(ControlVariate, IsUnbiasedOnTheLitRing) {
  const Scene scene = testing::scene_from_text(ring_with_profile(2));
  const RingSolution exact = solve_ring(scene, 0.5);
  const int seeds = 10;
  std::vector<double> a0, b1;
  for (int seed = 1; seed <= seeds; ++seed) {
    SolverSettings settings = variate_settings();
    settings.photons = 200'000;
    settings.elements = 16;
    settings.seed = static_cast<std::uint64_t>(seed);
    Solver solver = make_solver(scene, settings);
    solver.run();
    ASSERT_NE(solver.stop_reason(), StopReason::BooksUnbalanced) << solver.books_error();
    const auto [a, b] = ring_a0_b1(scene, [&](double u) { return solver.radiosity(0, Side::Front, u)[0]; });
    a0.push_back(a);
    b1.push_back(b);
  }
  auto check = [&](const std::vector<double>& values, double expected, const char* name) {
    const auto [mean, error] = mean_and_standard_error(values);
    EXPECT_LT(std::fabs(mean - expected), 5.0 * error + 1e-6 * std::fabs(exact.a[0]))
        << name << ": " << mean << " vs " << expected << " (standard error " << error << ")";
  };
  check(a0, exact.a[0], "a0");
  check(b1, exact.b[1], "b1");
}

// The books balance on rooms that are closed and open, coloured and grey (the solver checks them
// after every round), and the exact part's split between escaped and absorbed light agrees with
// plain shooting's: the coarse answer's escape by its form factors, the photons' by where they went.
// Plain shooting's escaped fraction at 1e6 photons has a standard deviation below 1e-3 of the
// emitted power here; 5e-3 allows five of them.
TEST(ControlVariate, KeepsTheBooksOnExampleScenes) {
  for (const char* file :
       {"scenes2d/default.json", "scenes2d/interreflection/window_room.json", "scenes2d/row_of_rooms.json"}) {
    SCOPED_TRACE(file);
    const Scene scene = testing::scene_from_file(file);
    SolverSettings settings = variate_settings();
    settings.photons = 200'000;
    Solver variate = make_solver(scene, settings);
    variate.run();
    ASSERT_NE(variate.stop_reason(), StopReason::BooksUnbalanced) << variate.books_error();
    settings.control_variate = ControlVariate::None;
    settings.photons = 1'000'000;
    Solver plain = make_solver(scene, settings);
    plain.run();
    const EnergyBooks a = variate.books();
    const EnergyBooks b = plain.books();
    EXPECT_NEAR(a.imbalance(), 0.0, 1e-9 * a.emitted);
    EXPECT_NEAR(a.escaped, b.escaped, 5e-3 * a.emitted);
    EXPECT_NEAR(a.absorbed + a.unshot, b.absorbed + b.unshot, 5e-3 * a.emitted);
  }
}

TEST(ControlVariate, GivesTheSameBitsOnAnyThreadCountAndStep) {
  const Scene scene = testing::scene_from_file("scenes2d/default.json");
  SolverSettings settings = variate_settings();
  settings.photons = 100'000;
  settings.threads = 1;
  Solver one = make_solver(scene, settings);
  one.run();
  settings.threads = 2;
  Solver two = make_solver(scene, settings);
  while (two.step_photons(7'777) > 0) {
  }
  EXPECT_GT(one.photons_shot(), 0u);
  EXPECT_EQ(testing::solution_data(one), testing::solution_data(two));
}

TEST(ControlVariate, RefusesWhatItCannotCarry) {
  const Scene room = testing::scene_from_file("scenes2d/default.json");
  const auto refused = [&](const Scene& scene, const SolverSettings& settings, const std::string& words) {
    const Result<Solver> solver = create_solver(scene, settings);
    ASSERT_FALSE(solver.ok()) << words;
    EXPECT_NE(solver.error().message.find("control variate"), std::string::npos) << solver.error().message;
    EXPECT_NE(solver.error().message.find(words), std::string::npos) << solver.error().message;
  };
  SolverSettings settings = variate_settings();
  settings.transport = Transport::Walk;
  refused(room, settings, "transport walk");
  settings.transport = Transport::Jacobi;
  refused(room, settings, "transport jacobi");
  settings = variate_settings();
  settings.sampling = PositionSampling::Uniform;
  refused(room, settings, "sampling reconstructed");
  settings = variate_settings(BasisKind::Hermite);
  refused(room, settings, "Hermite");
  settings = variate_settings();
  settings.importance = {"floor"};
  refused(room, settings, "importance");
  refused(testing::scene_from_file("scenes2d/mirror_room.json"), variate_settings(), "a mirror");
  refused(testing::scene_from_file("scenes2d/prism.json"), variate_settings(), "spectra");
}

// --control-variate auto (the default of create_solver's callers): the variate where it applies,
// with the bits of asking for it; elsewhere none, with the bits of asking for none and the refusal
// that coarse would give as its reason (without the file name and the advice to do without).
TEST(ControlVariate, AutoUsesItWhereItAppliesAndSaysWhyNotElsewhere) {
  const Scene room = testing::scene_from_file("scenes2d/default.json");
  const Scene mirrors = testing::scene_from_file("scenes2d/mirror_room.json");
  const auto solved = [](const Scene& scene, SolverSettings settings, ControlVariate variate) {
    settings.control_variate = variate;
    Result<Solver> solver = create_solver(scene, settings);
    EXPECT_TRUE(solver.ok()) << (solver.ok() ? "" : solver.error().message);
    solver->run();
    return std::move(*solver);
  };
  SolverSettings settings;
  EXPECT_EQ(settings.control_variate, ControlVariate::Auto);  // the default
  settings.photons = 20'000;
  const auto check = [&](const Scene& scene, const SolverSettings& s, ControlVariate chosen, const std::string& words) {
    const Solver automatic = solved(scene, s, ControlVariate::Auto);
    const Solver asked = solved(scene, s, chosen);
    EXPECT_EQ(automatic.settings().control_variate, chosen) << words;
    // The replicates' layout follows: blocks of one net under the variate, independent without.
    EXPECT_EQ(automatic.settings().replicate_layout,
              chosen == ControlVariate::Coarse ? ReplicateLayout::Blocks : ReplicateLayout::Independent)
        << words;
    EXPECT_EQ(testing::solution_data(automatic), testing::solution_data(asked)) << words;
    EXPECT_EQ(automatic.control_variate_skipped().empty(), words.empty()) << automatic.control_variate_skipped();
    EXPECT_NE(automatic.control_variate_skipped().find(words), std::string::npos)
        << automatic.control_variate_skipped();
    EXPECT_EQ(automatic.control_variate_skipped().find(scene.source), std::string::npos);
    EXPECT_EQ(automatic.control_variate_skipped().find("without the control variate"), std::string::npos);
  };
  check(room, settings, ControlVariate::Coarse, "");
  check(mirrors, settings, ControlVariate::None, "curve 'mirror' is a mirror");
  SolverSettings other = settings;
  other.transport = Transport::Walk;
  check(room, other, ControlVariate::None, "transport walk");
  other = settings;
  other.basis = BasisKind::Hermite;
  check(room, other, ControlVariate::None, "Hermite");
  // Solver::create alone, with no coarse answer, runs auto as none.
  Result<Solver> plain = Solver::create(room, settings);
  ASSERT_TRUE(plain.ok());
  EXPECT_EQ(plain->settings().control_variate, ControlVariate::None);
}

// The replicates' layout by default (ReplicateLayout::Auto) is blocks under the variate and
// independent without it: the same bits as asking for each, and under the variate the answer is
// the one net's (a round of 8 blocks deposits what a round of one replicate does).
TEST(ControlVariate, AutoLayoutIsOneNetUnderTheVariate) {
  const Scene room = testing::scene_from_file("scenes2d/default.json");
  // One coarse answer for every solver below (create_solver would solve it again each time).
  const Result<std::shared_ptr<const CoarseAnswer>> coarse = solve_coarse_answer(room, 2, nullptr);
  ASSERT_TRUE(coarse.ok()) << coarse.error().message;
  SolverSettings settings;
  EXPECT_EQ(settings.replicate_layout, ReplicateLayout::Auto);  // the default
  settings.photons = 20'000;
  settings.elements = 12;
  settings.control_variate = ControlVariate::Coarse;
  const auto solved = [&](ReplicateLayout layout, int replicates, bool one_round) -> std::optional<Solver> {
    SolverSettings s = settings;
    s.replicate_layout = layout;
    s.replicates = replicates;
    Result<Solver> solver =
        Solver::create(room, s, nullptr, s.control_variate == ControlVariate::Coarse ? *coarse : nullptr);
    if (!solver.ok()) {
      ADD_FAILURE() << solver.error().message;
      return std::nullopt;
    }
    if (one_round)
      EXPECT_TRUE(solver->step_round());
    else
      solver->run();
    return std::move(*solver);
  };
  const std::optional<Solver> automatic = solved(ReplicateLayout::Auto, 8, false);
  const std::optional<Solver> blocks = solved(ReplicateLayout::Blocks, 8, false);
  const std::optional<Solver> independent = solved(ReplicateLayout::Independent, 8, false);
  ASSERT_TRUE(automatic && blocks && independent);
  EXPECT_EQ(automatic->settings().replicate_layout, ReplicateLayout::Blocks);
  EXPECT_EQ(testing::solution_data(*automatic), testing::solution_data(*blocks));
  EXPECT_NE(testing::solution_data(*automatic).radiosity, testing::solution_data(*independent).radiosity);
  // The estimate reads the blocks as blocks (their stratification factor) under auto too.
  EXPECT_EQ(estimate_error(*automatic).bound.l1, estimate_error(*blocks).bound.l1);
  // One round: 8 blocks shoot the photons of one net, deposited in 8 parts, so the coefficients
  // agree with one replicate's to the round-off of summing the parts. A round's photons are a
  // multiple of R (one replicate: any number): the first budget whose first round one replicate
  // shoots as a multiple of 8, so that both shoot the same photons.
  std::optional<Solver> one_net = solved(ReplicateLayout::Independent, 1, true);
  while (one_net && one_net->photons_shot() % 8 != 0) {
    ++settings.photons;
    one_net = solved(ReplicateLayout::Independent, 1, true);
  }
  const std::optional<Solver> round = solved(ReplicateLayout::Auto, 8, true);
  ASSERT_TRUE(one_net && round);
  ASSERT_EQ(round->photons_shot(), one_net->photons_shot());
  std::size_t compared = 0;
  for (std::uint32_t curve = 0; curve < room.curves.size(); ++curve)
    for (Side side : {Side::Front, Side::Back}) {
      const std::vector<double> a = round->radiosity_coefficients(curve, side);
      const std::vector<double> b = one_net->radiosity_coefficients(curve, side);
      ASSERT_EQ(a.size(), b.size());
      double scale = 0.0;
      for (const double value : b) scale = std::max(scale, std::fabs(value));
      for (std::size_t k = 0; k < a.size(); ++k) EXPECT_NEAR(a[k], b[k], 1e-12 * scale) << curve << " " << k;
      compared += a.size();
    }
  EXPECT_GT(compared, 0u);
  // Without the variate, auto is independent replicates.
  settings.control_variate = ControlVariate::None;
  const std::optional<Solver> plain = solved(ReplicateLayout::Auto, 8, false);
  ASSERT_TRUE(plain);
  EXPECT_EQ(plain->settings().replicate_layout, ReplicateLayout::Independent);
}

// Auto's bound on the set-up: the projection's point-chord pairs grow with the storage (here its
// elements per curve) and are checked before any work; above the bound, the reason says so and
// coarse takes it all the same. The bound grows with the photons (three times their own time).
TEST(ControlVariate, AutoSkipsASetUpAboveItsBound) {
  const Scene room = testing::scene_from_file("scenes2d/curved_room.json");
  SolverSettings settings;
  settings.photons = 10'000;
  settings.elements = 16;
  const double small = control_variate_work(room, settings);
  EXPECT_GT(small, 0.0);
  EXPECT_LT(small, kAutoControlVariateWork);
  EXPECT_EQ(control_variate_auto_skip(room, settings), "");
  settings.elements = 16 * 1024;
  const double large = control_variate_work(room, settings);
  EXPECT_GT(large, 100.0 * small);  // the pairs grow with the spans (1024 times the elements)
  ASSERT_GT(large, kAutoControlVariateWork);
  const std::string reason = control_variate_auto_skip(room, settings);
  EXPECT_NE(reason.find("point-chord pairs"), std::string::npos) << reason;
  settings.photons = static_cast<std::uint64_t>(std::ceil(large / kAutoControlVariateWorkPerPhoton));
  EXPECT_EQ(control_variate_auto_skip(room, settings), "");
  settings.control_variate = ControlVariate::Coarse;
  EXPECT_TRUE(check_solver_settings(room, settings).ok());
}

}  // namespace
}  // namespace flatland
