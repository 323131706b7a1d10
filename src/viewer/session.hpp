// The viewer's solve: a Solver driven on a worker thread, so the window stays responsive, and
// published as immutable snapshots that the drawing thread picks up each frame. Where no thread can
// be started (the single-threaded web build), the same commands run on the caller's thread in
// short pieces between frames (Threading::Inline, pump). No GL, no SDL: the tests drive it directly. All physics is the
// core's Solver; this only steps it and copies out what is drawn.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <thread>

#include <nlohmann/json.hpp>

#include "flatland/reference/final_gather.hpp"
#include "flatland/results/sampled_result.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/transport/solver.hpp"
#include "viewer/frame.hpp"

namespace flatland::viewer {

enum class StepKind {
  Photon,  // one photon
  Batch,   // to the end of the current batch of Solver::kBatchSize photons
  Round,   // to the end of the current round (or a whole round when none is open)
};

// Fills the solver's state into a snapshot: describe_progress and describe_solution.
void describe_solver(const Solver& solver, const std::vector<CurveTrace>& traces, Snapshot& snapshot);
// The solver's counters, cheap to read: settings, progress, books, the open round's photons, the rate.
void describe_progress(const Solver& solver, Snapshot& snapshot);
// What the solver's answer draws, which costs a pass over every curve: B at every trace sample,
// detector bins, storage nodes and each curve's share of the reflected power.
void describe_solution(const Solver& solver, const std::vector<CurveTrace>& traces, Snapshot& snapshot);

class Session {
 public:
  enum class Threading {
    Worker,  // a worker thread runs the commands
    Inline,  // the caller runs them: pump() between frames, wait_idle() to finish them
  };
  explicit Session(Threading threading = Threading::Worker);
  ~Session();
  Session(const Session&) = delete;
  Session& operator=(const Session&) = delete;

  // Start over on this scene with these settings: the running solve is cancelled, paths cleared.
  // Invalid settings or a scene the solver rejects leave a snapshot whose `error` says why.
  void restart(std::shared_ptr<const Scene> scene, const SolverSettings& settings);
  // Run freely (in pieces of about kPieceSeconds) until the solve stops, or pause.
  void set_running(bool running);
  // Asked to run and not stopped (converged, budget spent, no solver). A run ends when the solve
  // stops: running() is then false, and a Reset starts the new solve paused.
  bool running() const;
  // Pause, then shoot `count` photons, batches or rounds (queued behind earlier steps).
  void step(StepKind kind, std::uint64_t count = 1);
  // How many recent paths the snapshots keep (0 records none: the fastest shooting).
  void set_path_limit(std::size_t count);
  // A reference result (flatland reference --out, or solve --out) of the same scene: snapshots then
  // carry the error so far and its history. nullptr removes it.
  void set_reference(std::shared_ptr<const SampledResult> reference);

  // The latest published snapshot (never null after construction).
  std::shared_ptr<const Snapshot> snapshot() const;
  // Blocks until every queued command is done and the worker is paused or stopped (Inline: runs
  // them to that point on the calling thread).
  void wait_idle();
  // Inline: runs queued commands and the free run for about `seconds` (at least one piece when
  // there is work; no further one that would end later), then returns; the next call goes on.
  // Worker: does nothing.
  void pump(double seconds);
  Threading threading() const { return threading_; }
  // The current result in the format of `flatland solve --out` (docs/result-format.md).
  Result<nlohmann::json> result_json(int samples_per_curve);

 private:
  // A piece of shooting: `count` photons of the first queued step (`stepping`: the step `step_id`,
  // of `kind`) or of the free run, recording at most `path_limit` paths.
  struct Piece {
    std::uint64_t count = 0;
    bool stepping = false;
    std::uint64_t step_id = 0;
    StepKind kind = StepKind::Photon;
    std::size_t path_limit = 0;
  };
  // The worker thread: waits for a command, then runs it (work_once).
  void worker();
  // Under mutex_: whether a command waits (or the free run goes on).
  bool has_work() const;
  // Runs one command, if one waits: restarts the solve, takes a new reference, republishes or
  // shoots a piece. False when there was nothing to do (the session is then idle).
  bool work_once();
  // Drops the solve, its paths and error history, creates the solver of `scene` (none for a null
  // scene; one the solver rejects leaves the error) and publishes it. Takes solver_mutex_, then mutex_.
  void start_solve(std::shared_ptr<const Scene> scene, const SolverSettings& settings);
  // The error against the reference starts over (under solver_mutex_).
  void clear_error_history();
  // Under mutex_: the next piece to shoot; none when the first queued step is dropped because no
  // solver can run it.
  std::optional<Piece> next_piece();
  // Shoots the piece and publishes it, then counts it against its step. Takes solver_mutex_, then
  // mutex_.
  void shoot_piece(const Piece& piece);
  // chunk_ from the rate of the last piece (under solver_mutex_).
  void adapt_chunk(const Solver& solver, std::uint64_t shot, double seconds);
  // Under mutex_: what is left of the piece's step after `shot` photons; a finished step is dropped.
  void count_step(const Piece& piece, const Solver& solver, std::uint64_t shot);
  // A new snapshot: the new paths, the solver's counters, and its answer (the open round included)
  // when due (see solution_). `force`: a manual step or a refresh, which show everything at once.
  void publish(Solver* solver, const std::vector<PathRecord>& new_paths, bool force);

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable idle_;
  // Commands, under mutex_.
  bool quit_ = false;
  bool restart_pending_ = false;
  std::shared_ptr<const Scene> pending_scene_;
  SolverSettings pending_settings_;
  struct Step {
    StepKind kind = StepKind::Photon;
    std::uint64_t count = 0;  // photons, batches or rounds still to shoot
    std::uint64_t id = 0;
  };
  std::deque<Step> steps_;
  std::uint64_t next_step_id_ = 0;
  bool reference_changed_ = false;
  bool running_ = false;
  bool busy_ = false;             // the worker is executing a command
  bool refresh_pending_ = false;  // publish again, forced (the reference changed, or a pause)
  bool can_run_ = false;          // a solver exists and has not stopped
  std::size_t path_limit_ = 20'000;
  std::shared_ptr<const SampledResult> reference_;
  std::shared_ptr<const Snapshot> snapshot_;

  // The worker's own state; solver_mutex_ guards the solver for result_json.
  std::mutex solver_mutex_;
  std::shared_ptr<const Scene> scene_;
  std::shared_ptr<const std::vector<CurveTrace>> traces_;
  std::optional<Solver> solver_;
  // The final gather the settings ask for (--gather samples, or auto where the scene allows it):
  // it gathers the saved result and the estimate once the solve stops; the plots stay the
  // storage's B, live. `gather_skipped_`: why auto gathers nothing.
  std::unique_ptr<FinalGather> gather_;
  std::string gather_skipped_;
  std::string error_;
  std::uint64_t generation_ = 0;
  std::deque<PathRecord> paths_;
  std::uint64_t next_serial_ = 0;
  // The light field: every finished round's first kFieldFlightsPerRound flights, standing for
  // all its photons (so the field of a solve does not depend on how it was cut into pieces), and
  // the open round's record so far: round_field_ holds its `round_flights_` flights with weight 1,
  // `round_recorded_` whole photons of the `round_shot_` the round has shot, and joins the field
  // weighted round_shot_ / round_recorded_ (provisionally in the image while the round is open;
  // for good when it ends). The image as last published is remade at most every kFieldSeconds
  // while the field changes, and at once for manual steps and when the solve stops.
  LightField field_;
  LightField round_field_;
  std::size_t round_flights_ = 0;
  std::size_t round_recorded_ = 0;
  std::uint64_t round_shot_ = 0;
  std::uint64_t field_changes_ = 0;  // pieces that added to the field or the round's record
  std::uint64_t field_version_ = 0;  // field_changes_ as of the image
  std::shared_ptr<const FieldImage> field_image_;
  std::chrono::steady_clock::time_point field_time_{};
  static constexpr double kFieldSeconds = 0.2;
  // The field's grid: the scene's longer side in cells (a 1000-pixel stage shows a cell on about
  // two pixels, filtered between them).
  static constexpr int kFieldResolution = 512;
  // Seconds of shooting a piece: long enough to amortise the per-piece work (the view's estimate
  // and the snapshot, serial while the other threads wait: with 25 ms the viewer shot 10 M photons
  // in 300 frames, with 50 ms 13.6 M; docs/performance-log.md), short enough for a prompt pause and
  // paths that arrive every other frame.
  static constexpr double kPieceSeconds = 0.05;
  // Inline, a piece shares the frame with drawing (a 60 Hz frame is 17 ms).
  static constexpr double kInlinePieceSeconds = 0.02;
  Threading threading_ = Threading::Worker;
  double piece_seconds_ = kPieceSeconds;
  // Paths recorded per running piece (frames are paced to 25 ms and draw at most 600 new paths):
  // the display keeps up with what is recorded.
  static constexpr std::size_t kPathsPerStep = 768;
  // Flights of each round recorded for the light field: about 360,000 over the default scene's
  // eleven rounds, for a few percent of the solve's time.
  static constexpr std::size_t kFieldFlightsPerRound = 32768;
  // The solver's answer as last described (describe_solution's fields only). Including the open
  // round and describing it costs a pass over the storage of every level and every curve: 22 ms on
  // the default scene, as long as a 20 ms piece of shooting on one thread, so per piece it halved
  // the rate. It is remade when a round ends, the solve stops, a step or refresh asks (`force`),
  // and otherwise once kSolutionSeconds have passed or, where it is cheap, once it would take at
  // most kSolutionShare of the time since the last; the counters and paths go out every piece.
  Snapshot solution_;
  bool solution_valid_ = false;
  std::uint32_t solution_rounds_ = 0;
  std::chrono::steady_clock::time_point solution_time_{};
  double solution_cost_ = 0.0;  // seconds the last one took
  static constexpr double kSolutionSeconds = 0.2;
  static constexpr double kSolutionShare = 0.1;
  std::vector<std::array<double, 2>> error_history_;
  std::optional<double> reference_error_;
  double last_error_time_ = -1.0;
  // The solve's estimated error and its band along the curves, and the solve time they were made at.
  std::optional<ErrorEstimate> estimated_error_;
  bool estimate_gathered_ = false;
  std::shared_ptr<const std::vector<std::array<std::vector<double>, 2>>> error_band_;
  double last_estimate_time_ = -1.0;
  bool estimate_final_ = false;
  std::uint64_t chunk_ = Solver::kBatchSize;  // photons per piece, adapted to about kPieceSeconds
  std::atomic<bool> cancel_{false};
  std::thread thread_;  // Worker only
};

}  // namespace flatland::viewer
