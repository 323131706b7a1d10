#include "flatland/transport/photon_shooter.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "flatland/base/portable_math.hpp"
#include "flatland/transport/optics.hpp"
#include "flatland/transport/qmc.hpp"

namespace flatland {

namespace {

// The key of a round's indexed uniforms that choose the photons' sources (random sampler): from
// (seed, round), apart from the batches' streams by a constant of its own.
std::uint64_t source_key(std::uint64_t seed, std::uint64_t round) {
  std::uint64_t state = seed ^ 0x736f7572636573ull;  // "sources"
  state = splitmix64(state) ^ (round * 0xd1342543de82ef95ull);
  return splitmix64(state);
}

// From this many coefficients on, shoot() chooses a batch's sources before shooting it and asks
// for their data ahead (measured: docs/performance.md); below, that data stays in the caches.
constexpr std::size_t kAheadFrom = 8192;

// A hint to the memory system; no effect on any result.
inline void prefetch(const void* address) {
#if defined(__GNUC__)
  __builtin_prefetch(address);
#else
  (void)address;
#endif
}

// A round's sources and its photons' quasi-random points.
//
// Randomised quasi-Monte Carlo: each photon of the round takes a point of a scrambled Sobol' net
// (below), whichever batch, step or thread shoots it; its coordinates (PhotonDimension) and how
// rejection loops use them are in origins.hpp.
//
// The round's N photons form R replicates (SolverSettings::replicates, N a multiple of R), whose
// spread measures the estimate's variance (error_estimate.hpp, and choose_levels' halves: the odd
// replicates), laid out as settings.hpp's ReplicateLayout says:
// - Independent: photon i is in replicate i mod R and takes point i / R of that replicate's net,
//   scrambled on its own (stream R round + r). (Interleaved parts of one net would not do: R fixes
//   the first digits of the first coordinate, so each part would cover a sliver of it.)
// - Blocks: photon i takes point i of the round's one net (stream `round`, as with one replicate)
//   and is in replicate i / (N / R), a block of consecutive points: each block is a well spread
//   set of uniform points (an unbiased estimate), and the blocks together are the whole net.
class RoundPoints {
 public:
  RoundPoints(std::uint64_t seed, std::uint32_t round, bool sobol, std::uint32_t replicates, ReplicateLayout layout,
              const RoundPlan& plan)
      : qmc(sobol),
        blocks_(layout == ReplicateLayout::Blocks),
        replicates_(replicates),
        block_(static_cast<std::uint32_t>(std::max<std::uint64_t>(1, plan.photons / replicates))),
        key_(source_key(seed, round)),
        plan_(plan) {
    if (!qmc) return;
    if (blocks_) {
      nets.emplace_back(seed, round);
      return;
    }
    nets.reserve(replicates);
    for (std::uint32_t r = 0; r < replicates; ++r) nets.emplace_back(seed, std::uint64_t{replicates} * round + r);
  }
  RoundPoints(const RoundPoints&) = delete;  // cursors keep pointers to the nets
  RoundPoints& operator=(const RoundPoints&) = delete;

  // A cursor on every net (none for the random sampler).
  std::vector<SobolCursor> cursors() const {
    std::vector<SobolCursor> result;
    result.reserve(nets.size());
    for (const ScrambledSobol& net : nets) result.emplace_back(net);
    return result;
  }
  // Where photon `index` is: its replicate, its point in its net, and (blocks) where its block
  // ends. A photon loop divides once, at its first photon, and steps on with next().
  struct Place {
    std::uint32_t index;
    std::uint32_t replicate;
    std::uint32_t point;
    std::uint64_t block_end;
  };
  Place place_of(std::uint32_t index) const {
    if (blocks_) {
      const std::uint32_t replicate = index / block_;
      return {index, replicate, index, (std::uint64_t{replicate} + 1) * block_};
    }
    return {index, index % replicates_, index / replicates_, 0};
  }
  void next(Place& at) const {
    ++at.index;
    if (blocks_) {
      ++at.point;
      if (at.index == at.block_end) {
        ++at.replicate;
        at.block_end += block_;
      }
    } else if (++at.replicate == replicates_) {
      at.replicate = 0;
      ++at.point;
    }
  }
  // The cursor of the photon's net, moved to its point.
  SobolCursor& seek(std::vector<SobolCursor>& cursors, const Place& at) const {
    SobolCursor& point = cursors[blocks_ ? 0 : at.replicate];
    point.seek(at.point);
    return point;
  }
  // The source of the photon, by unshot power: a side of a curve, or one of its coefficients.
  // Sobol': from the photon's point (`place` gets what the choice leaves of dimension kPlace,
  // which places the origin); random: from the round's indexed uniforms, so that the choice does
  // not depend on how the round is cut into batches and steps either.
  std::size_t choose_source(std::vector<SobolCursor>& cursors, const Place& at, double& place) const {
    if (!qmc) return plan_.sources.sample(indexed_uniform(key_, at.index));
    return plan_.sources.sample(seek(cursors, at).sample(kPlace), place);
  }

  const bool qmc;
  std::vector<ScrambledSobol> nets;

 private:
  const bool blocks_;
  const std::uint32_t replicates_;
  const std::uint32_t block_;  // photons per replicate (blocks)
  const std::uint64_t key_;
  const RoundPlan& plan_;
};

// Ahead of photon i: the source's own entries for photon i + 2 kAhead, then (those in cache by
// now) its basis function's for photon i + kAhead.
constexpr std::uint64_t kAhead = 4;
inline void prefetch_sources(const SceneStorage& storage, const RoundPlan& plan,
                             const std::vector<std::uint32_t>& sources, std::uint64_t i, bool qmc) {
  const std::uint64_t count = sources.size();
  if (i + 2 * kAhead < count) {
    const std::uint32_t later = sources[i + 2 * kAhead];
    prefetch(&plan.photon_units[later]);
    prefetch(storage.coefficient_blocks().data() + later);
  }
  if (i + kAhead < count) {
    const std::uint32_t later = sources[i + kAhead];
    const std::uint32_t block = storage.coefficient_block(later);
    const CurveStorage& curve_storage = storage.finest(block / 2);
    const std::size_t k = later - storage.block_offset(block);
    curve_storage.sampler.prefetch(k, qmc);
    prefetch(&curve_storage.speed_bound[k]);
  }
}

// The direction a photon leaves in: diffuse, except an emitter's own light (`emitted_light`: the
// first round; every later round shoots reflected light only) when its material says otherwise.
inline Vec2 leaving_direction(bool emitted_light, const Emission& emission, Vec2 normal, Rng& rng,
                              const SobolCursor* point) {
  const bool qmc = point != nullptr;
  if (!emitted_light || emission.kind == Emission::Kind::Diffuse)
    return square_to_diffuse(qmc ? point->sample(kDirection) : rng.uniform(), normal);
  if (emission.kind == Emission::Kind::Lobe) {
    // Sobol': sample_lobe's first proposal (theta uniform, kept with probability cos^n) from the
    // point; when it is refused, sample_lobe draws afresh from the stream.
    const double theta = qmc ? (point->sample(kDirection) - 0.5) * std::numbers::pi : 0.0;
    double s = 0.0;
    double c = 0.0;
    portable::sin_cos(theta, s, c);
    if (qmc && point->sample(kAcceptLobe) < portable::pow(c, emission.exponent))
      return s * Vec2{normal.y, -normal.x} + c * normal;
    return sample_lobe(rng, emission.exponent, normal);
  }
  return square_to_beam(qmc ? point->sample(kDirection) : rng.uniform(), emission.half_angle, normal);
}

// The path record of a photon leaving `leaves` from side `back` of curve `curve_index` with
// `units`, while `paths` has room (else null).
inline PhotonPath* start_path(std::vector<PhotonPath>* paths, std::size_t path_limit, const Origin& leaves,
                              std::uint32_t curve_index, bool back, const std::array<std::int64_t, 3>& units,
                              std::size_t channels, double unit_scale, std::uint32_t bounce) {
  if (paths == nullptr || paths->size() >= path_limit) return nullptr;
  PhotonPath* path = &paths->emplace_back();
  path->origin = leaves.position;
  path->source_curve = curve_index;
  path->source_side = back ? Side::Back : Side::Front;
  path->source_segment = leaves.segment;
  path->source_t = leaves.t;
  for (std::size_t ch = 0; ch < channels; ++ch) path->power[ch] = static_cast<double>(units[ch]) / unit_scale;
  path->bounce = bounce;
  return path;
}

// A rough surface's microfacet normal where a ray travelling along d meets it: facets of slope s
// (tan of their tilt from the surface normal `facing`, along the unit tangent `along`), s Gaussian
// with standard deviation `roughness` truncated at 5 of them, each met in proportion to its width
// as the ray sees it, (-d) . (facing + s along) (a facet of slope s is sqrt(1 + s^2) wide per unit of
// surface): rejection against that width's bound 1 + 5 roughness. After 64 refusals (a grazing
// ray), the surface's own normal.
inline Vec2 microfacet_normal(Vec2 facing, Vec2 along, Vec2 d, double roughness, Rng& rng) {
  const double bound = 1.0 + 5.0 * roughness;
  for (int tries = 0; tries < 64; ++tries) {
    double sine = 0.0, cosine = 0.0;
    portable::sin_cos(2.0 * std::numbers::pi * rng.uniform(), sine, cosine);
    const double slope = roughness * std::sqrt(-2.0 * portable::log(1.0 - rng.uniform())) * cosine;
    if (std::fabs(slope) > 5.0 * roughness) continue;
    const Vec2 tilted = facing + slope * along;
    const double seen = -dot(d, tilted);
    if (seen > 0.0 && rng.uniform() * bound < seen) return normalized(tilted);
  }
  return facing;
}

// A photon's units shared among the three channels by the shares of its wavelength: each channel
// the rounded share of the total, the last the remainder, so the total is unchanged.
inline void split_by_wavelength(std::array<std::int64_t, 3>& units, double wavelength) {
  const std::int64_t total = units[0] + units[1] + units[2];
  const Spectrum shares = channel_shares(wavelength);
  units[0] = static_cast<std::int64_t>(static_cast<double>(total) * shares[0] + 0.5);
  units[1] = std::min(total - units[0], static_cast<std::int64_t>(static_cast<double>(total) * shares[1] + 0.5));
  units[2] = total - units[0] - units[1];
}

}  // namespace

void Deposits::reset(std::size_t size, std::size_t detected_size) {
  received.assign(size, 0);
  escaped = {};
  absorbed = {};
  shot = {};
  lost = {};
  chains_cut = 0;
  detected.assign(detected_size, 0);
  rays = 0;
}

DetectorLayout detector_layout(const Scene& scene) {
  DetectorLayout layout;
  layout.offsets.assign(scene.curves.size(), kNoDetector);
  for (std::size_t c = 0; c < scene.curves.size(); ++c) {
    const Material& material = scene.material_of(scene.curves[c]);
    if (material.optics != Optics::Detector) continue;
    layout.offsets[c] = static_cast<std::uint32_t>(layout.size);
    layout.size += 2 * std::size_t{material.detector_bins} * static_cast<std::size_t>(scene.channels);
  }
  return layout;
}

PhotonShooter::PhotonShooter(const Scene& scene, const SolverSettings& settings, SegmentAccelerator accelerator,
                             std::vector<std::vector<double>> walls)
    : scene_(&scene),
      seed_(settings.seed),
      sobol_(settings.sampler == SamplerKind::Sobol),
      replicates_(static_cast<std::uint32_t>(settings.replicates)),
      layout_(settings.replicate_layout),
      walk_score_(settings.walk_score),
      ray_width_(settings.ray_width),
      ray_profile_(settings.ray_profile),
      accelerator_(std::move(accelerator)),
      walls_(std::move(walls)) {
  chains_ = scene.has_specular();
  spectral_ = scene.has_spectra();
  for (const Curve& curve : scene.curves) {
    const std::optional<EmitterSpectrum>& spectrum = scene.material_of(curve).spectrum;
    spectra_.push_back(spectrum ? &*spectrum : nullptr);
  }
  detectors_ = flatland::detector_layout(scene);
  const bool reconstructed = settings.sampling == PositionSampling::Reconstructed;
  by_hermite_ = reconstructed && settings.basis == BasisKind::Hermite;
  by_coefficient_ = reconstructed && !by_hermite_;
  for (const SceneSegment& segment : scene.segments)
    segment_info_.push_back({segment.curve, segment.index_in_curve, segment.geometry.kind});
  line_tangents_ = line_tangents(scene);
  for (const Curve& curve : scene.curves) segment_choice_.push_back(segment_choice(scene, curve));
  if (settings.ray_width > 0.0) {
    ray_kind_ = settings.ray_mode == RayMode::Band ? RayKind::Band : RayKind::Footprint;
    if (ray_kind_ == RayKind::Band)
      profile_quadrature(settings.ray_profile, settings.band_rays, band_offsets_, band_weights_);
  }
}

bool PhotonShooter::prepare_footprints(const SceneStorage& storage, const std::atomic<bool>* cancel) {
  if (ray_kind_ != RayKind::Footprint || !is_polynomial(ray_profile_)) return true;
  // Whole knot spans of the deposit mesh from precomputed moments (footprint.hpp).
  footprint_tables_.reserve(scene_->curves.size());
  for (std::uint32_t c = 0; c < scene_->curves.size(); ++c) {
    if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) return false;
    footprint_tables_.emplace_back(*scene_, scene_->curves[c], storage.finest(c).basis, profile_powers(ray_profile_));
  }
  return true;
}

void PhotonShooter::count_sources(const RoundView& round, std::uint64_t first, std::uint64_t count,
                                  std::vector<std::uint64_t>& per_block) const {
  const SceneStorage& storage = *round.storage;
  const RoundPoints points(seed_, round.number, sobol_, replicates_, layout_, *round.plan);
  std::vector<SobolCursor> cursors = points.cursors();
  RoundPoints::Place at = points.place_of(static_cast<std::uint32_t>(first));
  for (std::uint64_t i = 0; i < count; ++i, points.next(at)) {
    double place = 0.0;
    const std::size_t source = points.choose_source(cursors, at, place);
    ++per_block[by_coefficient_ ? storage.coefficient_block(source) : source];
  }
}

void PhotonShooter::shoot(const RoundView& round, Rng& rng, std::uint64_t first, std::uint64_t count, Deposits& acc,
                          std::vector<PhotonPath>* paths, std::size_t path_limit) const {
  // The ray kind is fixed per solve: each kind gets its own compiled loop, so point rays carry no
  // footprint or band code at all.
  // So is whether flights follow specular chains.
  if (chains_) {
    switch (ray_kind_) {
      case RayKind::Point: return shoot_rays<RayKind::Point, true>(round, rng, first, count, acc, paths, path_limit);
      case RayKind::Footprint:
        return shoot_rays<RayKind::Footprint, true>(round, rng, first, count, acc, paths, path_limit);
      case RayKind::Band: return shoot_rays<RayKind::Band, true>(round, rng, first, count, acc, paths, path_limit);
    }
  }
  switch (ray_kind_) {
    case RayKind::Point: return shoot_rays<RayKind::Point, false>(round, rng, first, count, acc, paths, path_limit);
    case RayKind::Footprint:
      return shoot_rays<RayKind::Footprint, false>(round, rng, first, count, acc, paths, path_limit);
    case RayKind::Band: return shoot_rays<RayKind::Band, false>(round, rng, first, count, acc, paths, path_limit);
  }
}

// Where the photon leaves (origins.hpp): emitted light of a curve with an emittance profile
// (first round only, and every walk) where the profile says, reflected light where the unshot
// density is (a coefficient's basis function or the Hermite reconstruction), or uniformly in arc
// length.
// Inlined: one call less per photon in the shooting loop.
[[gnu::always_inline]] inline Origin PhotonShooter::leave(const RoundView& round, std::uint32_t curve_index,
                                                          std::uint32_t block, std::size_t source,
                                                          OriginDraws& draws) const {
  const Curve& curve = scene_->curves[curve_index];
  if (round.emitted_light && !curve.emittance_profile.empty())
    return sample_profiled_origin(*scene_, curve, segment_choice_[curve_index], draws);
  if (by_coefficient_) {
    const SceneStorage& storage = *round.storage;
    return sample_coefficient_origin(*scene_, curve, storage.finest(curve_index), source - storage.block_offset(block),
                                     line_tangents_, draws);
  }
  if (by_hermite_) return sample_hermite_origin(*scene_, curve, (*round.hermite_unshot)[block], draws);
  return sample_uniform_origin(*scene_, curve, segment_choice_[curve_index], line_tangents_, draws);
}

template <PhotonShooter::RayKind kRays, bool kChains>
void PhotonShooter::shoot_rays(const RoundView& round, Rng& rng, std::uint64_t first, std::uint64_t count,
                               Deposits& acc, std::vector<PhotonPath>* paths, std::size_t path_limit) const {
  const SceneStorage& storage = *round.storage;
  const RoundPlan& plan = *round.plan;
  std::vector<FootprintWeight> footprint;
  if constexpr (kRays == RayKind::Footprint) footprint.reserve(64);
  const auto channels = static_cast<std::size_t>(storage.channels());
  static_assert(kAcceptLobe < kSobolDimensions);
  const RoundPoints points(seed_, round.number, sobol_, replicates_, layout_, plan);
  const bool qmc = points.qmc;
  // Consecutive photons of a net take consecutive points: one XOR per dimension each.
  std::vector<SobolCursor> cursors = points.cursors();
  const std::size_t replicate_size = storage.coefficient_count() * channels;
  // With many coefficients (their sampler's pieces, units and blocks far beyond the caches) every
  // photon's source is chosen first, and while photon i is shot the data of photon i + kAhead's
  // are asked for (docs/performance-log.md, "Sources chosen ahead"); the same choices either way.
  const bool by_coefficient = by_coefficient_;
  const bool ahead = by_coefficient && storage.coefficient_count() >= kAheadFrom;
  std::vector<std::uint32_t>& sources = acc.sources;
  std::vector<double>& places = acc.places;
  if (ahead) {
    sources.resize(count);
    places.resize(count);
    std::vector<SobolCursor> ahead_cursors = points.cursors();
    RoundPoints::Place at = points.place_of(static_cast<std::uint32_t>(first));
    for (std::uint64_t i = 0; i < count; ++i, points.next(at)) {
      double place = 0.0;
      sources[i] = static_cast<std::uint32_t>(points.choose_source(ahead_cursors, at, place));
      places[i] = place;
    }
  }
  // The photon's replicate and net point, stepped on without a division per photon.
  RoundPoints::Place at = points.place_of(static_cast<std::uint32_t>(first));
  for (std::uint64_t i = 0; i < count; ++i, points.next(at)) {
    if (ahead) prefetch_sources(storage, plan, sources, i, qmc);
    // Replicate r of the round deposits into the accumulator's part r.
    acc.replicate_offset = at.replicate * replicate_size;
    SobolCursor* net_point = qmc ? &points.seek(cursors, at) : nullptr;
    double place = ahead ? places[i] : 0.0;
    const std::size_t source = ahead ? sources[i] : points.choose_source(cursors, at, place);
    const std::uint32_t block = by_coefficient ? storage.coefficient_block(source) : static_cast<std::uint32_t>(source);
    const std::uint32_t curve_index = block / 2;
    const bool back = (block & 1u) != 0;
    const Curve& curve = scene_->curves[curve_index];
    std::array<std::int64_t, 3> units = plan.photon_units[source];
    // Light straight from a spectral emitter: a wavelength from its spectrum, and the photon's
    // units shared among the channels by that wavelength's shares (their total unchanged, so the
    // books stay exact; on average each channel gets the emittance's share).
    double wavelength = 0.0;
    if (spectral_ && round.emitted_light) {
      if (const EmitterSpectrum* spectrum = spectra_[curve_index]; spectrum != nullptr) {
        wavelength = spectrum->sample(rng.uniform());
        split_by_wavelength(units, wavelength);
      }
    }
    for (std::size_t ch = 0; ch < channels; ++ch) acc.shot[ch] += units[ch];

    OriginDraws draws{rng, net_point, place};
    const Origin leaves = leave(round, curve_index, block, source, draws);
    const Vec2 normal = back ? -perp(leaves.tangent) : perp(leaves.tangent);
    const Vec2 direction =
        leaving_direction(round.emitted_light, scene_->material_of(curve).emission, normal, rng, net_point);
    PhotonPath* path =
        start_path(paths, path_limit, leaves, curve_index, back, units, channels, plan.scale, round.bounce);
    if (path != nullptr) path->wavelength = wavelength;
    if constexpr (kRays == RayKind::Band) {
      shoot_band<kChains>(round, rng, leaves, back, normal, direction, units, wavelength, acc, path, footprint);
    } else {
      Ray ray{leaves.position, direction};
      SceneHit hit = accelerator_.closest_hit(ray, RayOrigin{leaves.segment, leaves.t});
      ++acc.rays;
      bool goes_on = false;
      const bool lands =
          receive<kRays, kChains>(round, rng, hit, ray, units, wavelength, acc, path, footprint, goes_on);
      if (lands && round.photons_go_on)
        walk_on<kRays, kChains>(round, rng, hit, ray, units, goes_on, acc, paths, path_limit, path, footprint);
    }
  }
}

// K parallel sub-rays across the width W. Each starts on the source segment itself, moved along it
// by offset * W / (2 cos(theta_out)) so the sub-rays' perpendicular spacing is the profile's offsets
// times W/2 (clamped at the segment's ends, so no sub-ray starts outside the scene). A sub-ray whose
// start does not face its direction (the source bends away) leaves from the centre instead. Each
// carries its share of the units, the last one the remainder, and deposits where it lands; the
// middle one continues the photon's path.
template <bool kChains>
void PhotonShooter::shoot_band(const RoundView& round, Rng& rng, const Origin& leaves, bool back, Vec2 normal,
                               Vec2 direction, const std::array<std::int64_t, 3>& units, double wavelength,
                               Deposits& acc, PhotonPath* path, std::vector<FootprintWeight>& footprint) const {
  const auto channels = static_cast<std::size_t>(round.storage->channels());
  const SceneSegment& emitter = scene_->segments[leaves.segment];
  const Cubic& shape = emitter.geometry.shape;
  const bool line_source = emitter.geometry.kind == SegmentKind::Line;
  const double along = 0.5 * ray_width_ / std::max(dot(direction, normal), kGrazingCosine);
  const double s0 = line_source ? leaves.t * emitter.length : emitter.arc_length.length_at(shape, leaves.t);
  std::array<std::int64_t, 3> left = units;
  for (std::size_t ray_index = 0; ray_index < band_offsets_.size(); ++ray_index) {
    const bool last = ray_index + 1 == band_offsets_.size();
    std::array<std::int64_t, 3> share{};
    for (std::size_t ch = 0; ch < channels; ++ch) {
      share[ch] =
          last ? left[ch] : static_cast<std::int64_t>(band_weights_[ray_index] * static_cast<double>(units[ch]) + 0.5);
      left[ch] -= share[ch];
    }
    // Strictly inside the segment: from the very end point (a corner of a room) a sub-ray could
    // leave between the two walls.
    const double s_i = std::clamp(s0 + band_offsets_[ray_index] * along, 0x1.0p-40 * emitter.length,
                                  (1.0 - 0x1.0p-40) * emitter.length);
    double t_i = line_source ? s_i / emitter.length : emitter.arc_length.parameter_at(shape, s_i);
    Vec2 start = line_source ? lerp(shape.p[0], shape.p[3], t_i) : evaluate(shape, t_i);
    if (!line_source) {
      const Vec2 n_i = perp(unit_tangent(shape, t_i, scene_->scale));
      if (!((back ? -dot(n_i, direction) : dot(n_i, direction)) > 0.0)) {
        t_i = leaves.t;
        start = leaves.position;
      }
    }
    Ray sub{start, direction};
    SceneHit hit = accelerator_.closest_hit(sub, RayOrigin{leaves.segment, t_i});
    bool goes_on = false;  // (bands are shooting's only: no walk goes on)
    receive<RayKind::Point, kChains>(round, rng, hit, sub, share, wavelength, acc,
                                     ray_index == band_offsets_.size() / 2 ? path : nullptr, footprint, goes_on);
  }
  acc.rays += band_offsets_.size();
}

Side PhotonShooter::side_hit(const SceneHit& hit, const Ray& ray, Vec2& tangent) const {
  // The ray arrives on the front when it travels against the front normal, i.e. when
  // cross(C'(t), d) < 0. Only the sign matters, so C'(t) need not be normalised; where it
  // vanishes (an end point with coincident control points) the tangent comes from the first
  // non-vanishing derivative.
  const SegmentInfo& info = segment_info_[hit.segment];
  tangent = line_tangents_[hit.segment];
  if (info.kind == SegmentKind::Cubic) {
    const Cubic& shape = scene_->segments[hit.segment].geometry.shape;
    tangent = derivative(shape, hit.t);
    if (length_squared(tangent) <= 1e-24 * scene_->scale * scene_->scale)
      tangent = unit_tangent(shape, hit.t, scene_->scale);
  }
  return cross(tangent, ray.direction) < 0.0 ? Side::Front : Side::Back;
}

template <PhotonShooter::RayKind kRays, bool kChains>
void PhotonShooter::walk_on(const RoundView& round, Rng& rng, SceneHit hit, Ray ray, std::array<std::int64_t, 3> units,
                            bool goes_on, Deposits& acc, std::vector<PhotonPath>* paths, std::size_t path_limit,
                            PhotonPath* last, std::vector<FootprintWeight>& footprint) const {
  const SceneStorage& storage = *round.storage;
  const RoundPlan& plan = *round.plan;
  const auto channels = static_cast<std::size_t>(storage.channels());
  for (std::uint32_t bounce = 1;; ++bounce) {
    if (hit.segment == kNoSegment) return;  // escaped (receive booked it)
    Vec2 tangent;
    const Side side = side_hit(hit, ray, tangent);
    const std::uint32_t curve = segment_info_[hit.segment].curve;
    const std::uint32_t block = curve * 2 + static_cast<std::uint32_t>(side);
    if (storage.block_offset(block) == SceneStorage::kNoBlock ||
        storage.block_black(block)) {  // absorbed (receive booked it)
      if (last != nullptr) last->absorbed = true;
      return;
    }
    // Russian roulette (drawn by receive, before the deposit): go on with probability q = max rho,
    // each channel then carrying rho / q of its power, so every channel's expected power after the
    // bounce is rho times what arrived. What the reweighting leaves behind (channels below the
    // maximum, and rounding) is absorbed, so every walk's units end exactly as absorbed or escaped.
    const Spectrum& rho = storage.block_reflectivity(block);
    double survive = 0.0;
    for (std::size_t ch = 0; ch < channels; ++ch) survive = std::max(survive, rho[ch]);
    if (!goes_on) {
      for (std::size_t ch = 0; ch < channels; ++ch) acc.absorbed[ch] += units[ch];
      if (last != nullptr) last->absorbed = true;
      return;
    }
    std::int64_t carried = 0;
    for (std::size_t ch = 0; ch < channels; ++ch) {
      const auto kept = static_cast<std::int64_t>(static_cast<double>(units[ch]) * (rho[ch] / survive) + 0.5);
      acc.absorbed[ch] += units[ch] - kept;
      units[ch] = kept;
      carried += kept;
    }
    if (carried == 0) {  // (all absorbed above)
      if (last != nullptr) last->absorbed = true;
      return;
    }
    // A diffuse bounce from the side that was hit, starting on the curve itself.
    const SceneSegment& segment = scene_->segments[hit.segment];
    const Cubic& shape = segment.geometry.shape;
    const Vec2 point =
        segment.geometry.kind == SegmentKind::Line ? lerp(shape.p[0], shape.p[3], hit.t) : evaluate(shape, hit.t);
    const Vec2 front = perp(normalized(tangent));
    const Vec2 normal = side == Side::Front ? front : -front;
    ray = Ray{point, square_to_diffuse(rng.uniform(), normal)};
    const RayOrigin origin{hit.segment, hit.t};
    hit = accelerator_.closest_hit(ray, origin);
    ++acc.rays;
    PhotonPath* path = nullptr;
    if (paths != nullptr && paths->size() >= path_limit && last != nullptr) last->cut = true;
    if (paths != nullptr && paths->size() < path_limit) {
      path = &paths->emplace_back();
      path->origin = point;
      path->source_curve = curve;
      path->source_side = side;
      path->source_segment = origin.segment;
      path->source_t = origin.t;
      for (std::size_t ch = 0; ch < channels; ++ch) path->power[ch] = static_cast<double>(units[ch]) / plan.scale;
      path->bounce = bounce;
    }
    last = path;
    // (A diffuse bounce keeps the light's colour in its channels, not a wavelength.)
    if (!receive<kRays, kChains>(round, rng, hit, ray, units, 0.0, acc, path, footprint, goes_on)) return;
  }
}

template <PhotonShooter::RayKind kRays, bool kChains>
bool PhotonShooter::receive(const RoundView& round, Rng& rng, SceneHit& hit, Ray& ray,
                            std::array<std::int64_t, 3>& units, double wavelength, Deposits& acc, PhotonPath* path,
                            std::vector<FootprintWeight>& footprint, bool& goes_on) const {
  const SceneStorage& storage = *round.storage;
  const auto channels = static_cast<std::size_t>(storage.channels());
  if constexpr (kChains) {
    if (!follow_chain(rng, hit, ray, units, wavelength, channels, acc, path)) return false;
  } else {
    (void)rng;
    (void)wavelength;
  }
  if (hit.segment == kNoSegment) {
    for (std::size_t ch = 0; ch < channels; ++ch) acc.escaped[ch] += units[ch];
    if (path != nullptr) {
      path->escaped = true;
      path->end = ray.origin + ray.direction;
    }
    return true;
  }
  const SegmentInfo& info = segment_info_[hit.segment];
  Vec2 hit_tangent;
  const Side side = side_hit(hit, ray, hit_tangent);
  if (path != nullptr) {
    path->end = ray.origin + hit.distance * ray.direction;
    path->hit_curve = info.curve;
    path->hit_side = side;
    path->hit_s = storage.arc_length_at(info.curve, info.index_in_curve + hit.t);
  }
  const std::uint32_t offset = storage.block_offset(info.curve, side);
  // A side that reflects nothing (rho = 0 in every channel) turns all it receives into absorbed
  // power whatever the deposit's shape: no footprint or deposit is computed for it.
  const std::uint32_t block = info.curve * 2 + static_cast<std::uint32_t>(side);
  if (offset == SceneStorage::kNoBlock || storage.block_black(block)) {
    for (std::size_t ch = 0; ch < channels; ++ch) acc.absorbed[ch] += units[ch];
    return true;
  }
  // What is deposited: the units that arrived, or for a walk its score's tally of them. The walk's
  // roulette is drawn here, where walk_on drew it before the scores (after the specular chain,
  // before the next direction), so the collision score's bits are the same as they were.
  std::array<std::int64_t, 3> tally = units;
  if (round.photons_go_on) {
    const Spectrum& rho = storage.block_reflectivity(block);
    double survive = 0.0;
    for (std::size_t ch = 0; ch < channels; ++ch) survive = std::max(survive, rho[ch]);
    goes_on = rng.uniform() < survive;
    const double weight = walk_score_weight(walk_score_, survive, goes_on);
    if (weight == 0.0) return true;
    if (weight != 1.0)
      for (std::size_t ch = 0; ch < channels; ++ch)
        tally[ch] = static_cast<std::int64_t>(static_cast<double>(units[ch]) * weight + 0.5);
  }
  const double u = info.index_in_curve + hit.t;
  if constexpr (kRays == RayKind::Footprint) {
    // Spread along the receiver over the projected width with the profile; the weights sum to
    // one and the largest share takes the rounding remainder.
    const double cos_incidence = std::fabs(cross(hit_tangent, ray.direction)) / length(hit_tangent);
    footprint.clear();
    footprint_weights(*scene_, scene_->curves[info.curve], storage.finest(info.curve).basis, u,
                      footprint_half_length(ray_width_, cos_incidence), ray_profile_, footprint, walls_[info.curve],
                      footprint_tables_.empty() ? nullptr : &footprint_tables_[info.curve]);
    std::size_t largest = 0;
    for (std::size_t i = 1; i < footprint.size(); ++i)
      if (footprint[i].weight > footprint[largest].weight) largest = i;
    for (std::size_t ch = 0; ch < channels; ++ch) {
      std::int64_t left = tally[ch];
      for (std::size_t i = 0; i < footprint.size(); ++i) {
        if (i == largest) continue;
        const auto share = static_cast<std::int64_t>(footprint[i].weight * static_cast<double>(tally[ch]) + 0.5);
        acc.received[acc.replicate_offset + (offset + footprint[i].coefficient) * channels + ch] += share;
        left -= share;
      }
      acc.received[acc.replicate_offset + (offset + footprint[largest].coefficient) * channels + ch] += left;
    }
  } else {
    // Deposit on the basis functions alive at u; the last share takes the remainder so every
    // photon's units land exactly.
    const SplineBasis& basis = storage.finest(info.curve).basis;
    std::array<double, SplineBasis::kMaxDegree + 1> phi{};
    const std::size_t first = basis.evaluate(u, phi.data());
    const auto degree = static_cast<std::size_t>(basis.degree());
    std::int64_t* target = acc.received.data() + acc.replicate_offset + offset * channels;
    for (std::size_t ch = 0; ch < channels; ++ch) {
      std::int64_t left = tally[ch];
      for (std::size_t j = 0; j < degree; ++j) {
        // Round half up by truncation (the product is >= 0, but for a control variate's negative
        // units, where truncation toward zero moves a share by up to 1.5 units; the remainder below
        // keeps every photon's sum exact either way); std::llround is a library call.
        const auto share = static_cast<std::int64_t>(phi[j] * static_cast<double>(tally[ch]) + 0.5);
        target[basis.index(first + j) * channels + ch] += share;
        left -= share;
      }
      target[basis.index(first + degree) * channels + ch] += left;
    }
  }
  return true;
}

// The specular chain (docs/optics.md). Every event restarts the
// flight on the curve itself (the point at the hit's parameter, that segment tested with the
// deflated query), as a diffuse bounce does. Each channel's power changes only by deterministic
// factors (a mirror's reflectance, the medium's transmittance), rounded to units with the
// remainder booked as lost, so the books stay exact; the choice between reflection and refraction
// is a draw with the Fresnel reflectance as its probability, so every photon keeps its power.
bool PhotonShooter::follow_chain(Rng& rng, SceneHit& hit, Ray& ray, std::array<std::int64_t, 3>& units,
                                 double wavelength, std::size_t channels, Deposits& acc, PhotonPath* path) const {
  // Dispersion: the index at the photon's wavelength (micrometres); light without one at the d line.
  const double micrometres = wavelength > 0.0 ? wavelength / 1000.0 : kGreyWavelength;
  // The attenuation per unit length of the medium the flight crosses (null: none). Light leaving
  // a diffuse side or an emitter starts in a clear medium; a dielectric's front side has its
  // absorption, its back side none.
  const Spectrum* medium = nullptr;
  auto lose = [&](ChainLoss where, Vec2 at) {
    for (std::size_t ch = 0; ch < channels; ++ch) acc.lost[static_cast<std::size_t>(where)][ch] += units[ch];
    if (path != nullptr) {
      path->end = at;
      path->absorbed = true;
      if (hit.segment != kNoSegment) path->hit_curve = segment_info_[hit.segment].curve;
    }
    return false;
  };
  // Each channel keeps `fraction(ch)` of its units (rounded, never more than it had), the rest
  // booked to `where`; returns the units still carried.
  auto attenuate = [&](ChainLoss where, auto fraction) {
    std::int64_t carried = 0;
    for (std::size_t ch = 0; ch < channels; ++ch) {
      // (At most what arrived: units + 0.5 rounds up in a double when units are past 2^53.)
      const auto kept =
          std::min(units[ch], static_cast<std::int64_t>(static_cast<double>(units[ch]) * fraction(ch) + 0.5));
      acc.lost[static_cast<std::size_t>(where)][ch] += units[ch] - kept;
      units[ch] = kept;
      carried += kept;
    }
    return carried;
  };
  for (std::uint32_t events = 0;; ++events) {
    if (medium != nullptr) {
      // Beer-Lambert over the flight; a flight that leaves the scene inside an absorbing medium
      // never comes out of it.
      const std::int64_t carried = attenuate(ChainLoss::Glass, [&](std::size_t ch) {
        return hit.segment == kNoSegment ? 0.0 : portable::exp(-(*medium)[ch] * hit.distance);
      });
      if (carried == 0)
        return lose(ChainLoss::Glass, ray.origin + (hit.segment == kNoSegment ? 1.0 : hit.distance) * ray.direction);
    }
    if (hit.segment == kNoSegment) return true;
    const SegmentInfo& info = segment_info_[hit.segment];
    const Curve& curve = scene_->curves[info.curve];
    const Material& material = scene_->material_of(curve);
    if (material.optics == Optics::Diffuse) return true;
    const SceneSegment& segment = scene_->segments[hit.segment];
    const Cubic& shape = segment.geometry.shape;
    const Vec2 point =
        segment.geometry.kind == SegmentKind::Line ? lerp(shape.p[0], shape.p[3], hit.t) : evaluate(shape, hit.t);
    if (events == kChainLimit) {
      ++acc.chains_cut;
      return lose(ChainLoss::Limit, point);
    }
    Vec2 tangent;
    const Side side = side_hit(hit, ray, tangent);
    const Vec2 front = perp(normalized(tangent));
    const Vec2 facing = side == Side::Front ? front : -front;  // the normal on the arriving side
    // The normal the light meets: the surface's, or on a rough surface a microfacet's.
    const Vec2 normal = material.roughness > 0.0 && material.optics != Optics::Detector
                            ? microfacet_normal(facing, normalized(tangent), ray.direction, material.roughness, rng)
                            : facing;
    const double cos_in = std::clamp(-dot(ray.direction, normal), 0.0, 1.0);
    Vec2 direction = ray.direction;
    switch (material.optics) {
      case Optics::Diffuse: break;
      case Optics::Detector: {
        // Tallied where it crosses; the flight goes on unchanged.
        const double s = arc_length_at(*scene_, curve, info.index_in_curve + hit.t);
        const std::uint32_t bins = material.detector_bins;
        const auto bin = std::min(bins - 1, static_cast<std::uint32_t>(std::max(0.0, s / curve.length * bins)));
        std::int64_t* tally = acc.detected.data() + detectors_.offsets[info.curve] +
                              (static_cast<std::size_t>(side) * bins + bin) * channels;
        for (std::size_t ch = 0; ch < channels; ++ch) tally[ch] += units[ch] >> kDetectorShift;
        break;
      }
      case Optics::Mirror: {
        if (!curve.has_side(side)) return lose(ChainLoss::Mirrors, point);
        const std::int64_t carried =
            attenuate(ChainLoss::Mirrors, [&](std::size_t ch) { return material.reflectance[ch]; });
        if (carried == 0) return lose(ChainLoss::Mirrors, point);
        direction = ray.direction + (2.0 * cos_in) * normal;
        // A microfacet may send the light into the surface: it meets the surface again and leaves.
        if (dot(direction, facing) < 0.0) direction = direction - (2.0 * dot(direction, facing)) * facing;
        break;
      }
      case Optics::Dielectric: {
        // Snell: n1 sin(in) = n2 sin(out); unpolarised Fresnel reflectance, the mean of s and p.
        const double front_index = material.ior.at(micrometres);
        const double n1 = side == Side::Front ? front_index : material.ior_back;
        const double n2 = side == Side::Front ? material.ior_back : front_index;
        const double eta = n1 / n2;
        const double sin2_out = eta * eta * (1.0 - cos_in * cos_in);
        bool reflects = true;  // total internal reflection when sin2_out >= 1
        double cos_out = 0.0;
        if (sin2_out < 1.0) {
          cos_out = std::sqrt(1.0 - sin2_out);
          reflects = rng.uniform() < fresnel_reflectance(n1, n2, cos_in, cos_out);
        }
        Side goes_to = side;
        if (reflects) {
          direction = ray.direction + (2.0 * cos_in) * normal;
          if (dot(direction, facing) < 0.0) direction = direction - (2.0 * dot(direction, facing)) * facing;
        } else {
          direction = eta * ray.direction + (eta * cos_in - cos_out) * normal;
          goes_to = side == Side::Front ? Side::Back : Side::Front;
          // (Through a tilted microfacet the light may still head back: it crosses all the same.)
          if (dot(direction, facing) > 0.0) direction = direction - (2.0 * dot(direction, facing)) * facing;
        }
        const Spectrum& absorption = material.absorption;
        const bool absorbing = absorption[0] > 0.0 || absorption[1] > 0.0 || absorption[2] > 0.0;
        medium = goes_to == Side::Front && absorbing ? &absorption : nullptr;
        break;
      }
    }
    if (path != nullptr) path->via.push_back(point);
    ray = Ray{point, normalized(direction)};
    hit = accelerator_.closest_hit(ray, RayOrigin{hit.segment, hit.t});
    ++acc.rays;
  }
}

}  // namespace flatland
