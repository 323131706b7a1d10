// One photon's flight, as every transport shoots it: a source by its power, a place on it (the
// origins of origins.hpp), a direction, the trace to the nearest hit, and what it leaves there (a
// point deposit on the receiver's basis functions, a footprint, or a band of sub-rays), then, for
// a transport whose photons go on (random walks), the next hops. The shooter is const while a
// round is shot: the threads share it, each writing only its own Deposits.
//
// Determinism: photon i of a round takes its source and quasi-Monte Carlo point by its number i
// (never by thread or batch), and its random stream is its batch's (named by seed, round and
// batch); deposits are integers (units of 2^-k of the round's power), so their sums do not depend
// on the order in which threads add them.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "flatland/geometry/accelerator.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/storage/hermite.hpp"
#include "flatland/transport/footprint.hpp"
#include "flatland/transport/origins.hpp"
#include "flatland/transport/sampling.hpp"
#include "flatland/transport/scene_storage.hpp"
#include "flatland/transport/settings.hpp"

namespace flatland {

// One photon's flight, kept for inspection (the viewer draws these; tests check the samplers).
struct PhotonPath {
  Vec2 origin;
  Vec2 end;  // the hit point, or origin + direction for a photon that escaped
  bool escaped = false;
  std::uint32_t source_curve = 0;
  Side source_side = Side::Front;
  std::uint32_t source_segment = 0;  // index into Scene::segments
  double source_t = 0.0;
  std::uint32_t hit_curve = 0;  // meaningless when escaped
  Side hit_side = Side::Front;
  double hit_s = 0.0;  // arc length along the hit curve from its start
  Spectrum power{};    // power carried (channels as in the scene)
  // Times the light carried has been reflected before this flight: shooting's round number, or
  // the hop's number in its walk (0: straight from an emitter). A walk's hops are consecutive
  // paths, its first with bounce 0.
  std::uint32_t bounce = 0;
  // Walks: the walk ended where this flight landed (Russian roulette, or a side that reflects
  // nothing). A flight that escaped ends its walk too (`escaped`).
  bool absorbed = false;
  // Walks: the walk went on after this flight, but the record was full (path_limit).
  bool cut = false;
  // The points where the flight met mirrors, glass or detectors on its way from `origin` to `end`
  // (empty in a scene without them); the flight ended in the chain when `absorbed` is set there.
  std::vector<Vec2> via;
  // Spectral light straight from its emitter: its wavelength in nanometres (0: none).
  double wavelength = 0.0;
};

// Where power ends inside a specular chain (each a line of the energy books): absorbed by mirrors
// (their reflectance below 1, or their side that does not reflect), absorbed in glass, or cut
// with its photon after kChainLimit events.
enum class ChainLoss : std::uint8_t { Mirrors = 0, Glass = 1, Limit = 2 };
inline constexpr std::size_t kChainLosses = 3;
// Specular events (reflections, refractions, detector crossings) one flight may take; a photon
// still in a chain after that is cut and counted (a light guide's thousandth bounce, or a ray
// caught between two parallel mirrors).
inline constexpr std::uint32_t kChainLimit = 1000;

// The detectors' tallies: detector curve c's bin b on side s (the side the light arrives on,
// front: crossing from the front to the back) and channel ch at
// offsets[c] + (s * bins + b) * channels + ch; offsets[c] = kNoDetector for other curves.
inline constexpr std::uint32_t kNoDetector = 0xffffffffu;
// A detector tallies a crossing's units divided by 2^kDetectorShift (rounded down: at most 2^-50 of
// the round's power per crossing): a photon may cross detectors up to kChainLimit < 2^10 times,
// and the tallies must stay within the round's 2^63 units as the deposits do.
inline constexpr int kDetectorShift = 10;
static_assert(kChainLimit < (1u << kDetectorShift));
struct DetectorLayout {
  std::vector<std::uint32_t> offsets;
  std::size_t size = 0;
};
DetectorLayout detector_layout(const Scene& scene);

// Integer deposits of one thread during one round. Its counters are written by every photon:
// each thread's deposits start a cache line of their own (the threads' lie side by side in a
// vector, and sharing a line cost a third of the two-thread rate, or not, as the heap happened to
// align them).
struct alignas(64) Deposits {
  // [replicate * coefficients * channels + coefficient * channels + channel]: replicate r of the
  // round (photon_shooter.cpp, RoundPoints) deposits into part r (replicate_offset, set per photon).
  std::vector<std::int64_t> received;
  std::size_t replicate_offset = 0;
  std::array<std::int64_t, 3> escaped{};
  // Absorbed outright: by sides that do not reflect, and (walks) where a walk ends or Russian
  // roulette's reweighting of its channels leaves power behind.
  std::array<std::int64_t, 3> absorbed{};
  std::array<std::int64_t, 3> shot{};
  // Specular chains: power that ends in them (by ChainLoss), photons cut at kChainLimit, and the
  // detectors' tallies (DetectorLayout).
  std::array<std::array<std::int64_t, 3>, kChainLosses> lost{};
  std::uint64_t chains_cut = 0;
  std::vector<std::int64_t> detected;
  std::uint64_t rays = 0;
  // Scratch of shooting: the sources of the photons of a batch, chosen before any is shot, and
  // (Sobol') what each choice left of its coordinate.
  std::vector<std::uint32_t> sources;
  std::vector<double> places;
  void reset(std::size_t size, std::size_t detected_size);
};

// What a round shoots, decided when it begins: its photons, the fixed point's scale, the sources
// (sides of curves for uniform origins, coefficients for reconstructed ones) chosen by their share
// of the round's power, and the units each source's photons carry per channel.
struct RoundPlan {
  std::uint64_t photons = 0;
  double scale = 0.0;  // fixed-point units per unit of power
  // Walks: bits of scale given up so that every hop's tally fits (the books allow for it).
  int headroom_bits = 0;
  DiscreteDistribution sources;
  std::vector<std::array<std::int64_t, 3>> photon_units;  // per source
};

// The round a batch of photons belongs to, as the shooter reads it.
struct RoundView {
  std::uint32_t number = 0;  // rounds finished before it
  const RoundPlan* plan = nullptr;
  const SceneStorage* storage = nullptr;
  // Reconstructed origins on Hermite storage: each block's unshot density (else empty).
  const std::vector<HermiteReconstruction>* hermite_unshot = nullptr;
  // Whether the photons carry light straight from the emitters (shooting's first round, every
  // walk): an emittance profile places them and the emitter's own directions send them.
  bool emitted_light = false;
  // Whether photons go on from where they land (random walks).
  bool photons_go_on = false;
  // The bounce its paths record (shooting: the round's number; walks count their own hops).
  std::uint32_t bounce = 0;
};

class PhotonShooter {
 public:
  PhotonShooter() = default;
  // The tables a flight reads: the segments' tree and kinds, each curve's segments by length, the
  // contacts that stop footprints (`walls`: per curve, arc lengths), the band's sub-rays and the
  // footprint tables of polynomial profiles on `storage`.
  PhotonShooter(const Scene& scene, const SolverSettings& settings, SegmentAccelerator accelerator,
                std::vector<std::vector<double>> walls);
  // The footprint tables for the deposit meshes of `storage` (polynomial profiles of footprint
  // rays only); `cancel` stops building them (then false).
  bool prepare_footprints(const SceneStorage& storage, const std::atomic<bool>* cancel);

  // Shoots photons first .. first + count - 1 of the round (`first` names their quasi-Monte Carlo
  // points; `rng` is their batch's stream) into `deposits`; their paths are appended to `paths`
  // while it holds fewer than `path_limit`.
  void shoot(const RoundView& round, Rng& rng, std::uint64_t first, std::uint64_t count, Deposits& deposits,
             std::vector<PhotonPath>* paths, std::size_t path_limit) const;

  // Adds to per_block[b] the photons first .. first + count - 1 of the round that leave from
  // block b (curve * 2 + side): the same choice of source, from the same Sobol' point or indexed
  // uniform, that shoot() makes. Importance sets the power a side's photons carry by their count.
  void count_sources(const RoundView& round, std::uint64_t first, std::uint64_t count,
                     std::vector<std::uint64_t>& per_block) const;

  const SegmentAccelerator& accelerator() const { return accelerator_; }
  const DetectorLayout& detector_layout() const { return detectors_; }

 private:
  enum class RayKind { Point, Footprint, Band };
  struct SegmentInfo {
    std::uint32_t curve = 0;
    std::uint32_t index_in_curve = 0;
    SegmentKind kind = SegmentKind::Line;
  };
  // kChains: the scene has mirrors, glass or detectors, and every flight follows its specular
  // chain (follow_chain); a scene without them compiles loops with no trace of it.
  template <RayKind kRays, bool kChains>
  void shoot_rays(const RoundView& round, Rng& rng, std::uint64_t first, std::uint64_t count, Deposits& deposits,
                  std::vector<PhotonPath>* paths, std::size_t path_limit) const;
  Origin leave(const RoundView& round, std::uint32_t curve_index, std::uint32_t block, std::size_t source,
               OriginDraws& draws) const;
  template <bool kChains>
  void shoot_band(const RoundView& round, Rng& rng, const Origin& leaves, bool back, Vec2 normal, Vec2 direction,
                  const std::array<std::int64_t, 3>& units, double wavelength, Deposits& deposits, PhotonPath* path,
                  std::vector<FootprintWeight>& footprint) const;
  // What a photon (or a band's sub-ray) carrying `units` does where it lands: with kChains, first
  // its specular chain, after which `hit`, `ray` and `units` are its last flight's and what that
  // brings. Returns false when the photon ended in the chain (booked there). `wavelength`: the
  // photon's (nm), or 0 for light without one. A walk (round.photons_go_on) that lands on a side
  // with storage draws its Russian roulette here, before the deposit, since the walk's score
  // deposits by the outcome: `goes_on` receives it, and walk_on carries it out.
  template <RayKind kRays, bool kChains>
  bool receive(const RoundView& round, Rng& rng, SceneHit& hit, Ray& ray, std::array<std::int64_t, 3>& units,
               double wavelength, Deposits& deposits, PhotonPath* path, std::vector<FootprintWeight>& footprint,
               bool& goes_on) const;
  // The specular chain of a flight that landed at `hit`: while it is on a mirror, a dielectric or
  // a detector, the photon reflects, refracts (by the Fresnel weight, drawn from `rng`, so every
  // photon keeps its power) or passes, and flies on. Returns true with `hit` on a diffuse side or
  // escaped; false when the photon ended in the chain (absorbed by a mirror or in glass, or cut).
  bool follow_chain(Rng& rng, SceneHit& hit, Ray& ray, std::array<std::int64_t, 3>& units, double wavelength,
                    std::size_t channels, Deposits& deposits, PhotonPath* path) const;
  // The side of a curve that `ray` hits; `tangent` gets the curve's (unnormalised) tangent there.
  Side side_hit(const SceneHit& hit, const Ray& ray, Vec2& tangent) const;
  // Walks: the rest of a walk whose first flight `ray` landed at `hit` carrying `units` (already
  // received there, its roulette drawn: `goes_on`): the roulette's outcome, a diffuse bounce from
  // the side hit, the next flight's deposit, until the walk ends. Its flights' paths are appended
  // while `paths` has room; `first_path` is the first flight's (or null), marked when the walk ends
  // where it landed.
  template <RayKind kRays, bool kChains>
  void walk_on(const RoundView& round, Rng& rng, SceneHit hit, Ray ray, std::array<std::int64_t, 3> units, bool goes_on,
               Deposits& deposits, std::vector<PhotonPath>* paths, std::size_t path_limit, PhotonPath* first_path,
               std::vector<FootprintWeight>& footprint) const;

  const Scene* scene_ = nullptr;
  std::uint64_t seed_ = 1;
  bool sobol_ = true;
  std::uint32_t replicates_ = 1;  // photon i of a round deposits into part i mod R or i / (N / R) (layout_)
  ReplicateLayout layout_ = ReplicateLayout::Independent;
  WalkScore walk_score_ = WalkScore::Collision;
  bool by_coefficient_ = false;  // reconstructed origins on a B-spline basis
  bool by_hermite_ = false;      // reconstructed origins on the Hermite reconstruction
  double ray_width_ = 0.0;
  RayProfile ray_profile_ = RayProfile::Box;
  RayKind ray_kind_ = RayKind::Point;
  bool chains_ = false;  // the scene has mirrors, glass or detectors
  // Per curve, its material's spectrum (null: none); spectral_ when any curve has one.
  std::vector<const EmitterSpectrum*> spectra_;
  bool spectral_ = false;
  DetectorLayout detectors_;
  SegmentAccelerator accelerator_;
  std::vector<SegmentInfo> segment_info_;
  std::vector<Vec2> line_tangents_;                   // per segment: its unit tangent if a line, else zero
  std::vector<DiscreteDistribution> segment_choice_;  // per curve, by segment length
  // Per curve, the arc lengths of its contacts: footprints stop there (empty with discontinuities
  // none).
  std::vector<std::vector<double>> walls_;
  // Per curve, the footprint's span moments on its deposit mesh (footprint rays with a
  // polynomial profile only; empty otherwise).
  std::vector<FootprintTable> footprint_tables_;
  std::vector<double> band_offsets_;  // sub-ray offsets in [-1, 1] across the width (band mode)
  std::vector<double> band_weights_;
};

}  // namespace flatland
