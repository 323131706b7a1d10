// Progressive Monte Carlo shooting (DESIGN.md section 5), as a steppable, observable object that the
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
// by (seed, round, batch); with the Sobol' sampler its uniforms come first from point i of the
// round's scrambled sequence, named by (seed, round). Deposits are accumulated in 64-bit fixed point (units of 2^-k of the
// round's power, k chosen so the round cannot overflow), and integer addition does not depend on
// order, so any number of threads gives bit-identical results.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "flatland/storage/curve_storage.hpp"
#include "flatland/storage/estimators.hpp"
#include "flatland/storage/restriction.hpp"
#include "flatland/geometry/accelerator.hpp"
#include "flatland/geometry/discontinuities.hpp"
#include "flatland/transport/footprint.hpp"
#include "flatland/storage/hermite.hpp"
#include "flatland/base/status.hpp"
#include "flatland/transport/round_sharing.hpp"
#include "flatland/transport/sampling.hpp"
#include "flatland/transport/settings.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/base/summation.hpp"
#include "flatland/base/workers.hpp"

namespace flatland {


// Power summed over channels. emitted = absorbed + escaped + unshot after every round.
struct EnergyBooks {
  double emitted = 0.0;
  double absorbed = 0.0;
  double escaped = 0.0;
  double unshot = 0.0;
  double imbalance() const { return emitted - (absorbed + escaped + unshot); }
};

enum class StopReason { Running, Converged, BudgetSpent, Cancelled, BooksUnbalanced };
const char* to_string(StopReason reason);

struct SolverProgress {
  std::uint64_t photons = 0;  // shot so far
  std::uint64_t budget = 0;
  std::uint32_t rounds = 0;   // completed
  double unshot_fraction = 1.0;  // unshot / emitted at the start of the current round
  double seconds = 0.0;          // wall time spent shooting
};
using ProgressCallback = std::function<void(const SolverProgress&)>;

// One photon's flight, kept for inspection (the viewer draws these; tests check the samplers).
struct PhotonPath {
  Vec2 origin;
  Vec2 end;          // the hit point, or origin + direction for a photon that escaped
  bool escaped = false;
  std::uint32_t source_curve = 0;
  Side source_side = Side::Front;
  std::uint32_t source_segment = 0;  // index into Scene::segments
  double source_t = 0.0;
  std::uint32_t hit_curve = 0;       // meaningless when escaped
  Side hit_side = Side::Front;
  double hit_s = 0.0;                // arc length along the hit curve from its start
  Spectrum power{};                  // power carried (channels as in the scene)
  // Times the light carried has been reflected before this flight: shooting's round number, or
  // the hop's number in its walk (0: straight from an emitter). A walk's hops are consecutive
  // paths, its first with bounce 0.
  std::uint32_t bounce = 0;
  // Walks: the walk ended where this flight landed (Russian roulette, or a side that reflects
  // nothing). A flight that escaped ends its walk too (`escaped`).
  bool absorbed = false;
  // Walks: the walk went on after this flight, but the record was full (path_limit).
  bool cut = false;
};


// The message of the error a cancelled Solver::create returns.
inline constexpr const char* kSolverCancelled = "the solve was cancelled while it was being set up";

class Solver {
 public:
  static constexpr std::uint64_t kBatchSize = 4096;
  // Every round shoots at least this many photons (or what is left of the budget): a round of a
  // few photons estimates the pool so coarsely that one photon landing on an absorber could empty
  // it and stop the solve as "converged" far from the answer (a room of rho = 0.9999999 with a
  // black lamp did). Not a whole batch (4096): the reserve for the rounds still expected starved
  // the first rounds of small budgets (docs/method.md, Progressive shooting).
  static constexpr std::uint64_t kMinPhotonsPerRound = 256;
  // And at most this many: the fixed-point deposits quantise each photon's power to 2^-60 of the
  // round's power (half a unit per deposit), so a round of n photons rounds each photon's power
  // by at most n 2^-61 of itself; 2^30 photons keep that below 5e-10.
  static constexpr std::uint64_t kMaxPhotonsPerRound = std::uint64_t{1} << 30;

  // `cancel` is checked between the curves' storage levels (building them all for a large budget
  // takes a moment): once it is set, create returns the error kSolverCancelled.
  static Result<Solver> create(const Scene& scene, const SolverSettings& settings,
                               const std::atomic<bool>* cancel = nullptr);

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
  std::string thread_shortfall() const { return pool_.started() != nullptr ? pool_.started()->shortfall() : std::string(); }
  std::uint64_t photons_shot() const { return photons_shot_; }
  // Rays cast in finished rounds: one per photon when shooting point rays or footprints, a band's
  // sub-rays each, and every hop of a walk.
  std::uint64_t rays_traced() const { return rays_traced_; }
  // Photons shot including those of a round that a cancel cut short (their deposits are dropped,
  // so they are not in photons_shot() or the books): what "interrupted after N photons" says.
  std::uint64_t photons_traced() const { return photons_shot_ + photons_cancelled_; }
  std::uint32_t rounds() const { return rounds_; }
  double seconds() const { return seconds_; }
  EnergyBooks books() const;
  SolverProgress progress() const;

  // Share every round with other processes (null: this process alone, the default). Every process
  // must create its solver from the same scene and settings and step it by whole rounds (a
  // step_photons call finishes the open round); a cancel on any of them cancels all. Paths are
  // those of the batches this process shot; seconds() its own wall time.
  void share_rounds(RoundSharing* sharing) { sharing_ = sharing; }
  const RoundSharing* round_sharing() const { return sharing_; }
  // Bytes this solver handed to the sharing's sum (one message per round).
  std::uint64_t bytes_shared() const { return bytes_shared_; }

  // Keep the paths of the first `count` photons of every round (0, the default, keeps none).
  void record_paths(std::size_t count) { path_limit_ = count; }
  // Paths of the last round finished by step_round, in photon order: its first photons, or, when
  // step_photons began that round, the first of those step_round shot.
  const std::vector<PhotonPath>& paths() const { return paths_; }

  // Storage of each curve (basis, integrals of the basis functions over arc length).
  const CurveStorage& storage(std::uint32_t curve) const { return storage_[curve]; }
  bool has_side(std::uint32_t curve, Side side) const;
  // Nodes of the storage meshes below C1 (value or slope jumps), and how many of them came from
  // visibility events (discontinuity meshing).
  std::size_t discontinuity_nodes() const;
  std::size_t visibility_event_nodes() const { return visibility_events_; }
  // C-1 nodes asked for at contacts (an end point or corner on another curve, a crossing); with
  // discontinuities scene or auto.
  std::size_t contact_nodes() const { return contact_nodes_; }
  std::size_t coefficient_count() const { return coefficient_count_; }
  // Storage elements (non-empty knot spans) of a curve's mesh in use: with auto storage the level
  // chosen after the last round (coefficients stay in the finest basis, which holds it exactly).
  int storage_elements(std::uint32_t curve) const;
  bool auto_storage() const { return auto_storage_; }
  // The levels a curve's mesh may take: with auto storage the coarsest (kAutoBaseElements
  // elements, at least one a segment) and each halving of it up to the finest; 1 on a fixed mesh.
  int storage_levels(std::uint32_t curve) const { return static_cast<int>(levels_[curve].size()) + 1; }
  // Radiosity coefficients of a curve side (lumped estimate): coefficient k, channel c at
  // [k * channels + c]; B(u) = E + sum_k b_k phi_k(u). Empty for a side that does not reflect.
  std::vector<double> radiosity_coefficients(std::uint32_t curve, Side side) const;
  // Unshot radiosity coefficients of a curve side (the power waiting to be shot in the next round,
  // per unit length, in the lumped estimate), laid out as radiosity_coefficients. The
  // reconstructed sampler draws photon origins with density proportional to this function.
  std::vector<double> unshot_coefficients(std::uint32_t curve, Side side) const;
  // Radiosity (emitted + reflected power per unit length) leaving a side at curve parameter u.
  Spectrum radiosity(std::uint32_t curve, Side side, double u) const;

 private:
  Solver() = default;

  struct SegmentInfo {
    std::uint32_t curve = 0;
    std::uint32_t index_in_curve = 0;
    SegmentKind kind = SegmentKind::Line;
  };
  // Integer deposits of one thread during one round. Its counters are written by every photon:
  // each thread's accumulator starts a cache line of its own (the threads' accumulators lie side
  // by side in a vector, and sharing a line cost a third of the two-thread rate, or not, as the
  // heap happened to align them).
  struct alignas(64) Accumulator {
    // [coefficient * channels + channel]; with auto storage twice that, odd-numbered photons of
    // the round depositing into the second half (half_offset, set per photon).
    std::vector<std::int64_t> received;
    std::size_t half_offset = 0;
    std::array<std::int64_t, 3> escaped{};
    // Absorbed outright: by sides that do not reflect, and (walks) where a walk ends or Russian
    // roulette's reweighting of its channels leaves power behind.
    std::array<std::int64_t, 3> absorbed{};
    std::array<std::int64_t, 3> shot{};
    std::uint64_t rays = 0;
    // Scratch of shoot(): the sources of the photons it shoots, chosen before any is shot, and
    // (Sobol') what each choice left of its coordinate.
    std::vector<std::uint32_t> sources;
    std::vector<double> places;
    void reset(std::size_t size);
  };
  struct Round {
    std::uint64_t photons = 0;
    double scale = 0.0;  // fixed-point units per unit of power
    // Walks: bits of scale given up so that every hop's tally fits (end_round's books allow for it).
    int headroom_bits = 0;
    // Over blocks (curve * 2 + side) for uniform sampling, over coefficients for reconstructed.
    DiscreteDistribution sources;
    std::vector<std::array<std::int64_t, 3>> photon_units;  // per source
  };

  static constexpr std::uint32_t kNoBlock = 0xffffffffu;
  std::uint32_t block_offset(std::uint32_t curve, Side side) const {
    return block_offset_[curve * 2 + static_cast<std::uint32_t>(side)];
  }
  bool begin_round();
  enum class RayKind { Point, Footprint, Band };
  // Shoots photons first .. first + count - 1 of the round (`first` names their quasi-Monte Carlo
  // points; `rng` is their batch's stream).
  void shoot_batch(Rng& rng, std::uint64_t first, std::uint64_t count, Accumulator& accumulator,
                   std::vector<PhotonPath>* paths, std::size_t path_limit) const;
  template <RayKind kRays>
  void shoot(Rng& rng, std::uint64_t first, std::uint64_t count, Accumulator& accumulator,
             std::vector<PhotonPath>* paths, std::size_t path_limit) const;
  // What a photon (or a band's sub-ray) carrying `units` does where it lands.
  template <RayKind kRays>
  void receive(const SceneHit& hit, const Ray& ray, const std::array<std::int64_t, 3>& units,
               Accumulator& accumulator, PhotonPath* path,
               std::vector<FootprintWeight>& footprint) const;
  void end_round(std::span<const Accumulator> accumulators);
  // Always-on: emitted = absorbed + escaped + unshot within the fixed point's rounding, or the
  // solve stops (StopReason::BooksUnbalanced).
  void check_books();
  // reflected_ (and the Hermite reconstructions) from the power received in all rounds.
  // `choice`: with auto storage, whether the levels are chosen again (Scheduled: when the photons
  // shot have grown by kLevelChoiceGrowth since the last choice; View: for a reader's view of an
  // open round, chosen again when the photons have grown by kLevelChoiceGrowth since the last
  // choice of either kind, never moving the solve's schedule; Final: always, at the end of the
  // solve).
  enum class LevelChoice { Scheduled, View, Final };
  // With auto storage, the levels chosen from all the photons when the solve stops.
  void choose_final_levels();
  void update_reflected(const std::vector<double>& received, const std::vector<double>& received_half,
                        LevelChoice choice = LevelChoice::Scheduled);
  // The readers' state (reflected_, hermite_reflected_) from `received` at the chosen levels.
  void refresh_readers(const std::vector<double>& received);
  // While run() goes, update_reflected leaves the readers' state stale (readers_stale_) for run to
  // refresh once when it returns.
  bool defer_readers_ = false;
  bool readers_stale_ = false;
  // Auto storage: each curve's level with the least estimated error (bias^2 + variance).
  void choose_levels(const std::vector<double>& received, const std::vector<double>& half);
  std::uint64_t photons_for_round(double unshot) const;
  // Walks per round: growing with the walks done (so the level choices and a viewer's picture
  // follow), at most kMaxWalksPerRound.
  std::uint64_t walks_for_round() const;
  static constexpr std::uint64_t kMinWalksPerRound = 16384;
  static constexpr std::uint64_t kMaxWalksPerRound = std::uint64_t{1} << 20;
  // The side of a curve that `ray` hits; `tangent` gets the curve's (unnormalised) tangent there.
  Side side_hit(const SceneHit& hit, const Ray& ray, Vec2& tangent) const;
  // Walks: the rest of a walk whose first flight `ray` landed at `hit` carrying `units` (already
  // received there): Russian roulette, a diffuse bounce from the side hit, the next flight's
  // deposit, until the walk ends. Its flights' paths are appended while `paths` has room;
  // `first_path` is the first flight's (or null), marked when the walk ends where it landed.
  template <RayKind kRays>
  void walk_on(Rng& rng, SceneHit hit, Ray ray, std::array<std::int64_t, 3> units,
               Accumulator& accumulator, std::vector<PhotonPath>* paths, std::size_t path_limit,
               PhotonPath* first_path, std::vector<FootprintWeight>& footprint) const;
  // The Hermite interpolant, in arc length, of the nodal values of a curve's hat basis at a level
  // (`values[k]`, that level's coefficients); C-1 nodes (double knots) keep their two values.
  HermiteReconstruction hermite_of(std::uint32_t curve, int level, const double* values) const;
  // A curve's storage at a level (levels_[curve].size(), or more: the finest, storage_[curve]).
  const CurveStorage& level_storage(std::uint32_t curve, int level) const;
  // One curve side's channel (`power[k * stride]`, finest layout) estimated at a level, in that
  // level's own basis (not prolonged).
  std::vector<double> estimate_in_level(std::uint32_t curve, int level, const double* power, std::size_t stride) const;
  // The Hermite reconstructions of every block side (channels summed, for the photon origins) or
  // of every channel times the side's reflectivity (the reflected radiosity), from the power
  // `power` (finest layout), at each curve's chosen level.
  void update_hermite(const std::vector<double>& power, bool reflected);
  // Arc length from the start of the curve to curve parameter u.
  double arc_length_at(std::uint32_t curve, double u) const;
  // Per-unit-length coefficients of `power` (same layout) by the chosen estimator, at each curve's
  // chosen level (prolonged into the finest basis).
  void estimate(const std::vector<double>& power, std::vector<double>& coefficients) const;
  // The same for one curve's sides (coefficients already sized and zero there).
  void estimate_curve(std::uint32_t c, const std::vector<double>& power, std::vector<double>& coefficients) const;
  // f(c) for every curve, shared among the threads in runs of curves (curve_chunks_); f must
  // write only curve c's own coefficients.
  void for_each_curve(const std::function<void(std::uint32_t)>& f);
  static constexpr std::size_t kCurveChunkCoefficients = 8192;
  std::vector<std::uint32_t> curve_chunks_;  // curves [curve_chunks_[i], curve_chunks_[i + 1])
  // Whether the given side (block at `offset` of `curve`) holds a nonzero value in `values`.
  bool holds_power(const std::vector<double>& values, std::uint32_t curve, std::uint32_t offset) const;
  void estimate_on(const CurveStorage& storage, const double* power, double* coefficients,
                   std::size_t stride) const;
  // One curve side's channel at a level (levels_[curve].size() is the finest: storage_[curve]).
  void estimate_at_level(std::uint32_t curve, int level, const double* power, double* coefficients,
                         std::size_t stride) const;

  const Scene* scene_ = nullptr;
  SolverSettings settings_;
  unsigned threads_ = 1;
  int channels_ = 1;
  SegmentAccelerator accelerator_;
  std::vector<SegmentInfo> segment_info_;
  std::vector<Vec2> line_tangents_;  // per segment: its unit tangent if it is a line, else zero
  std::vector<DiscreteDistribution> segment_choice_;  // per curve, by segment length
  std::vector<CurveStorage> storage_;  // the finest level of each curve
  // Auto storage: each curve's coarser levels (coarse to fine) with their restrictions from the
  // finest, and the level in use (levels_[c].size() for the finest). Fixed storage: no levels.
  struct Level {
    CurveStorage storage;
    Restriction restriction;
  };
  std::vector<std::vector<Level>> levels_;
  std::vector<int> chosen_level_;
  // Choosing levels estimates every level three times (all photons and the two halves): per round
  // that cost 2-3x the photons' own time in stiff scenes of thousands of small rounds. So levels are
  // chosen again only when the photons shot have grown by this factor since the last choice (and
  // once more when the solve stops), which is deterministic and independent of how rounds are
  // stepped; in between, the last scheduled choice is kept.
  static constexpr double kLevelChoiceGrowth = 1.25;
  // The photons shot when a view of an open round last chose the levels (LevelChoice::View).
  std::uint64_t photons_at_view_choice_ = 0;
  std::vector<int> scheduled_level_;
  std::uint64_t photons_at_choice_ = 0;
  bool auto_storage_ = false;
  std::vector<double> received_half_;  // auto storage: the part of received_ from odd photons
  std::vector<std::uint32_t> block_offset_;  // first coefficient of each (curve, side), or kNoBlock
  std::vector<Spectrum> block_reflectivity_;
  std::vector<std::uint8_t> block_black_;  // 1 where the side reflects nothing in any channel
  std::vector<std::uint32_t> coefficient_block_;  // block of each coefficient
  std::size_t coefficient_count_ = 0;
  std::size_t visibility_events_ = 0;
  std::size_t contact_nodes_ = 0;
  // Per curve, the arc lengths of its contacts: footprints stop there (empty with discontinuities
  // none).
  std::vector<std::vector<double>> walls_;
  // Per curve, the footprint's span moments on its deposit mesh (footprint rays with a
  // polynomial profile only; empty otherwise).
  std::vector<FootprintTable> footprint_tables_;

  // Shooting: all rounds' received power. Walks: each round's tallies estimate the whole received
  // power; this is their average weighted by walks (so it is an estimate after every round).
  std::vector<double> received_;  // [coefficient * channels + channel]
  std::vector<double> unshot_;    // current pool, same layout (walks: always zero)
  // Walks: the emitted power on each coefficient, where every round's walks start.
  std::vector<double> emission_;
  bool walk_ = false;
  double walk_expected_rays_ = 1.0;  // an upper bound on a walk's mean number of rays
  int walk_headroom_bits_ = 0;       // the most any round gave up
  // Walks: absorbed and escaped power per channel, averaged over rounds as received_ is.
  std::array<double, 3> walk_absorbed_{};
  std::array<double, 3> walk_escaped_{};
  std::uint64_t rays_traced_ = 0;
  std::vector<double> reflected_;  // reflected radiosity coefficients b_k (estimator applied)
  // Hermite basis only: reflected radiosity per block and channel, and the unshot density per
  // block (channels summed) that reconstructed sampling draws from; both in arc length.
  std::vector<std::vector<HermiteReconstruction>> hermite_reflected_;
  std::vector<HermiteReconstruction> hermite_unshot_;
  RayKind ray_kind_ = RayKind::Point;
  std::vector<double> band_offsets_;  // sub-ray offsets in [-1, 1] across the width (band mode)
  std::vector<double> band_weights_;
  bool sample_by_coefficient_ = false;  // reconstructed sampling on a B-spline basis
  bool sample_hermite_ = false;         // reconstructed sampling on the Hermite reconstruction
  Spectrum emitted_{};
  std::array<CompensatedSum, 3> absorbed_{};  // over all rounds
  std::array<CompensatedSum, 3> escaped_{};
  double emitted_total_ = 0.0;
  double initial_ratio_ = 0.5;
  double previous_unshot_ = 0.0;
  Round round_;
  std::vector<double> source_weights_;  // begin_round's scratch
  std::vector<double> density_power_;
  bool round_open_ = false;
  std::uint64_t round_done_ = 0;            // photons of the open round shot so far
  std::vector<Accumulator> round_deposits_;  // per worker thread, for the open round
  // The threads that shoot (and build the storage), started on first use and kept for the
  // solver's life (a copy of the solver starts its own).
  LazyWorkerPool pool_;
  WorkerPool& worker_pool() { return pool_.get(threads_); }
  std::optional<Rng> partial_batch_rng_;     // stream of a batch left half done by a step
  RoundSharing* sharing_ = nullptr;
  std::uint64_t bytes_shared_ = 0;
  // With sharing: the threads' deposits added into round_deposits_[0], then over all processes,
  // with this process's photons shot and whether it was cancelled; returns the totals of both.
  std::pair<std::uint64_t, bool> share_round(std::uint64_t photons_done, bool aborted);
  std::size_t path_limit_ = 0;
  std::vector<PhotonPath> paths_;

  std::uint64_t photons_shot_ = 0;
  std::uint64_t photons_cancelled_ = 0;
  std::uint32_t rounds_ = 0;
  double seconds_ = 0.0;
  StopReason stop_reason_ = StopReason::Running;
  std::string books_error_;
};

}  // namespace flatland
