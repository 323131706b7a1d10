#include "viewer/session.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "flatland/reference/coarse_answer.hpp"
#include "flatland/results/metrics.hpp"
#include "flatland/results/result_io.hpp"

namespace flatland::viewer {

namespace {

using Clock = std::chrono::steady_clock;

// The reference's B along each curve (its main side, channels averaged), for the side panel.
std::vector<std::vector<std::array<double, 2>>> reference_curves(const SampledResult& reference) {
  std::vector<std::vector<std::array<double, 2>>> curves;
  const int channels = reference.channels;
  for (const ResultCurve& curve : reference.curves) {
    std::vector<std::array<double, 2>>& out = curves.emplace_back();
    for (const ResultSample& sample : curve.samples) {
      double value = 0.0;
      for (int ch = 0; ch < channels; ++ch) value += sample.B[static_cast<std::size_t>(ch)];
      out.push_back({sample.s, value / channels});
    }
  }
  return curves;
}

int reference_samples(const SampledResult& reference) {
  return reference.curves.empty() ? 0 : static_cast<int>(reference.curves[0].samples.size());
}

}  // namespace

void describe_progress(const Solver& solver, Snapshot& snapshot) {
  snapshot.settings = solver.settings();
  snapshot.progress = solver.progress();
  snapshot.books = solver.books();
  snapshot.stop_reason = solver.stop_reason();
  snapshot.round_photons = solver.round_photons();
  snapshot.round_done = solver.round_photons_done();
  snapshot.photons_per_second =
      solver.seconds() > 0.0 ? static_cast<double>(solver.photons_shot()) / solver.seconds() : 0.0;
}

void describe_solution(const Solver& solver, const std::vector<CurveTrace>& traces, Snapshot& snapshot) {
  const Scene& scene = solver.scene();
  snapshot.radiosity.clear();
  snapshot.nodes.clear();
  snapshot.radiosity.resize(scene.curves.size());
  snapshot.nodes.resize(scene.curves.size());
  snapshot.detected.assign(scene.curves.size(), {});
  // Power per unit length per bin.
  for (DetectorReading& reading : solver.detector_readings()) {
    const double bin_length = scene.curves[reading.curve].length / static_cast<double>(reading.front.size());
    for (std::vector<Spectrum>* bins : {&reading.front, &reading.back})
      for (Spectrum& value : *bins)
        for (double& channel : value) channel /= bin_length;
    snapshot.detected[reading.curve] = {std::move(reading.front), std::move(reading.back)};
  }
  snapshot.received_share.assign(scene.curves.size(), 0.0);
  double total_reflected = 0.0;
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    const CurveTrace& trace = traces[c];
    for (Side side : {Side::Front, Side::Back}) {
      if (!solver.has_side(c, side)) continue;
      auto& samples = snapshot.radiosity[c][static_cast<std::size_t>(side)];
      samples.reserve(trace.u.size());
      for (double u : trace.u) samples.push_back(solver.radiosity(c, side, u));
      const std::vector<double> b = solver.radiosity_coefficients(c, side);
      const CurveStorage& storage = solver.storage(c);
      const auto channels = static_cast<std::size_t>(scene.channels);
      for (std::size_t k = 0; k < b.size(); ++k)
        snapshot.received_share[c] += b[k] * storage.basis_length[k / channels];
    }
    total_reflected += snapshot.received_share[c];
    const Curve& curve = scene.curves[c];
    for (const MeshNode& node : solver.storage(c).nodes) {
      const auto segment =
          static_cast<std::uint32_t>(std::clamp(std::floor(node.u), 0.0, static_cast<double>(curve.segment_count - 1)));
      const double t = node.u - segment;
      const bool joint = t == 0.0 || t == 1.0;
      const SceneSegment& piece = scene.segments[curve.first_segment + segment];
      snapshot.nodes[c].push_back({evaluate(piece.geometry.shape, t),
                                   curve.segment_start[segment] + piece.arc_length.length_at(piece.geometry.shape, t),
                                   node.continuity, !joint && node.continuity == Continuity::C0});
    }
    // A closed curve is one loop: its closing point is a node too (C1 or C0 where the storage wraps
    // round, C-1 at a corner or a seam).
    if (curve.closed)
      snapshot.nodes[c].push_back(
          {scene.segments[curve.first_segment].geometry.shape.p[0], curve.length, solver.storage(c).closing, false});
  }
  if (total_reflected > 0.0)
    for (double& share : snapshot.received_share) share /= total_reflected;
}

void describe_solver(const Solver& solver, const std::vector<CurveTrace>& traces, Snapshot& snapshot) {
  describe_progress(solver, snapshot);
  describe_solution(solver, traces, snapshot);
}

Session::Session(Threading threading) : threading_(threading) {
  snapshot_ = std::make_shared<const Snapshot>();
  if (threading_ == Threading::Inline) {
    piece_seconds_ = kInlinePieceSeconds;
    return;
  }
  // (A thread that the system refuses throws std::system_error, which Viewer::create reports.)
  thread_ = std::thread([this] { worker(); });
}

Session::~Session() {
  {
    std::lock_guard lock(mutex_);
    quit_ = true;
    cancel_.store(true);
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void Session::restart(std::shared_ptr<const Scene> scene, const SolverSettings& settings) {
  {
    std::lock_guard lock(mutex_);
    restart_pending_ = true;
    pending_scene_ = std::move(scene);
    pending_settings_ = settings;
    steps_.clear();
    // Under the lock, so the worker cannot have reset it for the new solve already: a long step
    // of the old solve ends early; that solver is discarded.
    cancel_.store(true);
  }
  wake_.notify_all();
}

void Session::set_running(bool running) {
  {
    std::lock_guard lock(mutex_);
    running_ = running;
    // A pause shows the answer as far as it has been shot (a running piece describes it only
    // every so often).
    if (!running) refresh_pending_ = true;
  }
  wake_.notify_all();
}

bool Session::running() const {
  std::lock_guard lock(mutex_);
  return running_ && can_run_;
}

void Session::step(StepKind kind, std::uint64_t count) {
  {
    std::lock_guard lock(mutex_);
    running_ = false;
    if (count > 0) steps_.push_back({kind, count, next_step_id_++});
  }
  wake_.notify_all();
}

void Session::set_path_limit(std::size_t count) {
  std::lock_guard lock(mutex_);
  path_limit_ = count;
}

void Session::set_reference(std::shared_ptr<const SampledResult> reference) {
  {
    std::lock_guard lock(mutex_);
    reference_ = std::move(reference);
    refresh_pending_ = true;  // republish with the new reference's numbers
    reference_changed_ = true;
  }
  wake_.notify_all();
}

std::shared_ptr<const Snapshot> Session::snapshot() const {
  std::lock_guard lock(mutex_);
  return snapshot_;
}

void Session::wait_idle() {
  if (threading_ == Threading::Inline) {
    while (work_once()) {
    }
    return;
  }
  std::unique_lock lock(mutex_);
  idle_.wait(lock, [&] {
    return !busy_ && !restart_pending_ && !refresh_pending_ && steps_.empty() && !(running_ && can_run_);
  });
}

Result<nlohmann::json> Session::result_json(int samples_per_curve) {
  std::lock_guard lock(solver_mutex_);
  if (!solver_) return Error{error_.empty() ? "nothing solved yet" : error_};
  if (gather_) return result_to_json(*solver_, samples_per_curve, gather_->gather_result(*solver_, samples_per_curve));
  return result_to_json(*solver_, samples_per_curve);
}

void Session::publish(Solver* solver, const std::vector<PathRecord>& new_paths, bool force) {
  auto snapshot = std::make_shared<Snapshot>();
  std::shared_ptr<const SampledResult> reference;
  std::size_t limit = 0;
  {
    std::lock_guard lock(mutex_);
    reference = reference_;
    limit = path_limit_;
    snapshot->running = running_;
  }
  for (const PathRecord& path : new_paths) paths_.push_back(path);
  while (paths_.size() > limit) paths_.pop_front();
  if (field_changes_ != field_version_) {
    const auto now = std::chrono::steady_clock::now();
    // Manual steps (force) show what they shot at once, as their paths do.
    if (!field_image_ || force || (solver != nullptr && solver->stopped()) ||
        std::chrono::duration<double>(now - field_time_).count() >= kFieldSeconds) {
      if (round_recorded_ == 0) {
        field_image_ = field_image(field_);
      } else {
        LightField with_open = field_;
        with_open.add(round_field_, static_cast<double>(round_shot_) / static_cast<double>(round_recorded_),
                      static_cast<double>(round_shot_));
        field_image_ = field_image(with_open);
      }
      field_version_ = field_changes_;
      field_time_ = now;
    }
  }

  snapshot->generation = generation_;
  snapshot->scene = scene_;
  snapshot->traces = traces_;
  snapshot->error = error_;
  snapshot->paths.assign(paths_.begin(), paths_.end());
  snapshot->field = field_image_;
  if (solver != nullptr && scene_) {
    describe_progress(*solver, *snapshot);
    const Clock::time_point start = Clock::now();
    const double since = std::chrono::duration<double>(start - solution_time_).count();
    if (!solution_valid_ || force || solver->stopped() || solver->rounds() != solution_rounds_ ||
        since >= std::min(kSolutionSeconds, solution_cost_ / kSolutionShare)) {
      solver->include_open_round();
      describe_solution(*solver, *traces_, solution_);
      solution_valid_ = true;
      solution_rounds_ = solver->rounds();
      solution_time_ = start;
      solution_cost_ = std::chrono::duration<double>(Clock::now() - start).count();
    }
    snapshot->radiosity = solution_.radiosity;
    snapshot->nodes = solution_.nodes;
    snapshot->detected = solution_.detected;
    snapshot->received_share = solution_.received_share;
    // The estimated error: R (or 2R) reconstructions of the whole scene, so about twice a second of
    // solving, and once more when the solve stops.
    const double now = solver->seconds();
    const bool final = solver->stopped();
    if (solver->photons_shot() > 0 && !solver->round_open() &&
        (last_estimate_time_ < 0.0 || now - last_estimate_time_ >= 0.5 || (final && !estimate_final_))) {
      last_estimate_time_ = now;
      estimate_final_ = final;
      const double confidence = solver->settings().confidence;
      // Once stopped, the estimate is the gathered answer's, as solve reports it.
      estimate_gathered_ = final && gather_ != nullptr;
      estimated_error_ =
          estimate_error(*solver, {confidence, Solver::kTargetSamples, estimate_gathered_ ? gather_.get() : nullptr});
      std::vector<std::vector<double>> parameters;
      for (const CurveTrace& trace : *traces_) parameters.push_back(trace.u);
      error_band_ = std::make_shared<const std::vector<std::array<std::vector<double>, 2>>>(
          pointwise_bound(*solver, parameters, confidence));
    }
    snapshot->estimated_error = estimated_error_;
    snapshot->estimate_gathered = estimate_gathered_;
    snapshot->gather_skipped = gather_skipped_;
    snapshot->variate_skipped = solver->control_variate_skipped();
    snapshot->error_band = error_band_;
    if (reference) {
      // The error against the reference, at most about twice a second while running.
      if (force || last_error_time_ < 0.0 || now - last_error_time_ >= 0.5 || solver->stopped()) {
        last_error_time_ = now;
        const int samples = reference_samples(*reference);
        if (samples > 0) {
          // Once stopped with a gather, the gathered answer is judged, as solve --reference judges it.
          Result<Comparison> comparison = compare_sampled(
              solver->stopped() && gather_ != nullptr
                  ? gather_->gather_result(*solver, samples)
                  : sample_radiosity(
                        solver->scene(), samples,
                        [solver](std::uint32_t c, Side side, double u) { return solver->radiosity(c, side, u); }),
              *reference);
          if (comparison) {
            reference_error_ = comparison->scene.l2;
            if (error_history_.empty() || error_history_.back()[0] != now)
              error_history_.push_back({now, comparison->scene.l2});
          } else {
            reference_error_.reset();
            snapshot->error = "reference: " + comparison.error().message;
          }
        }
      }
      snapshot->reference_error = reference_error_;
      snapshot->error_history = error_history_;
      snapshot->reference_curves = reference_curves(*reference);
    }
  }
  std::lock_guard lock(mutex_);
  snapshot_ = std::move(snapshot);
}

void Session::pump(double seconds) {
  if (threading_ != Threading::Inline) return;
  const Clock::time_point end =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds));
  // Another command only where one as long as the last still ends in time: a piece is adapted to
  // about the whole budget, so a second one would double the frame.
  for (Clock::time_point start = Clock::now();;) {
    if (!work_once()) return;
    const Clock::time_point now = Clock::now();
    if (now + (now - start) >= end) return;
    start = now;
  }
}

bool Session::has_work() const {
  return restart_pending_ || refresh_pending_ || reference_changed_ || !steps_.empty() || (running_ && can_run_);
}

void Session::worker() {
  for (;;) {
    {
      std::unique_lock lock(mutex_);
      busy_ = false;
      idle_.notify_all();
      wake_.wait(lock, [&] { return quit_ || has_work(); });
      if (quit_) return;
    }
    work_once();
  }
}

bool Session::work_once() {
  std::unique_lock lock(mutex_);
  if (quit_ || !has_work()) {
    busy_ = false;
    return false;
  }
  busy_ = true;
  if (restart_pending_) {
    restart_pending_ = false;
    std::shared_ptr<const Scene> scene = std::move(pending_scene_);
    const SolverSettings settings = pending_settings_;
    cancel_.store(false);
    lock.unlock();
    start_solve(std::move(scene), settings);
    return true;
  }
  if (reference_changed_) {
    // Only the worker touches the history; it starts over with the new reference.
    reference_changed_ = false;
    lock.unlock();
    std::lock_guard solver_lock(solver_mutex_);
    clear_error_history();
    return true;
  }
  if (refresh_pending_ && steps_.empty() && !(running_ && can_run_)) {
    refresh_pending_ = false;
    lock.unlock();
    std::lock_guard solver_lock(solver_mutex_);
    publish(solver_ ? &*solver_ : nullptr, {}, true);
    return true;
  }
  const std::optional<Piece> piece = next_piece();
  if (!piece) return true;
  lock.unlock();
  shoot_piece(*piece);
  return true;
}

void Session::clear_error_history() {
  error_history_.clear();
  reference_error_.reset();
  last_error_time_ = -1.0;
  estimated_error_.reset();
  error_band_.reset();
  last_estimate_time_ = -1.0;
  estimate_final_ = false;
}

void Session::start_solve(std::shared_ptr<const Scene> scene, const SolverSettings& settings) {
  std::lock_guard solver_lock(solver_mutex_);
  solver_.reset();
  gather_.reset();
  gather_skipped_.clear();
  estimate_gathered_ = false;
  paths_.clear();
  next_serial_ = 0;
  field_ = LightField{};
  round_field_ = LightField{};
  round_flights_ = 0;
  round_recorded_ = 0;
  round_shot_ = 0;
  field_image_.reset();
  field_version_ = field_changes_;
  clear_error_history();
  solution_valid_ = false;
  chunk_ = Solver::kBatchSize;
  ++generation_;
  if (scene_ != scene) {
    scene_ = scene;
    traces_ = scene_ ? std::make_shared<const std::vector<CurveTrace>>(trace_curves(*scene_)) : nullptr;
  }
  error_.clear();
  if (scene_) {
    if (Result<LightField> field = LightField::for_scene(*scene_, kFieldResolution)) {
      round_field_ = *field;
      field_ = std::move(*field);
    }
    Result<GatherChoice> choice = choose_gather(*scene_, settings, Solver::kTargetSamples);
    // The set-up (the control variate's coarse solve and projection) ends early when a restart or
    // the viewer's end sets cancel_; the restart then starts the next solve, so it is no error.
    Result<Solver> created = choice ? create_solver(*scene_, settings, &cancel_) : Result<Solver>(choice.error());
    if (created) {
      solver_.emplace(std::move(*created));
      gather_ = std::move(choice->gather);
      gather_skipped_ = choice->skipped;
      if (gather_) solver_->check_target_through(gather_.get());
    } else if (created.error().message != kSolverCancelled) {
      error_ = created.error().message;
    }
  }
  publish(solver_ ? &*solver_ : nullptr, {}, true);
  std::lock_guard relock(mutex_);
  can_run_ = solver_ && !solver_->stopped();
}

std::optional<Session::Piece> Session::next_piece() {
  // This piece: a part of the first queued step (manual steps are shot in pieces of about 50 ms,
  // so they publish as they go and a restart or Ctrl+E never waits long), or a running piece.
  Piece piece;
  if (!steps_.empty()) {
    piece.stepping = true;
    piece.step_id = steps_.front().id;
    piece.kind = steps_.front().kind;
    if (!can_run_) {
      steps_.pop_front();
      return std::nullopt;
    }
    const std::uint64_t done = solver_->round_photons_done();
    switch (piece.kind) {
      case StepKind::Photon: piece.count = std::min(steps_.front().count, chunk_); break;
      case StepKind::Batch: piece.count = Solver::kBatchSize - done % Solver::kBatchSize; break;
      case StepKind::Round:
        piece.count = std::min(chunk_, solver_->round_open() ? solver_->round_photons() - done : chunk_);
        break;
    }
  } else {
    // End on a batch boundary, so every batch of a running piece is shared among the threads.
    piece.count = chunk_ - solver_->round_photons_done() % Solver::kBatchSize;
  }
  refresh_pending_ = false;  // the piece publishes
  piece.path_limit = path_limit_;
  return piece;
}

void Session::shoot_piece(const Piece& piece) {
  std::lock_guard solver_lock(solver_mutex_);
  if (!solver_) return;
  Solver& solver = *solver_;
  std::vector<PhotonPath> shot_paths;
  const std::uint32_t round = solver.rounds();
  const Clock::time_point start = Clock::now();
  // Paths: all of a manual step (up to the kept number), or the first photons of a running step,
  // about as many as a frame can draw (a subset of the photons is what the eye can follow anyway).
  // The light field takes the round's first kFieldFlightsPerRound flights when paths are kept.
  const std::size_t shown = piece.stepping ? piece.path_limit : std::min<std::size_t>(piece.path_limit, kPathsPerStep);
  // (Only a record that covers the round from its first photon: paths may have been switched on
  // mid-round.)
  const std::uint64_t done_before = solver.round_open() ? solver.round_photons_done() : 0;
  const bool continues = done_before == round_shot_;
  const std::size_t for_field =
      shown > 0 && continues && round_flights_ < kFieldFlightsPerRound ? kFieldFlightsPerRound - round_flights_ : 0;
  const std::size_t recorded = std::max(shown, for_field);
  const std::uint64_t shot = solver.step_photons(piece.count, &cancel_, recorded > 0 ? &shot_paths : nullptr, recorded);
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  if (shot >= Solver::kBatchSize) adapt_chunk(solver, shot, seconds);
  const Transport transport = solver.settings().transport;
  // The piece continues the round's record for the field while that is short: its photons follow
  // the record's without a gap (every earlier piece of the round was recorded whole).
  if (for_field > 0) {
    round_flights_ += std::min(for_field, shot_paths.size());
    round_recorded_ += round_field_.add_flights(shot_paths, for_field, transport);
  }
  if (shown > 0 && continues) {
    round_shot_ += shot;
    ++field_changes_;
  }
  // A round ends: its record, standing for all its photons, joins the field. (A field that holds
  // whole rounds only is the same whatever pieces the rounds were shot in.)
  if (!solver.round_open()) {
    if (round_recorded_ > 0)
      field_.add(round_field_, static_cast<double>(round_shot_) / static_cast<double>(round_recorded_),
                 static_cast<double>(round_shot_));
    if (round_flights_ > 0) round_field_.clear();
    round_flights_ = 0;
    round_recorded_ = 0;
    round_shot_ = 0;
  }
  truncate_record(shot_paths, shown, transport);
  std::vector<PathRecord> records;
  records.reserve(shot_paths.size());
  for (const PhotonPath& path : shot_paths) append_path_records(path, *scene_, next_serial_, round, records);
  publish(&solver, records, piece.stepping);
  std::lock_guard relock(mutex_);
  can_run_ = !solver.stopped();
  if (!can_run_) running_ = false;  // run until the solve stops, then it is paused
  if (piece.stepping) count_step(piece, solver, shot);
}

void Session::adapt_chunk(const Solver& solver, std::uint64_t shot, double seconds) {
  // About piece_seconds_ a piece, in whole batches, at least one per thread.
  const double rate = static_cast<double>(shot) / std::max(seconds, 1e-6);
  const auto batches = static_cast<std::uint64_t>(std::clamp(rate * piece_seconds_ / Solver::kBatchSize, 1.0, 1024.0));
  chunk_ = std::max<std::uint64_t>(batches, solver.thread_count()) * Solver::kBatchSize;
}

void Session::count_step(const Piece& piece, const Solver& solver, std::uint64_t shot) {
  // What is left of the step (unless a restart dropped it meanwhile).
  if (steps_.empty() || steps_.front().id != piece.step_id) return;
  Step& step = steps_.front();
  const bool boundary = piece.kind == StepKind::Photon  ? true
                        : piece.kind == StepKind::Batch ? solver.round_photons_done() % Solver::kBatchSize == 0
                                                        : !solver.round_open();
  if (piece.kind == StepKind::Photon)
    step.count -= std::min(step.count, shot);
  else if (boundary)
    --step.count;
  if (shot == 0 || step.count == 0 || !can_run_) steps_.pop_front();
}

}  // namespace flatland::viewer
