// Progressive Monte Carlo shooting (docs/method.md), as a steppable, observable object that the
// command line, the viewer and the tests all drive.
//
// A round shoots the current unshot power with photons of equal power: it picks a source (a side of
// a curve) with probability proportional to its unshot power, a position on it uniformly in arc
// length, a diffuse direction, and traces the photon to its nearest hit, where the power is
// deposited on the receiver's storage basis (weights phi_k(u), summing to one). After the round
// the unshot power becomes rho times what was received, and the next round shoots that, until it
// falls below tolerance x emitted power or the photon budget is spent.
//
// Determinism: photon i of a round belongs to batch i / kBatchSize, whose random stream is named
// by (seed, round, batch), and to a replicate (settings.hpp, ReplicateLayout); with the Sobol' sampler its uniforms
// come first from a point of a scrambled net named by the seed and the round (photon_shooter.cpp). Deposits are
// accumulated in 64-bit fixed point (units of 2^-k of the round's power, k chosen so the round cannot overflow), and
// integer addition does not depend on order, so any number of threads gives bit-identical results.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <variant>
#include <vector>

#include "flatland/base/status.hpp"
#include "flatland/base/workers.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/transport/light_transport.hpp"
#include "flatland/transport/photon_shooter.hpp"
#include "flatland/transport/round_sharing.hpp"
#include "flatland/transport/sampling.hpp"
#include "flatland/transport/scene_storage.hpp"
#include "flatland/transport/settings.hpp"
#include "flatland/transport/shooting.hpp"
#include "flatland/transport/walks.hpp"

namespace flatland {

class ReflectedEvaluator;  // error_estimate.hpp
class CoarseAnswer;        // control_variate.hpp

enum class StopReason { Running, Converged, BudgetSpent, Cancelled, BooksUnbalanced, TargetReached };

// Reflected radiosity B - E as a solver reconstructs it from received power: B-spline coefficients
// (finest layout, per coefficient and channel, times the side's reflectivity) and, with Hermite
// storage, each block's reconstruction per channel (in arc length).
struct ReflectedField {
  std::vector<double> coefficients;
  std::vector<std::vector<HermiteReconstruction>> hermite;
};
const char* to_string(StopReason reason);

// A detector curve's tallies (Solver::detector_readings): per bin of its arc length the power that
// crossed it arriving on its front side (`front`) and on its back (`back`), per channel.
struct DetectorReading {
  std::uint32_t curve = 0;
  std::vector<Spectrum> front;
  std::vector<Spectrum> back;
  Spectrum front_total{};
  Spectrum back_total{};
};

struct SolverProgress {
  std::uint64_t photons = 0;  // shot so far
  std::uint64_t budget = 0;
  std::uint32_t rounds = 0;      // completed
  double unshot_fraction = 1.0;  // unshot / emitted at the start of the current round
  double seconds = 0.0;          // wall time spent shooting
};
using ProgressCallback = std::function<void(const SolverProgress&)>;

// The message of the error a cancelled Solver::create returns.
inline constexpr const char* kSolverCancelled = "the solve was cancelled while it was being set up";

class Solver {
 public:
  // Photon i of a round belongs to batch i / kBatchSize, whose random stream is named by (seed,
  // round, batch): the unit in which rounds are shared among threads and processes, and between
  // checks for a cancel.
  static constexpr std::uint64_t kBatchSize = 4096;
  // Solving to an accuracy: the first pass's photons, and the samples per curve the target is
  // checked at (flatland solve's default --samples).
  static constexpr std::uint64_t kFirstPassPhotons = std::uint64_t{1} << 15;
  static constexpr int kTargetSamples = 100;
  // Solving to an accuracy, the estimate checked is that of B - E as `evaluator` gives it (a final
  // gather's: reference/final_gather.hpp), or the storage's own (null, the default). The evaluator
  // must outlive the solve.
  void check_target_through(const ReflectedEvaluator* evaluator) { target_evaluator_ = evaluator; }

  // `cancel` is checked between the curves' storage levels (building them all for a large budget
  // takes a moment): once it is set, create returns the error kSolverCancelled.
  // With settings.control_variate coarse, `coarse` is the coarse answer (reference/coarse_answer.hpp's
  // create_solver solves it and calls this); with auto, the solver runs coarse when it is given one
  // and none without (settings().control_variate says which).
  static Result<Solver> create(const Scene& scene, const SolverSettings& settings,
                               const std::atomic<bool>* cancel = nullptr,
                               std::shared_ptr<const CoarseAnswer> coarse = nullptr);

  // Shoot one whole round; returns false (and does nothing) once the solve has stopped.
  // `progress` is called from the calling thread about every `progress_interval` seconds.
  bool step_round(const std::atomic<bool>* cancel = nullptr, const ProgressCallback& progress = {},
                  double progress_interval = 0.25);
  // Shoot up to `max_photons` photons of the current round: the next round is opened first when
  // none is open, and closed (its deposits reflected into the pool) when its last photon is shot.
  // Returns the number shot, 0 once the solve has stopped. Any sequence of steps gives results
  // bit-identical to whole rounds (a batch left half done keeps its random stream for the next
  // step). Paths of the photons shot are appended to `paths` while it holds fewer than
  // `path_limit`. Cancelling stops the solve (StopReason::Cancelled).
  std::uint64_t step_photons(std::uint64_t max_photons, const std::atomic<bool>* cancel = nullptr,
                             std::vector<PhotonPath>* paths = nullptr, std::size_t path_limit = 0,
                             const ProgressCallback& progress = {}, double progress_interval = 0.25);
  // Whether a round has been opened by step_photons and not yet finished, its photon count and
  // how many of them have been shot.
  bool round_open() const { return round_open_; }
  std::uint64_t round_photons() const { return round_open_ ? round_.photons : 0; }
  std::uint64_t round_photons_done() const { return round_open_ ? round_done_ : 0; }
  // While a round is open, radiosity() describes the completed rounds. This adds the open round's
  // deposits so far (as received, not extrapolated), so a viewer sees light arrive photon by
  // photon; closing the round replaces it with the round's exact estimate.
  void include_open_round();
  // Rounds until converged, budget spent or cancelled. The radiosity readers are brought up to
  // date when it returns (not between its rounds: a progress report must not read them).
  void run(const std::atomic<bool>* cancel = nullptr, const ProgressCallback& progress = {},
           double progress_interval = 0.25);

  bool stopped() const { return stop_reason_ != StopReason::Running; }
  StopReason stop_reason() const { return stop_reason_; }
  const std::string& books_error() const { return books_error_; }

  const Scene& scene() const { return *scene_; }
  const SolverSettings& settings() const { return settings_; }
  // The worker threads that run: those asked for, or fewer once the system refused to start some
  // (results are the same bits on any count); thread_shortfall() then says so, else it is empty.
  unsigned thread_count() const { return pool_.started() != nullptr ? pool_.started()->threads() : threads_; }
  std::string thread_shortfall() const {
    return pool_.started() != nullptr ? pool_.started()->shortfall() : std::string();
  }
  std::uint64_t photons_shot() const { return photons_shot_; }
  // Rays cast in finished rounds: one per photon when shooting point rays or footprints, a band's
  // sub-rays each, and every hop of a walk.
  std::uint64_t rays_traced() const { return rays_traced_; }
  // Photons shot including those of a round that a cancel cut short (their deposits are dropped,
  // so they are not in photons_shot() or the books): what "interrupted after N photons" says.
  std::uint64_t photons_traced() const { return photons_shot_ + photons_cancelled_; }
  std::uint32_t rounds() const { return rounds_; }
  // Photons cut at the specular chain limit (kChainLimit) in finished rounds; their power is the
  // books' `cut` line.
  std::uint64_t chains_cut() const { return chains_cut_; }
  // The detectors' tallies (DetectorLayout, photon_shooter.hpp): the power crossing each bin and
  // side per channel, over finished rounds (with a target error, the passes' photon-weighted mean).
  const DetectorLayout& detector_layout() const { return shooter_.detector_layout(); }
  std::vector<double> detected() const;
  // The same per detector curve, bin by bin each way, with their totals.
  std::vector<DetectorReading> detector_readings() const;
  // With a target error: the passes finished (shooting; docs/estimated-error.md, "Solving to an accuracy")
  // and the estimated error when the target was last checked (infinity before).
  std::uint32_t passes() const { return passes_; }
  double checked_error() const { return checked_error_; }
  double seconds() const { return seconds_; }
  // Transport::Jacobi: the iterations averaged into the answer so far (the current pass's).
  std::uint32_t jacobi_iterations() const {
    const auto* shooting = std::get_if<ProgressiveShooting>(&transport_);
    return shooting != nullptr ? shooting->iterations() : 0;
  }
  // What the pool holds: its power (the books' unshot), or for a control variate's signed pool the
  // sum of its magnitudes.
  double pool_magnitude() const;
  EnergyBooks books() const;
  SolverProgress progress() const;

  // Share every round with other processes (null: this process alone, the default). Every process
  // must create its solver from the same scene and settings and step it by whole rounds (a
  // step_photons call finishes the open round); a cancel on any of them cancels all. Paths are
  // those of the batches this process shot; seconds() its own wall time.
  void share_rounds(RoundSharing* sharing) { sharing_ = sharing; }
  const RoundSharing* round_sharing() const { return sharing_; }
  // Bytes this solver handed to the sharing's sum (one message per round).
  std::uint64_t bytes_shared() const { return rounds_shared_ * round_message_size() * sizeof(std::int64_t); }

  // Keep the paths of the first `count` photons of every round (0, the default, keeps none).
  void record_paths(std::size_t count) { path_limit_ = count; }
  // Paths of the last round finished by step_round, in photon order: its first photons, or, when
  // step_photons began that round, the first of those step_round shot.
  const std::vector<PhotonPath>& paths() const { return paths_; }

  // Storage of each curve (basis, integrals of the basis functions over arc length).
  const CurveStorage& storage(std::uint32_t curve) const { return storage_.finest(curve); }
  bool has_side(std::uint32_t curve, Side side) const;
  // Nodes of the storage meshes below C1 (value or slope jumps), and how many of them came from
  // visibility events (discontinuity meshing).
  std::size_t discontinuity_nodes() const;
  std::size_t visibility_event_nodes() const { return visibility_events_; }
  // C-1 nodes asked for at contacts (an end point or corner on another curve, a crossing); with
  // discontinuities scene or auto.
  std::size_t contact_nodes() const { return contact_nodes_; }
  // The storage's discontinuity nodes (discontinuity_nodes()) by what put each there, counted
  // once: the scene's corners and joints first, then contacts, then visibility events, then the
  // coarse control variate's element ends (the counts above are the nodes asked for, some of which
  // coincide with others and merge).
  struct NodeSources {
    std::size_t scene = 0;
    std::size_t contacts = 0;
    std::size_t events = 0;
    std::size_t variate = 0;
  };
  const NodeSources& node_sources() const { return node_sources_; }
  std::size_t coefficient_count() const { return storage_.coefficient_count(); }
  // Storage elements (non-empty knot spans) of a curve's mesh in use: with auto storage the level
  // chosen after the last round (coefficients stay in the finest basis, which holds it exactly).
  int storage_elements(std::uint32_t curve) const;
  bool auto_storage() const { return auto_storage_; }
  // The levels a curve's mesh may take: with auto storage the coarsest (kAutoBaseElements
  // elements, at least one a segment) and each halving of it up to the finest; 1 on a fixed mesh.
  int storage_levels(std::uint32_t curve) const { return storage_.level_count(curve); }
  // Radiosity coefficients of a curve side (lumped estimate): coefficient k, channel c at
  // [k * channels + c]; B(u) = E + sum_k b_k phi_k(u). Empty for a side that does not reflect.
  std::vector<double> radiosity_coefficients(std::uint32_t curve, Side side) const;
  // Unshot radiosity coefficients of a curve side (the power waiting to be shot in the next round,
  // per unit length, in the lumped estimate), laid out as radiosity_coefficients. The
  // reconstructed sampler draws photon origins with density proportional to this function.
  std::vector<double> unshot_coefficients(std::uint32_t curve, Side side) const;
  // Radiosity (emitted + reflected power per unit length) leaving a side at curve parameter u.
  Spectrum radiosity(std::uint32_t curve, Side side, double u) const;

  // What the error estimate reads (error_estimate.hpp). The replicates of every round
  // (settings().replicates), and replicate r's estimate of the received power: its part times R
  // (empty with one replicate). The received power of all photons.
  int replicates() const { return settings_.replicates; }
  std::vector<double> replicate_received(int replicate) const;
  const std::vector<double>& received() const { return passes_photons_ > 0.0 ? mixed_received_ : received_; }
  // The reflected radiosity B - E that the received power `received` gives with curve c's storage
  // at level levels[c] (chosen_levels(): what radiosity() shows), and its value on a side at u.
  ReflectedField reflected_field(const std::vector<double>& received, const std::vector<int>& levels) const;
  Spectrum reflected_at(const ReflectedField& field, std::uint32_t curve, Side side, double u) const;
  const std::vector<int>& chosen_levels() const { return storage_.chosen_levels(); }
  const SceneStorage& scene_storage() const { return storage_; }
  // Importance (settings().importance): each curve side's weight, per block (curve * 2 + side;
  // empty without importance), and what the adjoint solve that found them took.
  const std::vector<double>& side_importance() const { return importance_; }
  std::uint64_t importance_photons() const { return importance_photons_; }
  double importance_seconds() const { return importance_seconds_; }
  // The coarse control variate (settings().control_variate): the coarse reference's elements and
  // the seconds its solve and projections took (0 without one).
  std::size_t control_variate_elements() const { return variate_elements_; }
  double control_variate_seconds() const { return variate_seconds_; }
  // The control variate's own discretisation, estimated: g over the coarse chords less g over the
  // finer ones, over the ratio of their errors less one (per coefficient and channel, as received
  // power; empty without the variate or where the scene has no curves to model, only lines).
  const std::vector<double>& control_variate_bias() const { return variate_bias_; }
  // The magnitude of the difference D the photons start from (sum of |d_k|) over the emitted power.
  double control_variate_source_fraction() const { return variate_source_fraction_; }
  // Why --control-variate auto runs without the variate (empty where it runs it, or was not asked
  // for auto): create_solver's reason, reported by every front end.
  const std::string& control_variate_skipped() const { return variate_skipped_; }
  void set_control_variate_skipped(std::string reason) { variate_skipped_ = std::move(reason); }

  // The storage coefficients (the finest level's, over every side that stores light, one channel)
  // that create would make at most: what a caller sizes work by before building anything.
  static double coefficient_bound(const Scene& scene, const SolverSettings& settings);

  // What Solver::create refuses of `settings` on `scene` without building anything (the scene's
  // optics, spectra and emitters against the transport and storage, and the curves importance
  // names): for a caller that checks many settings before any work (converge's methods).
  static Status check_settings_on(const Scene& scene, const SolverSettings& settings);

 private:
  Solver() = default;

  // The set-up's steps (Solver::create).
  static Status check_scene(const Scene& scene, const SolverSettings& settings);
  static StoragePlan plan_storage(const Scene& scene, const SolverSettings& settings);
  // The storage mesh's extra nodes: contacts (C-1, where footprints also stop: `walls`, per curve
  // in arc length) and visibility events (C0), as the settings ask, on the curves that hold light.
  // Stops early (with partial nodes) once `cancel` is set.
  // Counts node_sources_ from the storage's nodes and find_events' lists.
  void count_node_sources(const std::vector<std::vector<MeshNode>>& events);
  std::vector<std::vector<MeshNode>> find_events(const SegmentAccelerator& accelerator, const StoragePlan& plan,
                                                 std::vector<std::vector<double>>& walls,
                                                 const std::atomic<bool>* cancel);
  // The power the emitters put on each coefficient (E times the basis integrals), the emitted
  // books, and the transport that starts from it.
  Status start_transport(const std::atomic<bool>* cancel);

  LightTransport& transport() {
    return std::visit([](auto& t) -> LightTransport& { return t; }, transport_);
  }
  const LightTransport& transport() const {
    return std::visit([](const auto& t) -> const LightTransport& { return t; }, transport_);
  }
  // The round a batch of photons belongs to, as the shooter reads it.
  RoundView round_view() const;

  bool begin_round();
  // The sources of the round (sides of curves, or coefficients for reconstructed origins) and the
  // units each one's photons carry, from the pool `pool` of `pool_power`.
  void plan_sources(const std::vector<double>& pool, const std::vector<Spectrum>& block_unshot, double pool_power);
  // plan_sources for a signed pool: sources by the magnitude of their power, photons with its signs.
  void plan_signed_sources(const std::function<const double*(std::size_t)>& source_power);
  // The coarse control variate (its answer kept in coarse_ until the transport starts): its elements'
  // ends added to `events` as value jumps; then g, the source d (replacing `emission`) and the
  // exact part's books.
  void add_coarse_nodes(std::vector<std::vector<MeshNode>>& events);
  // The power the tolerance is a fraction of: the emitted power, or with the control variate the
  // magnitude of the difference D its photons start from (so that the light left unshot is as small
  // a share of what the photons carry as without it).
  double tolerance_power() const { return signed_pool_ ? variate_source_fraction_ * emitted_total_ : emitted_total_; }

  Status start_control_variate(std::vector<double>& emission, const std::atomic<bool>* cancel);
  // Every estimate's received power and replicates' parts before any photon: g (and g / R each), or
  // zero.
  void start_received();
  // The same with importance: sources chosen by power times their side's importance, and each
  // side's photons, counted first, carrying its power between them (`by_coefficient`: the sources
  // are coefficients, else curve sides; `source_power(j)`: source j's power per channel). False
  // (nothing planned) for a round of emitted light in which some side with power would draw no
  // photon.
  bool plan_important_sources(const std::vector<double>& pool, bool by_coefficient,
                              const std::function<const double*(std::size_t)>& source_power);
  void end_round(std::span<const Deposits> deposits);
  // Always-on: emitted = absorbed + escaped + unshot within the fixed point's rounding, or the
  // solve stops (StopReason::BooksUnbalanced).
  void check_books();
  // readers_ from the power received in all rounds.
  // `choice`: with automatic storage, whether the levels are chosen again (Scheduled: when the
  // photons shot have grown by kLevelChoiceGrowth since the last choice; View: for a reader's view
  // of an open round, chosen again when the photons have grown by kLevelChoiceGrowth since the
  // last choice of either kind, never moving the solve's schedule; Final: always, at the end of the
  // solve).
  enum class LevelChoice { Scheduled, View, Final };
  // With automatic storage, the levels chosen from all the photons when the solve stops.
  void choose_final_levels();
  // `variance_factor`: what sum_odd_parts returned for `received_half`.
  void update_reflected(const std::vector<double>& received, const std::vector<double>& received_half,
                        double variance_factor, LevelChoice choice = LevelChoice::Scheduled);
  // Solving to an accuracy. With shooting, a target error is reached in passes: each a whole
  // progressive solve of its own budget from the emitted power (rounds numbered on, so with fresh
  // random streams), the solution their average weighted by photons. begin_round ends a pass when
  // its pool has converged or its budget is spent, and checks the target: met, or the cap spent,
  // ends the solve; else the next pass, of about the photons the estimate asks for, at most as many
  // as all before it. Walks check the target after every round (each round estimates the whole).
  // Returns whether the solve goes on.
  bool next_pass_or_stop(double unshot);
  // A pass's unshot-power tolerance: the settings' or, when smaller, a tenth of the target (light
  // left unshot adds to the estimated error, and no pass may leave more than the target allows).
  double pass_tolerance() const { return std::min(settings_.tolerance, 0.1 * settings_.target_error); }
  // The budget a shooting transport averages Jacobi iterations over (Transport::Jacobi), else 0.
  std::uint64_t averaged_budget(std::uint64_t budget) const {
    return settings_.transport == Transport::Jacobi ? budget : 0;
  }
  bool target_met();
  // The finished passes and the current one mixed (received_ and received_parts_ of the current
  // pass with passes_received_ and passes_parts_), into mixed_received_ and mixed_parts_.
  void mix_passes();
  // out = the photon-weighted mean of the finished passes (`passes`, each value times its photons)
  // and the current one; element by element, so `out` may be `current`.
  void passes_mean(const std::vector<double>& passes, const std::vector<double>& current,
                   std::vector<double>& out) const;
  // `half` = the sum of the odd replicates' parts in `parts`. Returns the factor on the variance the
  // halves' difference shows: replicates laid out as blocks of one net are stratified against each
  // other, and so are the halves (settings.hpp, stratification_factor, from the parts pooled over
  // the coefficients); 1 for independent replicates and the random sampler.
  double sum_odd_parts(const std::vector<double>& parts, std::vector<double>& half) const;
  // The readers' state (readers_) from `received` at the chosen levels.
  void refresh_readers(const std::vector<double>& received);
  // The Hermite reconstruction of every block side's `power` (finest layout, channels summed, at
  // each curve's chosen level): the density reconstructed origins are drawn from.
  void update_hermite_unshot(const std::vector<double>& power);
  // f(c) for every curve, shared among the threads in runs of curves (SceneStorage::curve_chunks);
  // f must write only curve c's own coefficients.
  void for_each_curve(const std::function<void(std::uint32_t)>& f);
  // With sharing: the threads' deposits added into round_deposits_[0], then over all processes,
  // with this process's photons shot and whether it was cancelled; returns the totals of both.
  std::pair<std::uint64_t, bool> share_round(std::uint64_t photons_done, bool aborted);
  // The entries of one round's message: the deposits, the detectors' tallies, 22 counters (escaped,
  // absorbed, shot and the three chain losses per channel, chains cut, rays, photons, the cancel).
  std::size_t round_message_size() const;

  const Scene* scene_ = nullptr;
  SolverSettings settings_;  // the estimator resolved
  unsigned threads_ = 1;
  int channels_ = 1;
  bool auto_storage_ = false;
  SceneStorage storage_;
  PhotonShooter shooter_;
  std::variant<ProgressiveShooting, RandomWalks> transport_;
  std::size_t visibility_events_ = 0;
  std::size_t contact_nodes_ = 0;
  NodeSources node_sources_;
  std::vector<std::size_t> contacts_per_curve_;  // set-up: each curve's contacts in find_events' lists
  Spectrum emitted_{};
  double emitted_total_ = 0.0;

  // What the solution is made of. Shooting: all rounds' received power; walks: each round's
  // tallies estimate the whole received power, and this is their average weighted by walks. With
  // more than one replicate, received_parts_ holds each replicate's part of it ([r * size + index],
  // the same rule applied to its photons alone); with automatic storage, received_half_ is the part
  // from odd-numbered photons (the odd replicates').
  std::vector<double> received_;  // [coefficient * channels + channel]
  std::vector<double> received_parts_;
  std::vector<double> received_half_;
  double half_variance_factor_ = 1.0;  // sum_odd_parts' factor for received_half_
  // Passes (next_pass_or_stop): the emitted power each pass starts from, the first guess of the
  // pool's decay, the current pass's budget and first photon and round, the finished passes'
  // photons, their received power, parts and books summed times their photons, and the mix of
  // those with the current pass that readers see once a pass has finished.
  std::vector<double> emission_;
  double decay_ = 0.5;
  std::uint64_t pass_budget_ = 0;
  std::uint64_t pass_first_photon_ = 0;
  std::uint32_t pass_first_round_ = 0;
  std::uint32_t passes_ = 0;
  double passes_photons_ = 0.0;
  std::vector<double> passes_received_;
  std::vector<double> passes_parts_;
  EnergyBooks passes_books_;
  std::vector<double> mixed_received_;
  std::vector<double> mixed_parts_;
  double checked_error_ = std::numeric_limits<double>::infinity();
  const ReflectedEvaluator* target_evaluator_ = nullptr;
  // What the readers see: the reflected radiosity of received_ at the chosen levels.
  ReflectedField readers_;
  // Hermite basis only: the unshot density per block (channels summed, in arc length) that
  // reconstructed origins are drawn from.
  std::vector<HermiteReconstruction> hermite_unshot_;
  // While run() goes, update_reflected leaves the readers' state stale (readers_stale_) for run to
  // refresh once when it returns.
  bool defer_readers_ = false;
  bool readers_stale_ = false;

  // Automatic storage's schedule. Choosing levels estimates every level three times (all photons
  // and the two halves): per round that cost 2-3x the photons' own time in stiff scenes of
  // thousands of small rounds. So levels are chosen again only when the photons shot have grown by
  // this factor since the last choice (and once more when the solve stops), which is deterministic
  // and independent of how rounds are stepped; in between, the last scheduled choice is kept.
  static constexpr double kLevelChoiceGrowth = 1.25;
  std::vector<int> scheduled_level_;
  std::uint64_t photons_at_choice_ = 0;
  // The photons shot when a view of an open round last chose the levels (LevelChoice::View).
  std::uint64_t photons_at_view_choice_ = 0;

  // The round.
  RoundPlan round_;
  std::vector<double> source_weights_;  // plan_sources' scratch, kept between rounds
  std::vector<double> density_power_;
  // Importance (importance.hpp): per block, the weight its sources' power takes (empty: none);
  // the adjoint solve's photons and seconds; the pool's power no photon of the round took, which
  // stays in the pool (plan_sources; empty when the round keeps nothing).
  std::vector<double> importance_;
  std::uint64_t importance_photons_ = 0;
  double importance_seconds_ = 0.0;
  std::vector<double> kept_;
  // The coarse control variate (control_variate.hpp): the pool is signed (its power is the sum of
  // magnitudes); every estimate's received power starts at g (variate_received_, per coefficient and
  // channel), and the exact part's books are what its light leaves the scene by and the rest of the
  // emitted power that D does not carry, absorbed.
  bool signed_pool_ = false;
  std::shared_ptr<const CoarseAnswer> coarse_;
  std::vector<std::size_t> coarse_nodes_per_curve_;  // set-up: the coarse ends last in each curve's events
  std::vector<double> variate_received_;
  std::vector<double> variate_bias_;
  Spectrum variate_absorbed_{};
  Spectrum variate_escaped_{};
  std::size_t variate_elements_ = 0;
  double variate_seconds_ = 0.0;
  double variate_source_fraction_ = 0.0;
  std::string variate_skipped_;
  bool round_open_ = false;
  std::uint64_t round_done_ = 0;          // photons of the open round shot so far
  std::vector<Deposits> round_deposits_;  // per worker thread, for the open round
  std::optional<Rng> partial_batch_rng_;  // stream of a batch left half done by a step
  // The threads that shoot (and build the storage), started on first use and kept for the
  // solver's life (a copy of the solver starts its own).
  LazyWorkerPool pool_;
  WorkerPool& worker_pool() { return pool_.get(threads_); }
  RoundSharing* sharing_ = nullptr;
  std::uint32_t rounds_shared_ = 0;
  std::size_t path_limit_ = 0;
  std::vector<PhotonPath> paths_;

  std::uint64_t photons_shot_ = 0;
  std::uint64_t photons_cancelled_ = 0;
  std::uint64_t rays_traced_ = 0;
  std::uint64_t chains_cut_ = 0;
  std::vector<double> detected_;         // this pass's (the whole solve's without passes)
  std::vector<double> passes_detected_;  // finished passes', each weighted by its photons
  std::uint32_t rounds_ = 0;
  double seconds_ = 0.0;
  StopReason stop_reason_ = StopReason::Running;
  std::string books_error_;
};

}  // namespace flatland
