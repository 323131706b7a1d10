#include "flatland/transport/solver.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <numeric>
#include <thread>

#include "flatland/transport/origins.hpp"
#include "flatland/transport/qmc.hpp"
#include "flatland/base/resources.hpp"
#include "flatland/base/text.hpp"

namespace flatland {

namespace {

using Clock = std::chrono::steady_clock;

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

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

}  // namespace

const char* to_string(StopReason reason) {
  switch (reason) {
    case StopReason::Running: return "running";
    case StopReason::Converged: return "converged";
    case StopReason::BudgetSpent: return "photon budget spent";
    case StopReason::Cancelled: return "cancelled";
    case StopReason::BooksUnbalanced: return "energy books unbalanced";
  }
  return "?";
}

namespace {

// The storage's memory, estimated from above before anything is allocated. Per coefficient and
// channel: the received, unshot and reflected totals (doubles), one fixed-point deposit per worker
// thread and the Galerkin scratch; per coefficient, its knots, basis integral, origin sampler and
// source weight (about 160 bytes). A curve's segments share its elements, at least one each (at
// most elements + segments); the regions between event nodes round their shares up, so that a
// curve has at most twice that many, plus per segment a joint of multiplicity up to the degree + 1.
Status check_memory(const Scene& scene, const SolverSettings& settings, unsigned threads) {
  double coefficients = 0.0;
  for (const Curve& curve : scene.curves) {
    const double sides = curve.sides == Sides::Both ? 2.0 : 1.0;
    coefficients += sides * (2.0 * (static_cast<double>(settings.elements) + curve.segment_count) +
                             4.0 * curve.segment_count + 4.0);
  }
  const double per_coefficient = scene.channels * 8.0 * (4.0 + threads) + 160.0;
  const double bytes = coefficients * per_coefficient + 2048.0 * static_cast<double>(scene.segments.size());
  const std::size_t limit = settings.memory_limit != 0 ? settings.memory_limit : default_memory_budget();
  if (bytes <= static_cast<double>(limit)) return ok_status();
  char message[320];
  std::snprintf(message, sizeof message,
                "elements: %d a curve on %zu curves would need about %.3g storage coefficients and %s of "
                "memory, more than the limit of %s; use fewer elements per curve",
                settings.elements, scene.curves.size(), coefficients, format_bytes(bytes).c_str(),
                format_bytes(static_cast<double>(limit)).c_str());
  return Error{message};
}

}  // namespace

void Solver::Accumulator::reset(std::size_t size) {
  received.assign(size, 0);
  escaped = {};
  absorbed = {};
  shot = {};
  rays = 0;
}

Result<Solver> Solver::create(const Scene& scene, const SolverSettings& settings,
                              const std::atomic<bool>* cancel) {
  auto cancelled = [cancel] { return cancel != nullptr && cancel->load(std::memory_order_relaxed); };
  if (Status status = validate(settings); !status) return status.error();
  if (scene.curves.empty() || scene.segments.empty())
    return Error{scene.source + ": the scene has no curves"};
  // A ray wider than the whole scene spreads every photon over everything it meets: the answer
  // is a blur of the scene, not of the light.
  if (settings.ray_width > scene.scale) {
    char message[240];
    std::snprintf(message, sizeof message,
                  "ray width: %g is wider than the scene itself (its bounding box's diagonal is %g); give "
                  "a width well below it, such as %.2g (1 %%)",
                  settings.ray_width, scene.scale, 0.01 * scene.scale);
    return Error{message};
  }

  Solver solver;
  solver.scene_ = &scene;
  solver.settings_ = settings;
  solver.settings_.estimator = resolve_estimator(settings.estimator, settings.basis);
  const Estimator estimator = solver.settings_.estimator;
  solver.channels_ = scene.channels;
  solver.threads_ = settings.threads != 0 ? settings.threads
                                          : std::max(1u, std::thread::hardware_concurrency());
  // Auto storage: the finest level that a reflecting curve's share of the budget still fills
  // with kAutoPhotonsPerElement photons per element (DESIGN: the best element length shrinks
  // with the photon count, so a bigger budget reaches finer levels).
  const bool hermite = settings.basis == BasisKind::Hermite;
  solver.auto_storage_ = settings.elements == kAutoElements;
  const int elements = settings.elements != kAutoElements ? settings.elements : kAutoBaseElements;
  int finest_level = 0;
  double room = 0.0;  // auto storage: elements a curve's finest level may have
  if (solver.auto_storage_) {
    std::size_t reflecting = 0;
    for (const Curve& curve : scene.curves) {
      const Spectrum& rho = scene.material_of(curve).reflectivity;
      reflecting += rho[0] + rho[1] + rho[2] > 0.0;
    }
    const double share = static_cast<double>(settings.photons) / static_cast<double>(std::max<std::size_t>(reflecting, 1));
    // Elements the finest level may have: share / kAutoPhotonsPerElement, or at small budgets up
    // to kAutoSmallBudgetElements as long as each still gets kAutoSmallBudgetPhotonsPerElement.
    room = std::max(share / kAutoPhotonsPerElement,
                    std::min(share / kAutoSmallBudgetPhotonsPerElement, kAutoSmallBudgetElements));
    while (finest_level + 1 < kAutoMaxLevels && (kAutoBaseElements << (finest_level + 1)) <= room)
      ++finest_level;
  }
  const int finest_elements = elements << finest_level;
  SolverSettings sized = settings;
  sized.elements = finest_elements;
  if (Status status = check_memory(scene, sized, solver.threads_); !status) return status.error();

  std::vector<SegmentGeometry> geometry;
  geometry.reserve(scene.segments.size());
  for (const SceneSegment& segment : scene.segments) {
    geometry.push_back(segment.geometry);
    SegmentInfo info;
    info.curve = segment.curve;
    info.index_in_curve = segment.index_in_curve;
    info.kind = segment.geometry.kind;
    solver.segment_info_.push_back(info);
  }
  solver.line_tangents_ = line_tangents(scene);
  solver.accelerator_ = SegmentAccelerator(std::move(geometry));
  std::vector<std::vector<MeshNode>> events(scene.curves.size());
  solver.walls_.resize(scene.curves.size());
  if (settings.discontinuities != DiscontinuityMode::None) {
    // Contacts are part of the geometry (light on the two sides is unrelated): a value jump there
    // whenever the scene's joints are honoured.
    for (const DiscontinuityNode& node : find_contacts(scene)) {
      events[node.curve].push_back({node.u, node.continuity});
      solver.walls_[node.curve].push_back(solver.arc_length_at(node.curve, node.u));
      ++solver.contact_nodes_;
    }
    for (std::vector<double>& walls : solver.walls_) std::sort(walls.begin(), walls.end());
  }
  if (settings.discontinuities == DiscontinuityMode::Auto ||
      settings.discontinuities == DiscontinuityMode::Secondary) {
    EventOptions options;
    options.elements = finest_elements;
    options.secondary = settings.discontinuities == DiscontinuityMode::Secondary;
    for (const DiscontinuityNode& node : find_visibility_events(scene, solver.accelerator_, options)) {
      events[node.curve].push_back({node.u, node.continuity});
      ++solver.visibility_events_;
    }
  }

  const auto channels = static_cast<std::size_t>(solver.channels_);
  double reflecting_length = 0.0;
  double weighted_reflectivity = 0.0;
  solver.block_offset_.assign(scene.curves.size() * 2, kNoBlock);
  solver.block_reflectivity_.assign(scene.curves.size() * 2, Spectrum{});
  solver.block_black_.assign(scene.curves.size() * 2, 0);
  // Every curve's storage and its coarser levels, built on the solver's workers (each curve's
  // own, so the result does not depend on the thread count).
  const bool smooth = settings.discontinuities == DiscontinuityMode::None;
  solver.storage_.resize(scene.curves.size());
  solver.levels_.resize(scene.curves.size());
  solver.worker_pool().for_each(scene.curves.size(), [&](std::size_t c) {
    if (cancelled()) return;
    const Curve& curve = scene.curves[c];
    // Footprints spread every deposit over the ray's width, so the deposited density is smooth on
    // that scale: elements shorter than kFootprintFinestElement x the width resolve only the
    // spread, while each hit pays for every span it covers. Auto storage stops refining where the
    // curve's longest element would be shorter.
    int curve_finest = finest_level;
    // A level has at least one element a segment before it halves them: a curve of many segments
    // stops refining where its own count would pass the room (counting kAutoBaseElements << level
    // built 1024 elements a curve for 3,900 photons on curves of 256 segments).
    const auto base = std::max<double>(kAutoBaseElements, curve.segment_count);
    while (solver.auto_storage_ && curve_finest > 0 && std::ldexp(base, curve_finest) > room) --curve_finest;
    if (solver.auto_storage_ && settings.ray_width > 0.0 && settings.ray_mode == RayMode::Footprint) {
      while (curve_finest > 0 && longest_element(scene, curve, elements, smooth, events[c], curve_finest) <
                                     kFootprintFinestElement * settings.ray_width)
        --curve_finest;
    }
    CurveStorage& finest = solver.storage_[c];
    finest = build_curve_storage(scene, curve, settings.basis, elements, smooth, events[c], curve_finest);
    if (estimator == Estimator::Local) build_local_estimator(scene, curve, finest, hermite);
    // The coarser levels, each with its restriction from the finest.
    std::vector<Level>& levels = solver.levels_[c];
    for (int level = 0; level < curve_finest; ++level) {
      if (cancelled()) return;
      Level& coarse = levels.emplace_back();
      coarse.storage = build_curve_storage(scene, curve, settings.basis, elements, smooth, events[c], level);
      if (estimator == Estimator::Local) build_local_estimator(scene, curve, coarse.storage, hermite);
      coarse.restriction = restriction_between(coarse.storage.basis, finest.basis);
    }
  });
  if (cancelled()) return Error{kSolverCancelled};
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    const Curve& curve = scene.curves[c];
    solver.segment_choice_.push_back(segment_choice(scene, curve));
    solver.chosen_level_.push_back(static_cast<int>(solver.levels_[c].size()));
    const Material& material = scene.material_of(curve);
    for (Side side : {Side::Front, Side::Back}) {
      if (!curve.has_side(side)) continue;
      const std::uint32_t block = c * 2 + static_cast<std::uint32_t>(side);
      solver.block_offset_[block] = static_cast<std::uint32_t>(solver.coefficient_count_);
      solver.block_reflectivity_[block] = material.reflectivity;
      bool black = true;
      for (std::size_t ch = 0; ch < channels; ++ch) black = black && !(material.reflectivity[ch] > 0.0);
      solver.block_black_[block] = black ? 1 : 0;
      solver.coefficient_count_ += solver.storage_[c].basis.size();
      solver.coefficient_block_.resize(solver.coefficient_count_, block);
      double mean = 0.0;
      for (std::size_t ch = 0; ch < channels; ++ch) mean += material.reflectivity[ch];
      weighted_reflectivity += curve.length * mean / static_cast<double>(channels);
      reflecting_length += curve.length;
    }
  }
  if (reflecting_length > 0.0) solver.initial_ratio_ = weighted_reflectivity / reflecting_length;
  // Runs of whole curves holding at least kCurveChunkCoefficients coefficients (the last may hold
  // fewer): the pieces in which per-round work over the storage is shared among the threads.
  solver.curve_chunks_.assign(1, 0);
  std::size_t in_chunk = 0;
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    for (Side side : {Side::Front, Side::Back})
      if (scene.curves[c].has_side(side)) in_chunk += solver.storage_[c].basis.size();
    if (in_chunk >= kCurveChunkCoefficients || c + 1 == scene.curves.size()) {
      solver.curve_chunks_.push_back(c + 1);
      in_chunk = 0;
    }
  }
  solver.walk_ = settings.transport == Transport::Walk;
  if (solver.walk_) {
    // A walk goes on with probability max rho at every hit, so its number of rays is at most
    // geometric with mean 1 / (1 - max rho) over the scene's reflecting sides.
    double most = 0.0;
    const Curve* brightest = nullptr;
    for (const Curve& curve : scene.curves)
      for (std::size_t ch = 0; ch < channels; ++ch)
        if (scene.material_of(curve).reflectivity[ch] > most) {
          most = scene.material_of(curve).reflectivity[ch];
          brightest = &curve;
        }
    if (most > kWalkMaxReflectivity) {
      char message[320];
      std::snprintf(message, sizeof message,
                    "%s: curve '%s' reflects %.9g: a random walk would average %.3g rays; "
                    "walks need every reflectivity at most %g (use transport shooting)",
                    scene.source.c_str(), brightest->id.c_str(), most, 1.0 / (1.0 - most),
                    kWalkMaxReflectivity);
      return Error{message};
    }
    solver.walk_expected_rays_ = 1.0 / (1.0 - most);
  }

  // The first round shoots the emitted power: on each emitting side E times the basis integrals.
  solver.received_.assign(solver.coefficient_count_ * channels, 0.0);
  if (solver.auto_storage_) solver.received_half_.assign(solver.coefficient_count_ * channels, 0.0);
  solver.unshot_.assign(solver.coefficient_count_ * channels, 0.0);
  solver.reflected_.assign(solver.coefficient_count_ * channels, 0.0);
  if (settings.ray_width > 0.0) {
    solver.ray_kind_ = settings.ray_mode == RayMode::Band ? RayKind::Band : RayKind::Footprint;
    if (solver.ray_kind_ == RayKind::Band) {
      profile_quadrature(settings.ray_profile, settings.band_rays, solver.band_offsets_,
                         solver.band_weights_);
    } else if (is_polynomial(settings.ray_profile)) {
      // Whole knot spans of the deposit mesh from precomputed moments (footprint.hpp).
      solver.footprint_tables_.reserve(scene.curves.size());
      for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
        if (cancelled()) return Error{kSolverCancelled};
        solver.footprint_tables_.emplace_back(scene, scene.curves[c], solver.storage_[c].basis,
                                              profile_powers(settings.ray_profile));
      }
    }
  }
  const bool reconstructed = settings.sampling == PositionSampling::Reconstructed;
  solver.sample_hermite_ = reconstructed && settings.basis == BasisKind::Hermite;
  solver.sample_by_coefficient_ = reconstructed && !solver.sample_hermite_;
  if (settings.basis == BasisKind::Hermite) {
    solver.hermite_reflected_.resize(solver.block_offset_.size());
    solver.hermite_unshot_.resize(solver.block_offset_.size());
  }
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    const Curve& curve = scene.curves[c];
    const CurveStorage& storage = solver.storage_[c];
    if (!scene.is_emitter(curve)) continue;
    const std::vector<double> emitted = project_emittance_profile(scene, curve, storage);
    for (Side side : {Side::Front, Side::Back}) {
      const std::uint32_t offset = solver.block_offset(c, side);
      if (offset == kNoBlock) continue;
      for (std::size_t k = 0; k < storage.basis.size(); ++k)
        for (std::size_t ch = 0; ch < channels; ++ch)
          solver.unshot_[(offset + k) * channels + ch] = curve.emittance[ch] * emitted[k];
      for (std::size_t ch = 0; ch < channels; ++ch)
        solver.emitted_[ch] += curve.emittance[ch] * curve.length * curve.profile_mean;
    }
  }
  for (std::size_t ch = 0; ch < channels; ++ch) solver.emitted_total_ += solver.emitted_[ch];
  // Walks start from the emission in every round; nothing waits to be shot.
  if (solver.walk_) {
    solver.emission_ = solver.unshot_;
    std::fill(solver.unshot_.begin(), solver.unshot_.end(), 0.0);
  }
  if (!(solver.emitted_total_ > 0.0))
    return Error{scene.source + ": no curve emits light (give a material or curve an emittance > 0)"};
  // Emittance (<= 1e100 with profile factors <= 1e100) times a length (<= 1e100 x segments) fits
  // a double, but the books and fixed-point units need headroom: refuse what comes near the edge.
  if (!(solver.emitted_total_ < 1e290) || !(solver.emitted_total_ > 1e-290)) {
    char message[256];
    std::snprintf(message, sizeof message,
                  "%s: the emitted power is %.3g, outside the supported 1e-290 .. 1e290; scale "
                  "the emittances (or the coordinates) so that it is",
                  scene.source.c_str(), solver.emitted_total_);
    return Error{message};
  }
  if (cancelled()) return Error{kSolverCancelled};
  return solver;
}

bool Solver::has_side(std::uint32_t curve, Side side) const {
  return block_offset(curve, side) != kNoBlock;
}

void Solver::estimate_on(const CurveStorage& storage, const double* power, double* coefficients,
                         std::size_t stride) const {
  if (settings_.estimator == Estimator::Galerkin) {
    galerkin_estimate(storage, power, coefficients, stride);
  } else if (settings_.estimator == Estimator::Local) {
    local_estimate(storage, power, coefficients, stride);
  } else {
    for (std::size_t k = 0; k < storage.basis.size(); ++k)
      coefficients[k * stride] = power[k * stride] / storage.basis_length[k];
  }
}

const CurveStorage& Solver::level_storage(std::uint32_t curve, int level) const {
  const std::vector<Level>& levels = levels_[curve];
  return level < static_cast<int>(levels.size()) ? levels[static_cast<std::size_t>(level)].storage : storage_[curve];
}

std::vector<double> Solver::estimate_in_level(std::uint32_t curve, int level, const double* power,
                                              std::size_t stride) const {
  const std::vector<Level>& levels = levels_[curve];
  const std::size_t n = level_storage(curve, level).basis.size();
  std::vector<double> deposits(n);
  std::vector<double> estimate(n);
  if (level >= static_cast<int>(levels.size())) {
    for (std::size_t k = 0; k < n; ++k) deposits[k] = power[k * stride];
    estimate_on(storage_[curve], deposits.data(), estimate.data(), 1);
    return estimate;
  }
  // Deposits of the coarse level follow from the fine ones.
  const Level& coarse = levels[static_cast<std::size_t>(level)];
  restrict_deposits(coarse.restriction, power, stride, deposits.data());
  estimate_on(coarse.storage, deposits.data(), estimate.data(), 1);
  return estimate;
}

void Solver::estimate_at_level(std::uint32_t curve, int level, const double* power,
                               double* coefficients, std::size_t stride) const {
  if (level >= static_cast<int>(levels_[curve].size())) {
    estimate_on(storage_[curve], power, coefficients, stride);
    return;
  }
  // A coarse level's estimate, prolonged, is the same function in the fine basis.
  const std::vector<double> estimate = estimate_in_level(curve, level, power, stride);
  prolong_coefficients(levels_[curve][static_cast<std::size_t>(level)].restriction, estimate.data(), coefficients,
                       stride);
}

bool Solver::holds_power(const std::vector<double>& values, std::uint32_t curve, std::uint32_t offset) const {
  const auto channels = static_cast<std::size_t>(channels_);
  const double* block = &values[offset * channels];
  return std::any_of(block, block + storage_[curve].basis.size() * channels, [](double x) { return x != 0.0; });
}

void Solver::estimate(const std::vector<double>& power, std::vector<double>& coefficients) const {
  coefficients.assign(power.size(), 0.0);
  for (std::uint32_t c = 0; c < scene_->curves.size(); ++c) estimate_curve(c, power, coefficients);
}

void Solver::estimate_curve(std::uint32_t c, const std::vector<double>& power, std::vector<double>& coefficients) const {
  const auto channels = static_cast<std::size_t>(channels_);
  for (Side side : {Side::Front, Side::Back}) {
    const std::uint32_t offset = block_offset(c, side);
    if (offset == kNoBlock) continue;
    // Every estimator is linear: a side that holds no power (most sides of a large scene in a
    // round of a few photons) keeps its zero coefficients without a solve.
    if (!holds_power(power, c, offset)) continue;
    for (std::size_t ch = 0; ch < channels; ++ch) {
      const std::size_t first = offset * channels + ch;
      estimate_at_level(c, chosen_level_[c], &power[first], &coefficients[first], channels);
    }
  }
}

void Solver::for_each_curve(const std::function<void(std::uint32_t)>& f) {
  // Each curve's work writes only that curve's coefficients, so the split changes no result.
  auto chunk = [&](std::size_t i) {
    for (std::uint32_t c = curve_chunks_[i]; c < curve_chunks_[i + 1]; ++c) f(c);
  };
  const std::size_t chunks = curve_chunks_.size() - 1;
  if (threads_ > 1 && chunks > 1) {
    worker_pool().for_each(chunks, chunk);
  } else {
    for (std::size_t i = 0; i < chunks; ++i) chunk(i);
  }
}

void Solver::choose_levels(const std::vector<double>& received, const std::vector<double>& half) {
  // Per curve, with the reflected power summed over channels (rho times received) on each side:
  // the estimate f_l at every level l, and f_l^A, f_l^B from the two halves of the photons (odd
  // and even numbers in their round: independent, with equal means; with Sobol' two independently
  // scrambled nets, see shoot). Then, in the L2 norm along
  // the curve (the fine mass matrix),
  //   variance  V_l = |f_l^A - f_l^B|^2     (its expectation is Var f_l^A + Var f_l^B = Var f_l),
  //   bias^2    |f_l - f_(l+1)|^2 less its own noise |D^A - D^B|^2 (D^X = f_l^X - f_(l+1)^X),
  //             times (2^q / (2^q - 1))^2: with the bias shrinking by 2^q per level (q the
  //             estimator's order), f_l - f_(l+1) is (1 - 2^-q) of level l's bias; the finest
  //             level's bias is the one below it over 2^q,
  // and the level kept minimises bias^2 + V (ties: the coarser). Each level's bias comes from its
  // own step to the next: sums of steps accumulate their noise, and differences to the finest
  // level carry the finest level's large variance, both of which pushed choices off the best.
  const auto channels = static_cast<std::size_t>(channels_);
  for (std::uint32_t c = 0; c < scene_->curves.size(); ++c) {
    const int finest = static_cast<int>(levels_[c].size());
    if (finest == 0) continue;
    const CurveStorage& fine = storage_[c];
    const std::size_t n = fine.basis.size();
    const auto count = static_cast<std::size_t>(finest) + 1;
    // A curve that received nothing keeps its level (as one whose reflected power is zero does).
    bool received_any = false;
    for (Side side : {Side::Front, Side::Back}) {
      const std::uint32_t offset = block_offset(c, side);
      received_any = received_any || (offset != kNoBlock && holds_power(received, c, offset));
    }
    if (!received_any) continue;
    // Per side, the reflected power summed over channels (rho times received): all photons, and
    // the halves A and B.
    std::vector<std::array<std::vector<double>, 3>> reflected;
    double total = 0.0;
    for (Side side : {Side::Front, Side::Back}) {
      const std::uint32_t offset = block_offset(c, side);
      if (offset == kNoBlock) continue;
      const Spectrum& rho = block_reflectivity_[c * 2 + static_cast<std::uint32_t>(side)];
      auto& [all, a, b] = reflected.emplace_back();
      all.assign(n, 0.0);
      a.assign(n, 0.0);
      b.assign(n, 0.0);
      for (std::size_t k = 0; k < n; ++k)
        for (std::size_t ch = 0; ch < channels; ++ch) {
          const std::size_t index = (offset + k) * channels + ch;
          all[k] += rho[ch] * received[index];
          a[k] += rho[ch] * half[index];
        }
      for (std::size_t k = 0; k < n; ++k) {
        b[k] = all[k] - a[k];
        total += all[k];
      }
    }
    const std::size_t sides = reflected.size();
    if (sides == 0 || !(total > 0.0)) continue;
    // Each level's function as a vector whose squared norm is its squared L2 norm along the curve:
    // a spline's coefficients prolonged into the fine basis (the norm through the fine mass
    // matrix), or a Hermite curve's values at two Gauss-Legendre points in arc length on every
    // finest span (every level's Hermite curve is a cubic in arc length there; the rule is exact
    // for the squared norm of differences up to linear, an approximation for cubic ones that chose
    // the same levels as four points on the tests' scenes at half the cost): the level is chosen by
    // the error of what is reconstructed.
    const bool hermite = settings_.basis == BasisKind::Hermite;
    std::vector<double> at;       // increasing arc lengths
    std::vector<double> weights;  // the quadrature's weight of each
    if (hermite) {
      const double gauss = 1.0 / std::sqrt(3.0);
      const std::vector<double>& knots = fine.basis.knots();
      double s1 = arc_length_at(c, knots[fine.basis.first_span()]);  // each knot's arc length once
      for (std::size_t span = fine.basis.first_span(); span < fine.basis.end_span(); ++span) {
        if (!(knots[span + 1] > knots[span])) continue;
        const double s0 = s1;
        s1 = arc_length_at(c, knots[span + 1]);
        const double half_width = 0.5 * (s1 - s0);
        for (const double x : {-gauss, gauss}) {
          at.push_back(s0 + half_width * (1.0 + x));
          weights.push_back(half_width);
        }
      }
    }
    const std::size_t width = hermite ? at.size() : n;
    auto represent = [&](std::size_t level, const std::vector<double>& source, double* out) {
      if (!hermite) {
        estimate_at_level(c, static_cast<int>(level), source.data(), out, 1);
        return;
      }
      const std::vector<double> nodal = estimate_in_level(c, static_cast<int>(level), source.data(), 1);
      hermite_of(c, static_cast<int>(level), nodal.data()).evaluate_increasing(at, out);
    };
    // [level][side][i]: full, A and B estimates.
    using PerLevel = std::vector<std::vector<double>>;
    PerLevel full(count, std::vector<double>(sides * width));
    PerLevel part_a = full;
    PerLevel part_b = full;
    const std::array<PerLevel*, 3> targets = {&full, &part_a, &part_b};
    for (std::size_t level = 0; level < count; ++level)
      for (std::size_t side = 0; side < sides; ++side)
        for (std::size_t set = 0; set < 3; ++set)
          represent(level, reflected[side][set], (*targets[set])[level].data() + side * width);
    // |x|^2 = x^T M x = |L^T x|^2 per side, with M's Cholesky factor L in envelope storage (a
    // Hermite curve: the Gauss rule above on its values).
    auto norm2 = [&](auto value) {
      double sum = 0.0;
      if (hermite) {
        for (std::size_t i = 0; i < sides * width; ++i) sum += weights[i % width] * value(i) * value(i);
        return sum;
      }
      std::vector<double> y(n);
      for (std::size_t s = 0; s < sides; ++s) {
        std::fill(y.begin(), y.end(), 0.0);
        for (std::size_t row = 0; row < n; ++row) {
          const double x = value(s * n + row);
          for (std::size_t col = fine.mass_first[row]; col <= row; ++col)
            y[col] += fine.mass_cholesky[fine.mass_offset[row] + col - fine.mass_first[row]] * x;
        }
        for (double v : y) sum += v * v;
      }
      return sum;
    };
    // The estimator's order q: its bias shrinks by 2^q per level.
    const int degree = fine.basis.degree();
    const double order = settings_.estimator == Estimator::Lumped ? std::min(degree + 1, 2) : degree + 1.0;
    const double richardson = std::pow(2.0, order) / (std::pow(2.0, order) - 1.0);
    const std::size_t last = count - 1;
    double best = std::numeric_limits<double>::infinity();
    double bias2 = 0.0;
    int chosen = finest;
    for (std::size_t l = 0; l < count; ++l) {
      if (l < last) {
        const double difference = norm2([&](std::size_t i) { return full[l][i] - full[l + 1][i]; });
        const double noise = norm2([&](std::size_t i) {
          return (part_a[l][i] - part_a[l + 1][i]) - (part_b[l][i] - part_b[l + 1][i]);
        });
        bias2 = std::max(difference - noise, 0.0) * richardson * richardson;
      } else {
        bias2 /= std::pow(2.0, 2.0 * order);  // the finest: the last step's bias, one level on
      }
      const double variance = norm2([&](std::size_t i) { return part_a[l][i] - part_b[l][i]; });
      if (bias2 + variance < best) {
        best = bias2 + variance;
        chosen = static_cast<int>(l);
      }
    }
    chosen_level_[c] = chosen;
  }
}

int Solver::storage_elements(std::uint32_t curve) const {
  const int level = chosen_level_[curve];
  const CurveStorage& storage = level < static_cast<int>(levels_[curve].size())
                                    ? levels_[curve][static_cast<std::size_t>(level)].storage
                                    : storage_[curve];
  int spans = 0;
  const std::vector<double>& knots = storage.basis.knots();
  for (std::size_t span = storage.basis.first_span(); span < storage.basis.end_span(); ++span)
    spans += knots[span + 1] > knots[span];
  return spans;
}

double Solver::arc_length_at(std::uint32_t curve, double u) const {
  return flatland::arc_length_at(*scene_, scene_->curves[curve], u);
}

HermiteReconstruction Solver::hermite_of(std::uint32_t curve, int level, const double* values) const {
  // Hat k of a linear B-spline peaks at knots[k + 1] (its Greville point); two hats peaking at the
  // same place are the two sides of a C-1 node.
  const CurveStorage& storage = level_storage(curve, level);
  const std::vector<double>& knots = storage.basis.knots();
  HermiteInput input;
  std::size_t next_node = 0;  // storage.nodes is sorted by u, as the Greville points are
  for (std::size_t k = 0; k < storage.basis.size(); ++k) {
    const double u = knots[k + 1];
    const double value = values[k];
    if (k > 0 && u == knots[k]) {  // the right side of a jump
      input.right.back() = value;
      continue;
    }
    while (next_node < storage.nodes.size() && storage.nodes[next_node].u < u) ++next_node;
    const Continuity continuity =
        next_node < storage.nodes.size() && storage.nodes[next_node].u == u
            ? storage.nodes[next_node].continuity
            : Continuity::C1;
    input.u.push_back(arc_length_at(curve, u));
    input.left.push_back(value);
    input.right.push_back(value);
    input.continuity.push_back(continuity);
  }
  if (storage.basis.is_periodic()) {
    // Hat 0 peaks at the closing point: it is node 0 and, a lap later, node n.
    input.periodic = true;
    input.continuity.front() = storage.closing;
    input.u.push_back(scene_->curves[curve].length);
    input.left.push_back(values[0]);
    input.right.push_back(values[0]);
    input.continuity.push_back(storage.closing);
  }
  return HermiteReconstruction(input);
}

std::size_t Solver::discontinuity_nodes() const {
  std::size_t count = 0;
  for (const CurveStorage& storage : storage_)
    for (const MeshNode& node : storage.nodes) count += node.continuity != Continuity::C1;
  return count;
}

std::uint64_t Solver::photons_for_round(double unshot) const {
  // Photons of (about) equal power in every round: this round gets the share of the remaining
  // budget that its power is of all the power still to be shot. With the observed decay ratio r
  // of the unshot power, that is about U / (1 - r) (the geometric tail; ignoring where the
  // tolerance cuts it off keeps a reserve, so the budget is never spent one round too early).
  // Every round shoots at least kMinPhotonsPerRound, so the rounds still needed to reach the
  // tolerance, K = ln(tolerance E / U) / ln r, each get that much set aside first; when the budget
  // cannot pay for them all, the solve ends with its budget spent and says how much is unshot.
  const std::uint64_t remaining = settings_.photons - photons_shot_;
  const double ratio =
      std::clamp(rounds_ == 0 ? initial_ratio_ : unshot / previous_unshot_, 0.0, 0.999999);
  const double target = settings_.tolerance * emitted_total_;
  double later_rounds = 0.0;
  if (ratio > 0.0 && unshot > target)
    later_rounds = std::clamp(std::ceil(std::log(target / unshot) / std::log(ratio)) - 1.0, 0.0, 1e15);
  const double reserve = later_rounds * static_cast<double>(kMinPhotonsPerRound);
  const double available = std::max(0.0, static_cast<double>(remaining) - reserve);
  auto photons = static_cast<std::uint64_t>(std::llround(available * (1.0 - ratio)));
  photons = std::max(photons, std::min(remaining, kMinPhotonsPerRound));
  return std::min({photons, remaining, kMaxPhotonsPerRound});
}

std::uint64_t Solver::walks_for_round() const {
  const std::uint64_t remaining = settings_.photons - photons_shot_;
  return std::min({std::max(kMinWalksPerRound, photons_shot_ / 2), kMaxWalksPerRound, remaining});
}

bool Solver::begin_round() {
  const auto channels = static_cast<std::size_t>(channels_);
  // Shooting draws from the power waiting to be shot, walks from the emission.
  const std::vector<double>& pool = walk_ ? emission_ : unshot_;
  std::vector<double> weights(block_offset_.size(), 0.0);
  std::vector<Spectrum> block_unshot(block_offset_.size(), Spectrum{});
  for (std::uint32_t c = 0; c < scene_->curves.size(); ++c) {
    for (Side side : {Side::Front, Side::Back}) {
      const std::uint32_t offset = block_offset(c, side);
      if (offset == kNoBlock) continue;
      const std::uint32_t block = c * 2 + static_cast<std::uint32_t>(side);
      const std::size_t count = storage_[c].basis.size();
      for (std::size_t k = 0; k < count; ++k)
        for (std::size_t ch = 0; ch < channels; ++ch)
          block_unshot[block][ch] += pool[(offset + k) * channels + ch];
      for (std::size_t ch = 0; ch < channels; ++ch) weights[block] += block_unshot[block][ch];
    }
  }
  const double unshot = std::accumulate(weights.begin(), weights.end(), 0.0);
  if (!walk_ && !(unshot > settings_.tolerance * emitted_total_)) {
    stop_reason_ = StopReason::Converged;
    choose_final_levels();
    return false;
  }
  if (photons_shot_ >= settings_.photons) {
    stop_reason_ = StopReason::BudgetSpent;
    choose_final_levels();
    return false;
  }
  round_.photons = walk_ ? walks_for_round() : photons_for_round(unshot);

  // Fixed point: unshot * scale < 2^61, and scale a power of two so units convert exactly.
  // A walk tallies its power at every hop, so a round of n walks deposits about n R times a
  // walk's power, R the mean rays per walk (at most walk_expected_rays_): the scale gives up H
  // bits, 2^H >= R (1 + 64 / n), so the total stays below 2^63 unless the round's rays exceed
  // 4 R n + 256 R, which for a sum of n geometric counts is rarer than e^-60. With n <= 2^20 and
  // R <= 1e6 a walk still carries at least 2^18 units.
  round_.headroom_bits = 0;
  if (walk_) {
    const double rays = walk_expected_rays_ * (1.0 + 64.0 / static_cast<double>(round_.photons));
    round_.headroom_bits = std::max(0, static_cast<int>(std::ceil(std::log2(rays))));
    walk_headroom_bits_ = std::max(walk_headroom_bits_, round_.headroom_bits);
  }
  round_.scale = std::ldexp(1.0, 60 - round_.headroom_bits - std::ilogb(unshot));
  // A photon from source j carries U_j / (n p_j) with p_j = w_j / U: its channels sum to U / n.
  // Sources are the sides of curves (uniform sampling) or single coefficients (reconstructed
  // sampling, so a photon also takes the colour of the unshot light where it starts).
  const bool by_coefficient = sample_by_coefficient_;
  // The unshot density of every block, channels summed, for the positions; each photon carries
  // its block's colour (its power comes from the deposits, so the books stay exact).
  if (sample_hermite_) update_hermite(pool, false);
  const std::size_t sources = by_coefficient ? coefficient_count_ : block_offset_.size();
  // Scratch kept between rounds (a fresh allocation of the storage's size faulted its pages in
  // every round).
  std::vector<double>& source_weights = source_weights_;
  source_weights.assign(sources, 0.0);
  round_.photon_units.assign(sources, {});
  const double per_photon = unshot / static_cast<double>(round_.photons);
  // With the Galerkin or local estimator the reconstructed unshot density has coefficients g
  // (M^-1 U, or the local weights times U) rather than U / L, and with auto storage it is the
  // chosen level's estimate: clamped at zero, keeping each curve side's power, coefficient k of the
  // finest basis carries the power g_k integral(phi_k ds).
  std::vector<double>& density_power = density_power_;
  density_power.clear();
  if (by_coefficient && (settings_.estimator != Estimator::Lumped || auto_storage_)) {
    density_power.assign(pool.size(), 0.0);
    // A solve per curve side and channel: shared among the threads, by runs of curves.
    for_each_curve([&](std::uint32_t c) {
      estimate_curve(c, pool, density_power);
      for (Side side : {Side::Front, Side::Back}) {
        const std::uint32_t offset = block_offset(c, side);
        if (offset == kNoBlock) continue;
        const CurveStorage& storage = storage_[c];
        for (std::size_t ch = 0; ch < channels; ++ch) {
          // The side's deposited unshot power, exactly; where the estimate has no positive part
          // left (a local estimate on a region too short for its window can), the lumped density.
          double power = 0.0;
          for (std::size_t k = 0; k < storage.basis.size(); ++k) power += pool[(offset + k) * channels + ch];
          if (!clamp_keeping_power(storage, &density_power[offset * channels + ch], channels, power))
            for (std::size_t k = 0; k < storage.basis.size(); ++k)
              density_power[(offset + k) * channels + ch] =
                  pool[(offset + k) * channels + ch] / storage.basis_length[k];
        }
        for (std::size_t k = 0; k < storage_[c].basis.size(); ++k)
          for (std::size_t ch = 0; ch < channels; ++ch)
            density_power[(offset + k) * channels + ch] *= storage_[c].basis_length[k];
      }
    });
  }
  const std::vector<double>& coefficient_power = density_power.empty() ? pool : density_power;
  for (std::size_t j = 0; j < sources; ++j) {
    const double* power = by_coefficient ? &coefficient_power[j * channels] : block_unshot[j].data();
    for (std::size_t ch = 0; ch < channels; ++ch) source_weights[j] += power[ch];
    if (!(source_weights[j] > 0.0)) continue;
    for (std::size_t ch = 0; ch < channels; ++ch)
      round_.photon_units[j][ch] =
          std::llround(power[ch] / source_weights[j] * per_photon * round_.scale);
  }
  round_.sources.assign(source_weights);
  return true;
}

void Solver::shoot_batch(Rng& rng, std::uint64_t first, std::uint64_t count, Accumulator& acc,
                         std::vector<PhotonPath>* paths, std::size_t path_limit) const {
  // The ray kind is fixed per solve: each kind gets its own compiled loop, so point rays carry no
  // footprint or band code at all.
  switch (ray_kind_) {
    case RayKind::Point: return shoot<RayKind::Point>(rng, first, count, acc, paths, path_limit);
    case RayKind::Footprint:
      return shoot<RayKind::Footprint>(rng, first, count, acc, paths, path_limit);
    case RayKind::Band: return shoot<RayKind::Band>(rng, first, count, acc, paths, path_limit);
  }
}

template <Solver::RayKind kRays>
void Solver::shoot(Rng& rng, std::uint64_t first, std::uint64_t count, Accumulator& acc,
                   std::vector<PhotonPath>* paths, std::size_t path_limit) const {
  std::vector<FootprintWeight> footprint;
  if constexpr (kRays == RayKind::Footprint) footprint.reserve(64);
  const auto channels = static_cast<std::size_t>(channels_);
  const double scale = scene_->scale;
  // Randomised quasi-Monte Carlo: photon j of the round takes point j of the round's scrambled
  // Sobol' sequence (named by seed and round), whichever batch, step or thread shoots it; its
  // coordinates (PhotonDimension) and how rejection loops use them are in origins.hpp.
  static_assert(kAcceptLobe < kSobolDimensions);
  const bool qmc = settings_.sampler == SamplerKind::Sobol;
  // With auto storage the round's photons form two halves, even and odd numbers, whose spread
  // measures the estimate's variance (choose_levels): the halves must be independent, so with
  // Sobol' each is a net of its own, scrambled independently (streams 2 round and 2 round + 1),
  // photon i taking point i / 2 of its half's. (Halves of one net are stratified against each
  // other: parity fixes the first digit of the first coordinate, and their difference is far
  // from noise.) A fixed mesh keeps one net per round (stream `round`).
  const bool halves = qmc && auto_storage_;
  const ScrambledSobol sobol(settings_.seed, halves ? 2 * std::uint64_t{rounds_} : rounds_);
  const ScrambledSobol sobol_odd(settings_.seed, 2 * std::uint64_t{rounds_} + 1);
  // Consecutive photons of a half take consecutive points: one XOR per dimension each.
  SobolCursor cursor(sobol);
  SobolCursor cursor_odd(sobol_odd);
  // The source, by unshot power: a side of a curve, or one of its coefficients. Sobol': from the
  // photon's point (what the choice leaves of dimension kPlace places the origin); random: from
  // the round's indexed uniforms, so that the choice does not depend on how the round is cut into
  // batches and steps either.
  const std::uint64_t key = source_key(settings_.seed, rounds_);
  auto choose_source = [&](SobolCursor& even_point, SobolCursor& odd_point, std::uint32_t index, double& place) {
    if (!qmc) return round_.sources.sample(indexed_uniform(key, index));
    SobolCursor& point = halves && (index & 1u) != 0 ? odd_point : even_point;
    point.seek(halves ? index >> 1 : index);
    return round_.sources.sample(point.sample(kPlace), place);
  };
  // With many coefficients (their sampler's pieces, units and blocks far beyond the caches) every
  // photon's source is chosen first, and while photon i is shot the data of photon i + kAhead's
  // are asked for (docs/performance-log.md, "Sources chosen ahead"); the same choices either way.
  const bool by_coefficient = sample_by_coefficient_;
  const bool ahead = by_coefficient && coefficient_count_ >= kAheadFrom;
  std::vector<std::uint32_t>& sources = acc.sources;
  std::vector<double>& places = acc.places;
  if (ahead) {
    sources.resize(count);
    places.resize(count);
    SobolCursor even_point(sobol);
    SobolCursor odd_point(sobol_odd);
    for (std::uint64_t i = 0; i < count; ++i) {
      double place = 0.0;
      sources[i] = static_cast<std::uint32_t>(choose_source(even_point, odd_point, static_cast<std::uint32_t>(first + i), place));
      places[i] = place;
    }
  }
  constexpr std::uint64_t kAhead = 4;
  for (std::uint64_t i = 0; i < count; ++i) {
    if (ahead) {
      // Two stages: the source's own entries for photon i + 2 kAhead, then (those in cache by
      // now) its basis function's for photon i + kAhead.
      if (i + 2 * kAhead < count) {
        const std::uint32_t later = sources[i + 2 * kAhead];
        prefetch(&round_.photon_units[later]);
        prefetch(&coefficient_block_[later]);
      }
      if (i + kAhead < count) {
        const std::uint32_t later = sources[i + kAhead];
        const std::uint32_t block = coefficient_block_[later];
        const CurveStorage& storage = storage_[block / 2];
        const std::size_t k = later - block_offset_[block];
        storage.sampler.prefetch(k, qmc);
        prefetch(&storage.speed_bound[k]);
      }
    }
    const auto index = static_cast<std::uint32_t>(first + i);  // < kMaxPhotonsPerRound
    // Auto storage: odd-numbered photons deposit into the accumulator's second half.
    if (auto_storage_) acc.half_offset = (index & 1u) != 0 ? coefficient_count_ * static_cast<std::size_t>(channels_) : 0;
    const bool odd = halves && (index & 1u) != 0;
    const std::uint32_t net_index = halves ? index >> 1 : index;
    SobolCursor& net_point = odd ? cursor_odd : cursor;
    if (qmc) net_point.seek(net_index);
    auto quasi = [&net_point](int dimension) { return net_point.sample(dimension); };
    double place = ahead ? places[i] : 0.0;
    const std::size_t source = ahead ? sources[i] : choose_source(cursor, cursor_odd, index, place);
    const std::uint32_t block =
        by_coefficient ? coefficient_block_[source] : static_cast<std::uint32_t>(source);
    const std::uint32_t curve_index = block / 2;
    const bool back = (block & 1u) != 0;
    const Curve& curve = scene_->curves[curve_index];
    const std::array<std::int64_t, 3>& units = round_.photon_units[source];
    for (std::size_t ch = 0; ch < channels; ++ch) acc.shot[ch] += units[ch];

    // Where the photon leaves (origins.hpp): emitted light of a curve with an emittance profile
    // (first round only, and every walk) where the profile says, reflected light where the
    // unshot density is (a coefficient's basis function or the Hermite reconstruction), or
    // uniformly in arc length.
    const bool emitted_light = rounds_ == 0 || walk_;
    OriginDraws draws{rng, qmc ? &net_point : nullptr, place};
    const Origin leaves =
        emitted_light && !curve.emittance_profile.empty()
            ? sample_profiled_origin(*scene_, curve, segment_choice_[curve_index], draws)
        : by_coefficient
            ? sample_coefficient_origin(*scene_, curve, storage_[curve_index],
                                        source - block_offset_[block], line_tangents_, draws)
        : sample_hermite_
            ? sample_hermite_origin(*scene_, curve, hermite_unshot_[block], draws)
            : sample_uniform_origin(*scene_, curve, segment_choice_[curve_index], line_tangents_, draws);
    const std::uint32_t segment_index = leaves.segment;
    const double t = leaves.t;
    const Vec2 origin = leaves.position;
    const Vec2 tangent = leaves.tangent;
    // Directions: diffuse, except an emitter's own light in the first round (every later round
    // shoots reflected light only) when its material says otherwise.
    const Vec2 normal = back ? -perp(tangent) : perp(tangent);
    Vec2 direction;
    const Emission& emission = scene_->material_of(curve).emission;
    if (!emitted_light || emission.kind == Emission::Kind::Diffuse) {
      direction = square_to_diffuse(qmc ? quasi(kDirection) : rng.uniform(), normal);
    } else if (emission.kind == Emission::Kind::Lobe) {
      // Sobol': sample_lobe's first proposal (theta uniform, kept with probability cos^n) from
      // the point; when it is refused, sample_lobe draws afresh from the stream.
      const double theta = qmc ? (quasi(kDirection) - 0.5) * std::numbers::pi : 0.0;
      const double c = std::cos(theta);
      if (qmc && quasi(kAcceptLobe) < std::pow(c, emission.exponent))
        direction = std::sin(theta) * Vec2{normal.y, -normal.x} + c * normal;
      else
        direction = sample_lobe(rng, emission.exponent, normal);
    } else {
      direction = square_to_beam(qmc ? quasi(kDirection) : rng.uniform(), emission.half_angle, normal);
    }
    const Ray ray{origin, direction};

    PhotonPath* path = nullptr;
    if (paths != nullptr && paths->size() < path_limit) {
      path = &paths->emplace_back();
      path->origin = origin;
      path->source_curve = curve_index;
      path->source_side = back ? Side::Back : Side::Front;
      path->source_segment = segment_index;
      path->source_t = t;
      for (std::size_t ch = 0; ch < channels; ++ch)
        path->power[ch] = static_cast<double>(units[ch]) / round_.scale;
      path->bounce = walk_ ? 0 : rounds_;
    }
    if constexpr (kRays == RayKind::Band) {
      // K parallel sub-rays across the width W. Each starts on the source segment itself, moved
      // along it by offset * W / (2 cos(theta_out)) so the sub-rays' perpendicular spacing is the
      // profile's offsets times W/2 (clamped at the segment's ends, so no sub-ray starts outside
      // the scene). A sub-ray whose start does not face its direction (the source bends away)
      // leaves from the centre instead. Each carries its share of the units, the last one the
      // remainder, and deposits where it lands.
      const SceneSegment& emitter = scene_->segments[segment_index];
      const Cubic& shape = emitter.geometry.shape;
      const bool line_source = emitter.geometry.kind == SegmentKind::Line;
      const double along = 0.5 * settings_.ray_width /
                           std::max(dot(direction, normal), kGrazingCosine);
      const double s0 = line_source ? t * emitter.length : emitter.arc_length.length_at(shape, t);
      std::array<std::int64_t, 3> left = units;
      for (std::size_t ray_index = 0; ray_index < band_offsets_.size(); ++ray_index) {
        const bool last = ray_index + 1 == band_offsets_.size();
        std::array<std::int64_t, 3> share{};
        for (std::size_t ch = 0; ch < channels; ++ch) {
          share[ch] = last ? left[ch]
                           : static_cast<std::int64_t>(band_weights_[ray_index] *
                                                           static_cast<double>(units[ch]) + 0.5);
          left[ch] -= share[ch];
        }
        // Strictly inside the segment: from the very end point (a corner of a room) a sub-ray
        // could leave between the two walls.
        const double s_i = std::clamp(s0 + band_offsets_[ray_index] * along, 0x1.0p-40 * emitter.length,
                                      (1.0 - 0x1.0p-40) * emitter.length);
        double t_i = line_source ? s_i / emitter.length : emitter.arc_length.parameter_at(shape, s_i);
        Vec2 start = line_source ? lerp(shape.p[0], shape.p[3], t_i) : evaluate(shape, t_i);
        if (!line_source) {
          const Vec2 n_i = perp(unit_tangent(shape, t_i, scale));
          if (!((back ? -dot(n_i, direction) : dot(n_i, direction)) > 0.0)) {
            t_i = t;
            start = origin;
          }
        }
        const Ray sub{start, direction};
        const SceneHit hit = accelerator_.closest_hit(sub, RayOrigin{segment_index, t_i});
        receive<RayKind::Point>(hit, sub, share, acc,
                                ray_index == band_offsets_.size() / 2 ? path : nullptr, footprint);
      }
      acc.rays += band_offsets_.size();
    } else {
      const SceneHit hit = accelerator_.closest_hit(ray, RayOrigin{segment_index, t});
      ++acc.rays;
      receive<kRays>(hit, ray, units, acc, path, footprint);
      if (walk_) walk_on<kRays>(rng, hit, ray, units, acc, paths, path_limit, path, footprint);
    }
  }
}

Side Solver::side_hit(const SceneHit& hit, const Ray& ray, Vec2& tangent) const {
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

template <Solver::RayKind kRays>
void Solver::walk_on(Rng& rng, SceneHit hit, Ray ray, std::array<std::int64_t, 3> units,
                     Accumulator& acc, std::vector<PhotonPath>* paths, std::size_t path_limit,
                     PhotonPath* last, std::vector<FootprintWeight>& footprint) const {
  const auto channels = static_cast<std::size_t>(channels_);
  for (std::uint32_t bounce = 1;; ++bounce) {
    if (hit.segment == kNoSegment) return;  // escaped (receive booked it)
    Vec2 tangent;
    const Side side = side_hit(hit, ray, tangent);
    const std::uint32_t curve = segment_info_[hit.segment].curve;
    const std::uint32_t block = curve * 2 + static_cast<std::uint32_t>(side);
    if (block_offset_[block] == kNoBlock || block_black_[block]) {  // absorbed (receive booked it)
      if (last != nullptr) last->absorbed = true;
      return;
    }
    // Russian roulette: go on with probability q = max rho, each channel then carrying rho / q of
    // its power, so every channel's expected power after the bounce is rho times what arrived.
    // What the reweighting leaves behind (channels below the maximum, and rounding) is absorbed,
    // so every walk's units end exactly as absorbed or escaped.
    const Spectrum& rho = block_reflectivity_[block];
    double survive = 0.0;
    for (std::size_t ch = 0; ch < channels; ++ch) survive = std::max(survive, rho[ch]);
    if (!(rng.uniform() < survive)) {
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
    const Vec2 point = segment.geometry.kind == SegmentKind::Line ? lerp(shape.p[0], shape.p[3], hit.t)
                                                                  : evaluate(shape, hit.t);
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
      for (std::size_t ch = 0; ch < channels; ++ch)
        path->power[ch] = static_cast<double>(units[ch]) / round_.scale;
      path->bounce = bounce;
    }
    last = path;
    receive<kRays>(hit, ray, units, acc, path, footprint);
  }
}

template <Solver::RayKind kRays>
void Solver::receive(const SceneHit& hit, const Ray& ray, const std::array<std::int64_t, 3>& units,
                     Accumulator& acc, PhotonPath* path,
                     std::vector<FootprintWeight>& footprint) const {
  const auto channels = static_cast<std::size_t>(channels_);
  if (hit.segment == kNoSegment) {
    for (std::size_t ch = 0; ch < channels; ++ch) acc.escaped[ch] += units[ch];
    if (path != nullptr) {
      path->escaped = true;
      path->end = ray.origin + ray.direction;
    }
    return;
  }
  const SegmentInfo& info = segment_info_[hit.segment];
  Vec2 hit_tangent;
  const Side side = side_hit(hit, ray, hit_tangent);
  if (path != nullptr) {
    path->end = ray.origin + hit.distance * ray.direction;
    path->hit_curve = info.curve;
    path->hit_side = side;
    path->hit_s = arc_length_at(info.curve, info.index_in_curve + hit.t);
  }
  const std::uint32_t offset = block_offset(info.curve, side);
  // A side that reflects nothing (rho = 0 in every channel) turns all it receives into absorbed
  // power whatever the deposit's shape: no footprint or deposit is computed for it.
  if (offset == kNoBlock || block_black_[info.curve * 2 + static_cast<std::uint32_t>(side)]) {
    for (std::size_t ch = 0; ch < channels; ++ch) acc.absorbed[ch] += units[ch];
    return;
  }
  const double u = info.index_in_curve + hit.t;
  if constexpr (kRays == RayKind::Footprint) {
    // Spread along the receiver over the projected width with the profile; the weights sum to
    // one and the largest share takes the rounding remainder.
    const double cos_incidence = std::fabs(cross(hit_tangent, ray.direction)) / length(hit_tangent);
    footprint.clear();
    footprint_weights(*scene_, scene_->curves[info.curve], storage_[info.curve].basis, u,
                      footprint_half_length(settings_.ray_width, cos_incidence),
                      settings_.ray_profile, footprint, walls_[info.curve],
                      footprint_tables_.empty() ? nullptr : &footprint_tables_[info.curve]);
    std::size_t largest = 0;
    for (std::size_t i = 1; i < footprint.size(); ++i)
      if (footprint[i].weight > footprint[largest].weight) largest = i;
    for (std::size_t ch = 0; ch < channels; ++ch) {
      std::int64_t left = units[ch];
      for (std::size_t i = 0; i < footprint.size(); ++i) {
        if (i == largest) continue;
        const auto share = static_cast<std::int64_t>(footprint[i].weight * static_cast<double>(units[ch]) + 0.5);
        acc.received[acc.half_offset + (offset + footprint[i].coefficient) * channels + ch] += share;
        left -= share;
      }
      acc.received[acc.half_offset + (offset + footprint[largest].coefficient) * channels + ch] += left;
    }
  } else {
    // Deposit on the basis functions alive at u; the last share takes the remainder so every
    // photon's units land exactly.
    const SplineBasis& basis = storage_[info.curve].basis;
    std::array<double, SplineBasis::kMaxDegree + 1> phi{};
    const std::size_t first = basis.evaluate(u, phi.data());
    const auto degree = static_cast<std::size_t>(basis.degree());
    std::int64_t* target = acc.received.data() + acc.half_offset + offset * channels;
    for (std::size_t ch = 0; ch < channels; ++ch) {
      std::int64_t left = units[ch];
      for (std::size_t j = 0; j < degree; ++j) {
        // Round half up by truncation (the product is >= 0); std::llround is a library call.
        const auto share = static_cast<std::int64_t>(phi[j] * static_cast<double>(units[ch]) + 0.5);
        target[basis.index(first + j) * channels + ch] += share;
        left -= share;
      }
      target[basis.index(first + degree) * channels + ch] += left;
    }
  }
}

void Solver::end_round(std::span<const Accumulator> accumulators) {
  const auto channels = static_cast<std::size_t>(channels_);
  const double inverse_scale = 1.0 / round_.scale;
  std::array<std::int64_t, 3> escaped{};
  std::array<std::int64_t, 3> absorbed{};
  for (const Accumulator& acc : accumulators) {
    for (std::size_t ch = 0; ch < channels; ++ch) {
      escaped[ch] += acc.escaped[ch];
      absorbed[ch] += acc.absorbed[ch];
    }
    rays_traced_ += acc.rays;
  }
  const std::size_t half = coefficient_count_ * channels;
  if (walk_) {
    // Each round's tallies estimate the whole received power (its walks carry all the emitted
    // power between them): the running estimate is their average weighted by walks. Power is
    // absorbed or escapes only where a walk's units end, so the books stay exact per round.
    const double weight = static_cast<double>(round_.photons) / static_cast<double>(photons_shot_);
    for (std::size_t index = 0; index < half; ++index) {
      std::int64_t units = 0;
      std::int64_t odd = 0;
      for (const Accumulator& acc : accumulators) {
        units += acc.received[index];
        if (auto_storage_) odd += acc.received[half + index];
      }
      received_[index] += weight * (static_cast<double>(units + odd) * inverse_scale - received_[index]);
      if (auto_storage_)
        received_half_[index] += weight * (static_cast<double>(odd) * inverse_scale - received_half_[index]);
    }
    for (std::size_t ch = 0; ch < channels; ++ch) {
      walk_escaped_[ch] += weight * (static_cast<double>(escaped[ch]) * inverse_scale - walk_escaped_[ch]);
      walk_absorbed_[ch] += weight * (static_cast<double>(absorbed[ch]) * inverse_scale - walk_absorbed_[ch]);
    }
    update_reflected(received_, received_half_);
    ++rounds_;
    check_books();
    return;
  }
  // Power shot this round leaves the pool; what was received comes back as rho times itself. With
  // auto storage, odd-numbered photons deposited into the accumulators' second half.
  double previous_pool = 0.0;
  for (double value : unshot_) previous_pool += value;
  for (std::uint32_t c = 0; c < scene_->curves.size(); ++c) {
    for (Side side : {Side::Front, Side::Back}) {
      const std::uint32_t offset = block_offset(c, side);
      if (offset == kNoBlock) continue;
      const Spectrum& rho = block_reflectivity_[c * 2 + static_cast<std::uint32_t>(side)];
      const std::size_t count = storage_[c].basis.size();
      for (std::size_t k = 0; k < count; ++k) {
        for (std::size_t ch = 0; ch < channels; ++ch) {
          const std::size_t index = (offset + k) * channels + ch;
          std::int64_t units = 0;
          std::int64_t odd = 0;
          for (const Accumulator& acc : accumulators) {
            units += acc.received[index];
            if (auto_storage_) odd += acc.received[half + index];
          }
          units += odd;
          const double power = static_cast<double>(units) * inverse_scale;
          received_[index] += power;
          if (auto_storage_) received_half_[index] += static_cast<double>(odd) * inverse_scale;
          unshot_[index] = rho[ch] * power;
          absorbed_[ch].add(power - unshot_[index]);
        }
      }
    }
  }
  for (std::size_t ch = 0; ch < channels; ++ch) {
    escaped_[ch].add(static_cast<double>(escaped[ch]) * inverse_scale);
    absorbed_[ch].add(static_cast<double>(absorbed[ch]) * inverse_scale);
  }
  update_reflected(received_, received_half_);
  previous_unshot_ = previous_pool;
  ++rounds_;
  check_books();
}

void Solver::check_books() {
  // Always-on check of the books. Fixed-point quantisation moves at most half a unit per photon
  // and channel, 2^-61 of the round's power each (walks: 2^(H-61), H the headroom given up);
  // allow that plus double round-off.
  const EnergyBooks totals = books();
  const double allowed =
      emitted_total_ * (1e-12 + static_cast<double>(photons_shot_) * 3.0 * std::ldexp(1.0, walk_headroom_bits_ - 60));
  if (!(std::fabs(totals.imbalance()) <= allowed)) {
    char message[256];
    std::snprintf(message, sizeof message,
                  "energy books do not balance after round %u: emitted %.17g, absorbed %.17g, "
                  "escaped %.17g, unshot %.17g",
                  rounds_, totals.emitted, totals.absorbed, totals.escaped, totals.unshot);
    books_error_ = message;
    stop_reason_ = StopReason::BooksUnbalanced;
  }
}

void Solver::choose_final_levels() {
  if (auto_storage_ && (photons_at_choice_ != photons_shot_ || chosen_level_ != scheduled_level_))
    update_reflected(received_, received_half_, LevelChoice::Final);
}

void Solver::update_reflected(const std::vector<double>& received,
                              const std::vector<double>& received_half, LevelChoice choice) {
  if (auto_storage_) {
    const bool due = scheduled_level_.empty() ||
                     static_cast<double>(photons_shot_) >= kLevelChoiceGrowth * static_cast<double>(photons_at_choice_);
    if (choice == LevelChoice::View) {
      // A viewer asks after every piece (about 50 ms); choosing every level of every curve each
      // time cost a fifth of its solving thread's time.
      // Between choices the levels stay as the last choice left them (the solve's or the view's).
      const auto last = static_cast<double>(std::max(photons_at_view_choice_, photons_at_choice_));
      if (static_cast<double>(photons_shot_) >= kLevelChoiceGrowth * last) {
        choose_levels(received, received_half);
        photons_at_view_choice_ = photons_shot_;
      }
    } else if (choice == LevelChoice::Final || due) {
      choose_levels(received, received_half);
      scheduled_level_ = chosen_level_;
      photons_at_choice_ = photons_shot_;
    } else {
      chosen_level_ = scheduled_level_;
    }
  }
  // Reflected radiosity coefficients, kept current for readers between rounds; run() has no
  // readers between its rounds and refreshes them once, when it returns.
  if (defer_readers_) {
    readers_stale_ = true;
    return;
  }
  refresh_readers(received);
}

void Solver::refresh_readers(const std::vector<double>& received) {
  const auto channels = static_cast<std::size_t>(channels_);
  readers_stale_ = false;
  estimate(received, reflected_);
  for (std::uint32_t c = 0; c < scene_->curves.size(); ++c)
    for (Side side : {Side::Front, Side::Back}) {
      const std::uint32_t offset = block_offset(c, side);
      if (offset == kNoBlock) continue;
      const Spectrum& rho = block_reflectivity_[c * 2 + static_cast<std::uint32_t>(side)];
      for (std::size_t k = 0; k < storage_[c].basis.size(); ++k)
        for (std::size_t ch = 0; ch < channels; ++ch) reflected_[(offset + k) * channels + ch] *= rho[ch];
    }
  if (settings_.basis == BasisKind::Hermite) update_hermite(received, true);
}

void Solver::update_hermite(const std::vector<double>& power, bool reflected) {
  const auto channels = static_cast<std::size_t>(channels_);
  for (std::uint32_t c = 0; c < scene_->curves.size(); ++c)
    for (Side side : {Side::Front, Side::Back}) {
      const std::uint32_t offset = block_offset(c, side);
      if (offset == kNoBlock) continue;
      const std::uint32_t block = c * 2 + static_cast<std::uint32_t>(side);
      // Each channel's estimate at the chosen level, in that level's hats.
      std::vector<std::vector<double>> values;
      for (std::size_t ch = 0; ch < channels; ++ch)
        values.push_back(estimate_in_level(c, chosen_level_[c], &power[offset * channels + ch], channels));
      if (reflected) {
        const Spectrum& rho = block_reflectivity_[block];
        hermite_reflected_[block].clear();
        for (std::size_t ch = 0; ch < channels; ++ch) {
          for (double& v : values[ch]) v *= rho[ch];
          hermite_reflected_[block].push_back(hermite_of(c, chosen_level_[c], values[ch].data()));
        }
      } else {
        std::vector<double> summed(values[0].size(), 0.0);
        for (std::size_t k = 0; k < summed.size(); ++k)
          for (std::size_t ch = 0; ch < channels; ++ch) summed[k] += values[ch][k];
        hermite_unshot_[block] = hermite_of(c, chosen_level_[c], summed.data());
      }
    }
}

std::uint64_t Solver::step_photons(std::uint64_t max_photons, const std::atomic<bool>* cancel,
                                   std::vector<PhotonPath>* paths, std::size_t path_limit,
                                   const ProgressCallback& progress, double progress_interval) {
  if (stopped() || max_photons == 0) return 0;
  if (!round_open_) {
    if (!begin_round()) return 0;
    round_open_ = true;
    round_done_ = 0;
    round_deposits_.resize(threads_);
    for (Accumulator& acc : round_deposits_)
      acc.reset(coefficient_count_ * static_cast<std::size_t>(channels_) * (auto_storage_ ? 2 : 1));
  }
  const Clock::time_point start = Clock::now();
  const std::uint64_t first = round_done_;
  // Shared rounds are shot whole: every process must reach the round's sum.
  const std::uint64_t last =
      sharing_ != nullptr ? round_.photons : first + std::min(max_photons, round_.photons - first);
  const std::uint64_t share_rank = sharing_ != nullptr ? sharing_->rank() : 0;
  const std::uint64_t share_size = sharing_ != nullptr ? sharing_->size() : 1;
  const std::uint64_t photons_before = photons_shot_;
  auto room = [&]() -> std::size_t {
    return paths != nullptr && paths->size() < path_limit ? path_limit - paths->size() : 0;
  };
  auto shoot_here = [&](Rng& rng, std::uint64_t from, std::uint64_t count) {
    shoot_batch(rng, from, count, round_deposits_[0], room() > 0 ? paths : nullptr, path_limit);
  };
  std::uint64_t position = first;
  // The rest of a batch that an earlier step began, with the stream it left off.
  if (position % kBatchSize != 0) {
    const std::uint64_t end = std::min(last, (position / kBatchSize + 1) * kBatchSize);
    shoot_here(*partial_batch_rng_, position, end - position);
    position = end;
  }
  // Whole batches (the round's last, short one included), shared among the threads.
  const std::uint64_t whole_end = last == round_.photons ? last : last / kBatchSize * kBatchSize;
  if (whole_end > position || sharing_ != nullptr) {
    // Batch batch_begin + i * share_size + share_rank is this process's i-th.
    const std::uint64_t batch_begin = position / kBatchSize;
    const std::uint64_t all_batches = (whole_end - position + kBatchSize - 1) / kBatchSize;
    const std::uint64_t batches =
        all_batches > share_rank ? (all_batches - share_rank + share_size - 1) / share_size : 0;
    const unsigned workers = static_cast<unsigned>(std::min<std::uint64_t>(threads_, batches));
    const std::size_t path_room = room();
    const std::uint64_t path_batches =
        std::min<std::uint64_t>(batches, (path_room + kBatchSize - 1) / kBatchSize);
    std::vector<std::vector<PhotonPath>> batch_paths(path_batches);
    std::atomic<std::uint64_t> next_batch{0};
    std::atomic<std::uint64_t> photons_done{0};
    std::atomic<bool> aborted{false};
    auto work = [&](Accumulator& acc, bool reports) {
      Clock::time_point last_report = Clock::now();
      for (;;) {
        if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) {
          aborted.store(true);
          return;
        }
        const std::uint64_t i = next_batch.fetch_add(1);
        if (i >= batches) return;
        const std::uint64_t batch = batch_begin + i * share_size + share_rank;
        const std::uint64_t count = std::min(kBatchSize, round_.photons - batch * kBatchSize);
        std::vector<PhotonPath>* recorded = nullptr;
        std::size_t limit = 0;
        if (i < path_batches) {
          recorded = &batch_paths[i];
          limit = static_cast<std::size_t>(std::min<std::uint64_t>(count, path_room - i * kBatchSize));
          recorded->reserve(limit);
        }
        Rng rng(settings_.seed, rounds_, batch);
        shoot_batch(rng, batch * kBatchSize, count, acc, recorded, limit);
        photons_done.fetch_add(count, std::memory_order_relaxed);
        if (reports && progress && seconds_since(last_report) >= progress_interval) {
          last_report = Clock::now();
          SolverProgress p = this->progress();
          p.photons = photons_before + (position - first) + photons_done.load(std::memory_order_relaxed);
          p.seconds += seconds_since(start);
          progress(p);
        }
      }
    };
    worker_pool().run(workers, [&](unsigned w) { work(round_deposits_[w], w == 0); });
    if (sharing_ != nullptr) {
      const auto [all_done, any_aborted] = share_round(photons_done.load(), aborted.load());
      photons_done.store(all_done);
      aborted.store(any_aborted);
    }
    if (aborted.load()) {
      photons_cancelled_ = (position - first) + photons_done.load();
      seconds_ += seconds_since(start);
      stop_reason_ = StopReason::Cancelled;
      round_open_ = false;
      return 0;
    }
    if (paths != nullptr)
      for (std::vector<PhotonPath>& batch : batch_paths) paths->insert(paths->end(), batch.begin(), batch.end());
    position = whole_end;
  }
  // A batch begun here and finished by a later step keeps its stream.
  if (position < last) {
    partial_batch_rng_.emplace(settings_.seed, rounds_, position / kBatchSize);
    shoot_here(*partial_batch_rng_, position, last - position);
    position = last;
  }
  round_done_ = last;
  photons_shot_ += last - first;
  seconds_ += seconds_since(start);
  if (round_done_ == round_.photons) {
    round_open_ = false;
    partial_batch_rng_.reset();
    end_round(round_deposits_);
  }
  return last - first;
}

std::pair<std::uint64_t, bool> Solver::share_round(std::uint64_t photons_done, bool aborted) {
  Accumulator& total = round_deposits_[0];
  for (std::size_t w = 1; w < round_deposits_.size(); ++w) {
    Accumulator& acc = round_deposits_[w];
    for (std::size_t index = 0; index < total.received.size(); ++index) total.received[index] += acc.received[index];
    for (std::size_t ch = 0; ch < 3; ++ch) {
      total.escaped[ch] += acc.escaped[ch];
      total.absorbed[ch] += acc.absorbed[ch];
      total.shot[ch] += acc.shot[ch];
    }
    total.rays += acc.rays;
    acc.reset(total.received.size());
  }
  // One message per round: the deposits, then the books' counters, rays, photons and the cancel.
  std::vector<std::int64_t> values(total.received);
  for (const std::array<std::int64_t, 3>* counters : {&total.escaped, &total.absorbed, &total.shot})
    values.insert(values.end(), counters->begin(), counters->end());
  values.push_back(static_cast<std::int64_t>(total.rays));
  values.push_back(static_cast<std::int64_t>(photons_done));
  values.push_back(aborted ? 1 : 0);
  sharing_->sum(values);
  bytes_shared_ += values.size() * sizeof(std::int64_t);
  std::size_t at = total.received.size();
  std::copy(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(at), total.received.begin());
  for (std::array<std::int64_t, 3>* counters : {&total.escaped, &total.absorbed, &total.shot})
    for (std::int64_t& counter : *counters) counter = values[at++];
  total.rays = static_cast<std::uint64_t>(values[at++]);
  const auto all_done = static_cast<std::uint64_t>(values[at++]);
  return {all_done, values[at] != 0};
}

void Solver::include_open_round() {
  if (!round_open_) return;
  const double inverse_scale = 1.0 / round_.scale;
  std::vector<double> received = received_;
  std::vector<double> received_half = received_half_;
  const std::size_t half = received.size();
  // Walks: the round's walks so far, each carrying 1/n of the emitted power, estimate
  // round_done_ / n of the received power; averaged with the finished rounds by walks.
  const double before = static_cast<double>(photons_shot_ - round_done_);
  const double done = static_cast<double>(round_done_);
  const double walks = static_cast<double>(round_.photons);
  for (std::size_t index = 0; index < received.size(); ++index) {
    std::int64_t units = 0;
    std::int64_t odd = 0;
    for (const Accumulator& acc : round_deposits_) {
      units += acc.received[index];
      if (auto_storage_) odd += acc.received[half + index];
    }
    const double power = static_cast<double>(units + odd) * inverse_scale;
    const double power_odd = static_cast<double>(odd) * inverse_scale;
    if (walk_) {
      if (done > 0.0) {
        received[index] = (before * received[index] + walks * power) / (before + done);
        if (auto_storage_) received_half[index] = (before * received_half[index] + walks * power_odd) / (before + done);
      }
      continue;
    }
    received[index] += power;
    if (auto_storage_) received_half[index] += power_odd;
  }
  update_reflected(received, received_half, LevelChoice::View);
}

bool Solver::step_round(const std::atomic<bool>* cancel, const ProgressCallback& progress,
                        double progress_interval) {
  if (stopped()) return false;
  std::vector<PhotonPath> paths;
  const std::uint64_t shot = step_photons(std::numeric_limits<std::uint64_t>::max(), cancel, &paths,
                                          path_limit_, progress, progress_interval);
  if (shot == 0) return false;
  paths_ = std::move(paths);
  if (progress) progress(this->progress());
  return true;
}

void Solver::run(const std::atomic<bool>* cancel, const ProgressCallback& progress,
                 double progress_interval) {
  // Nobody reads the radiosity between run's rounds (its progress reports carry counts only), so
  // the reflected estimate, a solve per curve side and channel, is made once at the end instead
  // of after every round: from the same received power, so with the same result.
  defer_readers_ = true;
  while (step_round(cancel, progress, progress_interval)) {
  }
  defer_readers_ = false;
  if (readers_stale_) refresh_readers(received_);
}

EnergyBooks Solver::books() const {
  EnergyBooks books;
  for (int ch = 0; ch < channels_; ++ch) {
    books.emitted += emitted_[static_cast<std::size_t>(ch)];
    books.absorbed += walk_ ? walk_absorbed_[static_cast<std::size_t>(ch)] : absorbed_[static_cast<std::size_t>(ch)].value();
    books.escaped += walk_ ? walk_escaped_[static_cast<std::size_t>(ch)] : escaped_[static_cast<std::size_t>(ch)].value();
  }
  for (double value : unshot_) books.unshot += value;
  // Walks: until a round has finished nothing is accounted for; the emitted power is still to go.
  if (walk_ && rounds_ == 0) books.unshot = books.emitted;
  return books;
}

SolverProgress Solver::progress() const {
  SolverProgress p;
  p.photons = photons_shot_;
  p.budget = settings_.photons;
  p.rounds = rounds_;
  p.unshot_fraction = books().unshot / emitted_total_;
  p.seconds = seconds_;
  return p;
}

std::vector<double> Solver::radiosity_coefficients(std::uint32_t curve, Side side) const {
  const std::uint32_t offset = block_offset(curve, side);
  if (offset == kNoBlock) return {};
  const auto channels = static_cast<std::size_t>(channels_);
  const auto begin = reflected_.begin() + static_cast<std::ptrdiff_t>(offset * channels);
  return {begin, begin + static_cast<std::ptrdiff_t>(storage_[curve].basis.size() * channels)};
}

std::vector<double> Solver::unshot_coefficients(std::uint32_t curve, Side side) const {
  const std::uint32_t offset = block_offset(curve, side);
  if (offset == kNoBlock) return {};
  const auto channels = static_cast<std::size_t>(channels_);
  std::vector<double> all;
  estimate(unshot_, all);
  const auto begin = all.begin() + static_cast<std::ptrdiff_t>(offset * channels);
  return {begin, begin + static_cast<std::ptrdiff_t>(storage_[curve].basis.size() * channels)};
}

Spectrum Solver::radiosity(std::uint32_t curve, Side side, double u) const {
  Spectrum result{};
  const std::uint32_t offset = block_offset(curve, side);
  if (offset == kNoBlock) return result;
  const auto channels = static_cast<std::size_t>(channels_);
  const CurveStorage& storage = storage_[curve];
  std::array<double, SplineBasis::kMaxDegree + 1> phi{};
  const std::size_t first = storage.basis.evaluate(u, phi.data());
  if (settings_.basis == BasisKind::Hermite) {
    const auto& per_channel = hermite_reflected_[curve * 2 + static_cast<std::uint32_t>(side)];
    const double s = arc_length_at(curve, u);
    for (std::size_t ch = 0; ch < channels; ++ch)
      result[ch] = scene_->curves[curve].emittance[ch] * emittance_factor(scene_->curves[curve], u) +
                   (per_channel.empty() ? 0.0 : per_channel[ch].evaluate(s));
    return result;
  }
  for (std::size_t ch = 0; ch < channels; ++ch) {
    double reflected = 0.0;
    for (int j = 0; j <= storage.basis.degree(); ++j)
      reflected += phi[static_cast<std::size_t>(j)] *
                   reflected_[(offset + storage.basis.index(first + static_cast<std::size_t>(j))) * channels + ch];
    result[ch] =
        scene_->curves[curve].emittance[ch] * emittance_factor(scene_->curves[curve], u) + reflected;
  }
  return result;
}

}  // namespace flatland
