// The viewer's solve session (src/viewer/session): the core Solver stepped on a worker thread.
// What the viewer shows must be what `flatland solve` computes.
#include "viewer/session.hpp"

#include <gtest/gtest.h>

#include "flatland/reference/final_gather.hpp"
#include "flatland/results/result_io.hpp"
#include "test_support.hpp"

namespace flatland::viewer {
namespace {

// What `flatland solve` writes of the solver: with the final gather its settings choose (the
// default, auto, gathers these diffuse scenes), as the session's saved result is.
nlohmann::json solved_json(const Solver& solver, int samples) {
  Result<GatherChoice> choice = choose_gather(solver.scene(), solver.settings(), Solver::kTargetSamples);
  EXPECT_TRUE(choice);
  if (choice && choice->gather) return result_to_json(solver, samples, choice->gather->gather_result(solver, samples));
  return result_to_json(solver, samples);
}

std::string without_timing(nlohmann::json result) {
  result["stats"].erase("seconds");
  return result.dump();
}

TEST(Session, SteppedRoundsGiveTheSolversResult) {
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/mixed.json"));
  SolverSettings settings;
  settings.photons = 200'000;
  settings.seed = 5;
  settings.threads = 2;
  Session session;
  session.restart(scene, settings);
  session.step(StepKind::Photon);       // one photon
  session.step(StepKind::Photon, 999);  // a partial batch
  session.step(StepKind::Batch);        // to the batch's end
  session.step(StepKind::Round, 3);     // the rest of round 0, then rounds 1 and 2
  session.wait_idle();
  const std::shared_ptr<const Snapshot> snapshot = session.snapshot();
  EXPECT_EQ(snapshot->progress.rounds, 3u);
  EXPECT_EQ(snapshot->round_photons, 0u);  // no round left open
  Result<nlohmann::json> stepped = session.result_json(40);
  ASSERT_TRUE(stepped);

  Solver solver = *create_solver(*scene, settings);
  for (int round = 0; round < 3; ++round) ASSERT_TRUE(solver.step_round());
  EXPECT_EQ(snapshot->progress.photons, solver.photons_shot());
  EXPECT_EQ(without_timing(*stepped), without_timing(solved_json(solver, 40)));
}

// The light field holds whole rounds only: a session stepped in odd pieces and one stepped round by
// round (two threads against one) end with the same field, bit for bit, which stands for every
// photon shot.
TEST(Session, TheFieldDoesNotDependOnThePieces) {
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/mirror_room.json"));
  SolverSettings settings;
  settings.photons = 120'000;
  settings.seed = 9;
  auto field_after = [&](int threads, bool odd) {
    SolverSettings s = settings;
    s.threads = threads;
    Session session;
    session.restart(scene, s);
    if (odd) {
      session.step(StepKind::Photon, 777);
      session.step(StepKind::Batch);
      session.step(StepKind::Photon, 50'001);
    }
    session.step(StepKind::Round, 100);  // to the end of the solve
    session.wait_idle();
    const std::shared_ptr<const Snapshot> snapshot = session.snapshot();
    EXPECT_EQ(snapshot->stop_reason == StopReason::Running, false);
    EXPECT_NE(snapshot->field, nullptr);
    if (snapshot->field) {
      EXPECT_EQ(snapshot->field->photons, static_cast<double>(snapshot->progress.photons));
    }
    return snapshot->field;
  };
  const std::shared_ptr<const FieldImage> odd = field_after(1, true);
  const std::shared_ptr<const FieldImage> whole = field_after(2, false);
  ASSERT_TRUE(odd && whole);
  EXPECT_EQ(odd->rgba, whole->rgba);
}

TEST(Session, StepsAcrossBatchesRoundsAndThreadCountsMatchTheSolver) {
  // A one-thread session stepped in odd pieces (inside a batch, then partial, whole and partial
  // batches in one piece, then across a round's end) against a three-thread solver.
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/default.json"));
  SolverSettings settings;
  settings.photons = 150'000;
  settings.seed = 21;
  settings.threads = 1;
  Session session;
  session.restart(scene, settings);
  session.step(StepKind::Photon, 1000);
  session.step(StepKind::Photon, 10'000);
  session.wait_idle();
  EXPECT_EQ(session.snapshot()->progress.photons, 11'000u);
  // More photons than the first round has: the step goes on into the next rounds.
  const std::uint64_t first_round = session.snapshot()->round_photons;
  ASSERT_GT(first_round, 11'000u);
  session.step(StepKind::Photon, first_round + 5'000);
  session.wait_idle();
  EXPECT_EQ(session.snapshot()->progress.photons, first_round + 16'000);
  EXPECT_GE(session.snapshot()->progress.rounds, 1u);
  session.step(StepKind::Round, 2);
  session.wait_idle();
  const std::uint32_t rounds = session.snapshot()->progress.rounds;

  settings.threads = 3;
  Solver solver = *create_solver(*scene, settings);
  for (std::uint32_t r = 0; r < rounds; ++r) ASSERT_TRUE(solver.step_round());
  EXPECT_EQ(session.snapshot()->progress.photons, solver.photons_shot());
  nlohmann::json a = *session.result_json(30);
  nlohmann::json b = solved_json(solver, 30);
  a["settings"].erase("threads");
  b["settings"].erase("threads");
  EXPECT_EQ(without_timing(a), without_timing(b));
}

TEST(Session, RestartWhileRunningStartsAFreshSolve) {
  // The restart's cancellation must stop the old solve only, never the new one.
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/mixed.json"));
  SolverSettings settings;
  settings.photons = 400'000;
  settings.tolerance = 1e-9;
  Session session;
  session.restart(scene, settings);
  session.set_running(true);
  for (int i = 0; i < 20; ++i) {
    settings.seed = static_cast<std::uint64_t>(100 + i);
    session.restart(scene, settings);
  }
  session.wait_idle();
  const std::shared_ptr<const Snapshot> snapshot = session.snapshot();
  EXPECT_EQ(snapshot->settings.seed, 119u);
  EXPECT_NE(snapshot->stop_reason, StopReason::Cancelled);
  Solver solver = *create_solver(*scene, settings);
  solver.run();
  EXPECT_EQ(snapshot->stop_reason, solver.stop_reason());
  EXPECT_EQ(without_timing(*session.result_json(20)), without_timing(solved_json(solver, 20)));
}

TEST(Session, OnePhotonStepShowsOnePathAndItsDeposit) {
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/penumbra.json"));
  SolverSettings settings;
  settings.control_variate = ControlVariate::None;  // the first photon leaves the emitter (as the viewer's default)
  settings.photons = 10'000;
  Session session;
  session.restart(scene, settings);
  session.wait_idle();
  EXPECT_EQ(session.snapshot()->paths.size(), 0u);
  session.step(StepKind::Photon);
  session.wait_idle();
  const std::shared_ptr<const Snapshot> snapshot = session.snapshot();
  EXPECT_EQ(snapshot->progress.photons, 1u);
  EXPECT_EQ(snapshot->round_done, 1u);
  ASSERT_EQ(snapshot->paths.size(), 1u);
  const PathRecord& path = snapshot->paths[0];
  EXPECT_NEAR(path.from.y, 2.0, 1e-12);  // it leaves the emitter
  // The open round's deposit is visible: B is nonzero somewhere on the receiver iff the photon
  // landed on it (the only reflector).
  double receiver = 0.0;
  for (const Spectrum& b : snapshot->radiosity[2][0]) receiver += b[0];
  EXPECT_EQ(receiver > 0.0, !path.escaped && std::fabs(path.to.y) < 1e-9);
}

TEST(Session, RunningSpendsTheBudgetAndKeepsTheNewestPaths) {
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/room_reflector.json"));
  SolverSettings settings;
  settings.photons = 300'000;
  settings.tolerance = 1e-9;
  Session session;
  session.set_path_limit(500);
  session.restart(scene, settings);
  session.set_running(true);
  session.wait_idle();
  const std::shared_ptr<const Snapshot> snapshot = session.snapshot();
  // Where and when a free-running solve stops does not depend on how it was stepped.
  Solver solver = *create_solver(*scene, settings);
  solver.run();
  EXPECT_EQ(snapshot->stop_reason, solver.stop_reason());
  EXPECT_EQ(snapshot->progress.photons, solver.photons_shot());
  EXPECT_EQ(without_timing(*session.result_json(30)), without_timing(solved_json(solver, 30)));
  ASSERT_EQ(snapshot->paths.size(), 500u);
  for (std::size_t i = 1; i < snapshot->paths.size(); ++i)
    EXPECT_LT(snapshot->paths[i - 1].serial, snapshot->paths[i].serial);
  EXPECT_NEAR(snapshot->books.imbalance(), 0.0, 1e-9 * snapshot->books.emitted);
  // Shares of the reflected power sum to one.
  double shares = 0.0;
  for (double share : snapshot->received_share) shares += share;
  EXPECT_NEAR(shares, 1.0, 1e-12);
}

TEST(Session, AnInlineSessionPumpedBetweenFramesMatchesTheSolver) {
  // The web page's session: no worker thread; the caller pumps it in short slices (as frames do),
  // with a step and a restart queued in between. The free run ends where the solver's run does.
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/room_reflector.json"));
  SolverSettings settings;
  settings.photons = 200'000;
  settings.seed = 3;
  settings.threads = 1;
  Session session(Session::Threading::Inline);
  EXPECT_EQ(session.threading(), Session::Threading::Inline);
  session.restart(scene, settings);
  session.step(StepKind::Photon, 777);
  session.pump(0.0);  // one command per call at the least: the restart
  EXPECT_EQ(session.snapshot()->progress.photons, 0u);
  session.wait_idle();
  EXPECT_EQ(session.snapshot()->progress.photons, 777u);
  settings.seed = 4;
  session.restart(scene, settings);  // the new seed, from the start
  session.set_running(true);
  int slices = 0;
  while (session.running() || slices == 0) {
    session.pump(0.005);
    ++slices;
    ASSERT_LT(slices, 100'000);
  }
  EXPECT_GT(slices, 1);  // it took several frames, each returning
  Solver solver = *create_solver(*scene, settings);
  solver.run();
  EXPECT_EQ(session.snapshot()->progress.photons, solver.photons_shot());
  EXPECT_EQ(without_timing(*session.result_json(30)), without_timing(solved_json(solver, 30)));
}

TEST(Session, APauseShowsTheOpenRoundAsFarAsItWasShot) {
  // A running piece describes the answer only every so often (on the default scene's storage it
  // costs about as much as the piece's shooting); a pause describes it at once: B of every photon
  // shot, the open round's deposits included, the same bits as a solver stepped as far in one call.
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/default.json"));
  SolverSettings settings;
  settings.photons = 100'000'000;  // a first round far longer than the frames below
  settings.tolerance = 1e-12;
  settings.threads = 1;
  // The viewer's default: the variate's projection onto storage for 1e8 photons would be most of
  // the test's time (a minute and a half under the sanitizers), and pausing is shooting's.
  settings.control_variate = ControlVariate::None;
  Session session(Session::Threading::Inline);
  session.restart(scene, settings);
  session.set_running(true);
  session.pump(0.02);
  // Pump until a frame shot photons but left B as it was (the throttle at work), then pause.
  for (int frame = 0;; ++frame) {
    ASSERT_LT(frame, 1000) << "every piece described B";
    const std::shared_ptr<const Snapshot> before = session.snapshot();
    session.pump(0.02);
    const std::shared_ptr<const Snapshot> after = session.snapshot();
    if (after->progress.photons > before->progress.photons && after->radiosity == before->radiosity) break;
  }
  session.set_running(false);
  session.wait_idle();
  const std::shared_ptr<const Snapshot> snapshot = session.snapshot();
  ASSERT_GT(snapshot->round_done, 0u);  // the round is open
  Solver solver = *create_solver(*scene, settings);
  ASSERT_EQ(solver.step_photons(snapshot->progress.photons), snapshot->progress.photons);
  solver.include_open_round();
  Snapshot expected;
  describe_solution(solver, *snapshot->traces, expected);
  EXPECT_EQ(snapshot->radiosity, expected.radiosity);
  EXPECT_EQ(snapshot->received_share, expected.received_share);
}

TEST(Session, RestartTakesNewSettingsAndReportsRejectedOnes) {
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/penumbra.json"));
  SolverSettings settings;
  settings.photons = 50'000;
  Session session;
  session.restart(scene, settings);
  session.step(StepKind::Round);
  session.wait_idle();
  const std::uint64_t generation = session.snapshot()->generation;
  settings.basis = BasisKind::Linear;
  session.restart(scene, settings);
  session.wait_idle();
  std::shared_ptr<const Snapshot> snapshot = session.snapshot();
  EXPECT_NE(snapshot->generation, generation);
  EXPECT_EQ(snapshot->settings.basis, BasisKind::Linear);
  EXPECT_EQ(snapshot->progress.photons, 0u);
  EXPECT_TRUE(snapshot->paths.empty());
  settings.ray_width = -1.0;
  session.restart(scene, settings);
  session.wait_idle();
  snapshot = session.snapshot();
  EXPECT_FALSE(snapshot->error.empty());
  EXPECT_FALSE(session.result_json(10));
}

TEST(Session, ReportsTheErrorAgainstAReference) {
  // The penumbra's one-bounce reference; a second, independent solve of the same scene.
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/penumbra.json"));
  SolverSettings settings;
  settings.photons = 100'000;
  settings.seed = 11;
  Solver reference_solver = *Solver::create(*scene, settings);
  reference_solver.run();
  auto reference = std::make_shared<const SampledResult>(sample_solver(reference_solver, 50));
  settings.seed = 12;
  Session session;
  session.set_reference(reference);
  session.restart(scene, settings);
  session.set_running(true);
  session.wait_idle();
  const std::shared_ptr<const Snapshot> snapshot = session.snapshot();
  ASSERT_TRUE(snapshot->reference_error.has_value());
  // Two noisy estimates at 1e5 photons differ by a few per cent, not by their size.
  EXPECT_GT(*snapshot->reference_error, 0.0);
  EXPECT_LT(*snapshot->reference_error, 0.2);
  EXPECT_FALSE(snapshot->error_history.empty());
  ASSERT_EQ(snapshot->reference_curves.size(), scene->curves.size());
  EXPECT_EQ(snapshot->reference_curves[2].size(), 50u);
}

}  // namespace
}  // namespace flatland::viewer
