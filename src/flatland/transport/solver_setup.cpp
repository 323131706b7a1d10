// Setting a solver up: the scene and settings checked, the storage planned (levels, budget shares,
// discontinuity events), its memory estimated before anything is allocated, and the transport
// started. Stepping, the books and the readers are in solver.cpp.
#include "flatland/transport/solver.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <numeric>
#include <thread>

#include "flatland/base/resources.hpp"
#include "flatland/scene/discontinuities.hpp"
#include "flatland/transport/control_variate.hpp"
#include "flatland/transport/error_estimate.hpp"
#include "flatland/transport/importance.hpp"

namespace flatland {

namespace {

// The storage's memory, estimated from above before anything is allocated. Per coefficient and
// channel: the received, unshot and reflected totals (doubles), each replicate's part of the
// received power, one fixed-point deposit per replicate and worker thread and the Galerkin scratch; per coefficient,
// its knots, basis integral, origin sampler and source weight (about 160 bytes). A curve's segments share its elements,
// at least one each (at most elements + segments); the regions between event nodes round their shares up, so that a
// curve has at most twice that many, plus per segment a joint of multiplicity up to the degree + 1.
// The coefficients' bound above (all sides, one channel), and the most elements any curve is given.
double coefficient_bound(const Scene& scene, const StoragePlan& plan, int* most_elements = nullptr) {
  double coefficients = 0.0;
  int most = 0;  // elements a curve, the most any curve is given
  for (std::size_t c = 0; c < scene.curves.size(); ++c) {
    const Curve& curve = scene.curves[c];
    // Curves that hold no light (mirrors, glass, detectors) get one element a segment and no
    // coefficients: the per-segment allowance below covers them.
    const double sides = scene.stores(curve, Side::Front) + scene.stores(curve, Side::Back);
    if (sides == 0.0) continue;
    // Automatic storage: the finest level the curve's room allows (as SceneStorage::build makes it).
    int level = plan.finest_level;
    const auto base = std::max<double>(kAutoBaseElements, curve.segment_count);
    while (plan.automatic && level > 0 && std::ldexp(base, level) > plan.room[c]) --level;
    const int elements = plan.elements << level;
    most = std::max(most, elements);
    coefficients +=
        sides * (2.0 * (static_cast<double>(elements) + curve.segment_count) + 4.0 * curve.segment_count + 4.0);
  }
  if (most_elements != nullptr) *most_elements = most;
  return coefficients;
}

Status check_memory(const Scene& scene, const SolverSettings& settings, const StoragePlan& plan, unsigned threads) {
  int most = 0;
  const double coefficients = coefficient_bound(scene, plan, &most);
  const double replicates = settings.replicates;
  const double per_coefficient = scene.channels * 8.0 * (4.0 + replicates * (1.0 + threads)) + 160.0;
  const double bytes = coefficients * per_coefficient + 2048.0 * static_cast<double>(scene.segments.size());
  const std::size_t limit = settings.memory_limit != 0 ? settings.memory_limit : default_memory_budget();
  if (bytes <= static_cast<double>(limit)) return ok_status();
  std::size_t holding = 0;
  for (const Curve& curve : scene.curves) holding += scene.holds_light(curve);
  char message[400];
  if (plan.automatic)
    std::snprintf(message, sizeof message,
                  "elements: automatic storage refines up to %d elements a curve for this photon budget, and on "
                  "%zu curves that hold light that would need about %.3g storage coefficients and %s of memory, "
                  "more than the limit of %s; give a fixed number of elements per curve, or fewer photons",
                  most, holding, coefficients, format_bytes(bytes).c_str(),
                  format_bytes(static_cast<double>(limit)).c_str());
  else
    std::snprintf(message, sizeof message,
                  "elements: %d a curve on %zu curves that hold light would need about %.3g storage coefficients "
                  "and %s of memory, more than the limit of %s; use fewer elements per curve",
                  settings.elements, holding, coefficients, format_bytes(bytes).c_str(),
                  format_bytes(static_cast<double>(limit)).c_str());
  return Error{message};
}

}  // namespace

Status Solver::check_scene(const Scene& scene, const SolverSettings& settings) {
  if (Status status = validate(settings); !status) return status;
  if (scene.curves.empty() || scene.segments.empty()) return Error{scene.source + ": the scene has no curves"};
  if (settings.control_variate == ControlVariate::Coarse)
    if (Status status = check_control_variate(scene); !status) return status;
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
  return ok_status();
}

StoragePlan Solver::plan_storage(const Scene& scene, const SolverSettings& settings) {
  StoragePlan plan;
  plan.automatic = settings.elements == kAutoElements;
  plan.elements = plan.automatic ? kAutoBaseElements : settings.elements;
  if (!plan.automatic) return plan;
  // Automatic storage: each curve's finest level is the finest that its share of the budget still
  // fills with kAutoPhotonsPerElement photons per element (the best element length shrinks with
  // the photon count, docs/storage-mesh.md, so a bigger budget reaches finer levels), or at small budgets
  // up to kAutoSmallBudgetElements as long as each still gets kAutoSmallBudgetPhotonsPerElement. A
  // reflecting curve's share is the budget times its share of the reflecting curves' length (light
  // lands on a curve about in proportion to its length: an equal share per curve let hundreds of
  // small reflecting boxes hold the walls of their room at 16 elements); a curve that reflects
  // nothing (only emits, or absorbs) gets an equal share of one reflecting curve.
  std::size_t reflecting = 0;
  double reflecting_length = 0.0;
  const auto reflects = [&](const Curve& curve) {
    const Spectrum& rho = scene.material_of(curve).reflectivity;
    return rho[0] + rho[1] + rho[2] > 0.0;
  };
  for (const Curve& curve : scene.curves)
    if (reflects(curve)) {
      ++reflecting;
      reflecting_length += curve.length;
    }
  const auto photons = static_cast<double>(settings.photons);
  const double equal_share = photons / static_cast<double>(std::max<std::size_t>(reflecting, 1));
  plan.room.resize(scene.curves.size());
  double most = 0.0;
  for (std::size_t c = 0; c < scene.curves.size(); ++c) {
    const Curve& curve = scene.curves[c];
    const double share = reflects(curve) ? photons * (curve.length / reflecting_length) : equal_share;
    plan.room[c] = std::max(share / kAutoPhotonsPerElement,
                            std::min(share / kAutoSmallBudgetPhotonsPerElement, kAutoSmallBudgetElements));
    most = std::max(most, plan.room[c]);
  }
  while (plan.finest_level + 1 < kAutoMaxLevels && (kAutoBaseElements << (plan.finest_level + 1)) <= most)
    ++plan.finest_level;
  return plan;
}

std::vector<std::vector<MeshNode>> Solver::find_events(const SegmentAccelerator& accelerator, const StoragePlan& plan,
                                                       std::vector<std::vector<double>>& walls,
                                                       const std::atomic<bool>* cancel) {
  const Scene& scene = *scene_;
  std::vector<std::vector<MeshNode>> events(scene.curves.size());
  walls.assign(scene.curves.size(), {});
  contacts_per_curve_.assign(scene.curves.size(), 0);
  // Only curves that hold light need nodes: a mirror's, a dielectric's or a detector's would
  // refine a storage nothing is deposited on.
  const auto holds_light = [&](std::uint32_t c) { return scene.holds_light(scene.curves[c]); };
  if (settings_.discontinuities != DiscontinuityMode::None) {
    // Contacts are part of the geometry (light on the two sides is unrelated): a value jump there
    // whenever the scene's joints are honoured.
    for (const DiscontinuityNode& node : find_contacts(scene, accelerator)) {
      if (!holds_light(node.curve)) continue;
      events[node.curve].push_back({node.u, node.continuity});
      walls[node.curve].push_back(arc_length_at(scene, scene.curves[node.curve], node.u));
      ++contact_nodes_;
      ++contacts_per_curve_[node.curve];
    }
    for (std::vector<double>& curve_walls : walls) std::sort(curve_walls.begin(), curve_walls.end());
  }
  if (settings_.discontinuities == DiscontinuityMode::Auto ||
      settings_.discontinuities == DiscontinuityMode::Secondary) {
    EventOptions options;
    options.elements = plan.elements << plan.finest_level;
    options.secondary = settings_.discontinuities == DiscontinuityMode::Secondary;
    options.cancel = cancel;
    for (const DiscontinuityNode& node : find_visibility_events(scene, accelerator, options)) {
      if (!holds_light(node.curve)) continue;
      events[node.curve].push_back({node.u, node.continuity});
      ++visibility_events_;
    }
  }
  return events;
}

void Solver::count_node_sources(const std::vector<std::vector<MeshNode>>& events) {
  // find_events lists a curve's contacts first (contacts_per_curve_), then its visibility events, and
  // add_coarse_nodes the coarse element ends after them (coarse_nodes_per_curve_); a storage node within
  // 1e-9 of one of them is that one's (the storage merges nodes that close, curve_storage.cpp).
  const Scene& scene = *scene_;
  const std::vector<std::size_t>& contacts = contacts_per_curve_;
  node_sources_ = {};
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    const auto near = [&](double u, std::size_t from, std::size_t to) {
      for (std::size_t k = from; k < to; ++k)
        if (std::fabs(events[c][k].u - u) <= 1e-9) return true;
      return false;
    };
    for (const MeshNode& node : storage_.finest(c).nodes) {
      if (node.continuity == Continuity::C1) continue;
      // Joint j (between segments j - 1 and j) is at u = j; a closed curve's closing joint (the last)
      // at u = 0 or u = segment count.
      const Curve& curve = scene.curves[c];
      const double joint = std::round(node.u);
      const auto count = static_cast<double>(curve.segment_count);
      bool at_joint = false;
      if (std::fabs(node.u - joint) <= 1e-9) {
        if (joint >= 1.0 && joint < count)
          at_joint = curve.joints[static_cast<std::size_t>(joint) - 1] != Continuity::C1;
        else if (curve.closed && (joint == 0.0 || joint == count))
          at_joint = curve.joints.back() != Continuity::C1;
      }
      const std::size_t coarse = coarse_nodes_per_curve_.empty() ? 0 : coarse_nodes_per_curve_[c];
      if (at_joint)
        ++node_sources_.scene;
      else if (near(node.u, 0, contacts[c]))
        ++node_sources_.contacts;
      else if (coarse > 0 && !near(node.u, contacts[c], events[c].size() - coarse) &&
               near(node.u, events[c].size() - coarse, events[c].size()))
        ++node_sources_.variate;
      else
        ++node_sources_.events;
    }
  }
}

Status Solver::start_transport(const std::atomic<bool>* cancel) {
  const Scene& scene = *scene_;
  const auto channels = static_cast<std::size_t>(channels_);
  const std::size_t size = storage_.coefficient_count() * channels;
  // The first round (or every walk) starts from the emitted power: on each emitting side E times
  // the basis integrals (with its profile).
  std::vector<double> emission(size, 0.0);
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    const Curve& curve = scene.curves[c];
    const CurveStorage& storage = storage_.finest(c);
    if (!scene.is_emitter(curve)) continue;
    const std::vector<double> emitted = project_emittance_profile(scene, curve, storage);
    for (Side side : {Side::Front, Side::Back}) {
      const std::uint32_t offset = storage_.block_offset(c, side);
      if (offset == SceneStorage::kNoBlock) continue;
      for (std::size_t k = 0; k < storage.basis.size(); ++k)
        for (std::size_t ch = 0; ch < channels; ++ch)
          emission[(offset + k) * channels + ch] = curve.emittance[ch] * emitted[k];
      for (std::size_t ch = 0; ch < channels; ++ch)
        emitted_[ch] += curve.emittance[ch] * curve.length * curve.profile_mean;
    }
  }
  for (std::size_t ch = 0; ch < channels; ++ch) emitted_total_ += emitted_[ch];
  // The first guess of the pool's decay per round: the reflecting sides' mean reflectivity.
  double reflecting_length = 0.0;
  double weighted_reflectivity = 0.0;
  for (std::uint32_t block = 0; block < storage_.block_count(); ++block) {
    if (storage_.block_offset(block) == SceneStorage::kNoBlock) continue;
    const Spectrum& rho = storage_.block_reflectivity(block);
    double mean = 0.0;
    for (std::size_t ch = 0; ch < channels; ++ch) mean += rho[ch];
    weighted_reflectivity += scene.curves[block / 2].length * mean / static_cast<double>(channels);
    reflecting_length += scene.curves[block / 2].length;
  }
  const double decay = reflecting_length > 0.0 ? weighted_reflectivity / reflecting_length : 0.5;
  // The target is a relative error of B - E; where no diffuse side reflects, B - E is exactly
  // zero and its relative error is not defined: no number of photons reaches a target.
  if (settings_.target_error > 0.0 && !(weighted_reflectivity > 0.0))
    return Error{scene.source +
                 ": target error: no diffuse side of the scene reflects light (every reflectivity is 0), so the "
                 "reflected light B - E is exactly zero and its relative error is not defined; solve without a "
                 "target error"};
  if (!(emitted_total_ > 0.0))
    return Error{scene.source + ": no curve emits light (give a material or curve an emittance > 0)"};
  if (settings_.control_variate == ControlVariate::Coarse)
    if (Status status = start_control_variate(emission, cancel); !status) return status;
  if (settings_.transport == Transport::Walk) {
    Result<RandomWalks> walks = RandomWalks::create(scene, std::move(emission), settings_.walk_score);
    if (!walks) return walks.error();
    transport_ = std::move(*walks);
  } else if (settings_.target_error > 0.0) {
    // Passes: each starts from the emitted power again.
    emission_ = emission;
    decay_ = decay;
    pass_budget_ = std::min(settings_.photons, kFirstPassPhotons);
    transport_ = ProgressiveShooting(std::move(emission), tolerance_power(), decay, pass_tolerance(),
                                     averaged_budget(pass_budget_), signed_pool_);
  } else {
    transport_ = ProgressiveShooting(std::move(emission), tolerance_power(), decay, settings_.tolerance,
                                     averaged_budget(settings_.photons), signed_pool_);
  }
  // Emittance (<= 1e100 with profile factors <= 1e100) times a length (<= 1e100 x segments) fits
  // a double, but the books and fixed-point units need headroom: refuse what comes near the edge.
  if (!(emitted_total_ < 1e290) || !(emitted_total_ > 1e-290)) {
    char message[256];
    std::snprintf(message, sizeof message,
                  "%s: the emitted power is %.3g, outside the supported 1e-290 .. 1e290; scale "
                  "the emittances (or the coordinates) so that it is",
                  scene.source.c_str(), emitted_total_);
    return Error{message};
  }
  detected_.assign(shooter_.detector_layout().size, 0.0);
  start_received();
  readers_.coefficients.assign(size, 0.0);
  if (settings_.basis == BasisKind::Hermite) {
    readers_.hermite.resize(storage_.block_count());
    hermite_unshot_.resize(storage_.block_count());
  }
  // With the control variate the answer holds g before any photon.
  if (signed_pool_) update_reflected(received_, received_half_, half_variance_factor_);
  return ok_status();
}

void Solver::start_received() {
  const std::size_t size = storage_.coefficient_count() * static_cast<std::size_t>(channels_);
  const auto replicates = static_cast<std::size_t>(settings_.replicates);
  received_.assign(size, 0.0);
  if (replicates > 1) received_parts_.assign(size * replicates, 0.0);
  if (auto_storage_) received_half_.assign(size, 0.0);
  if (variate_received_.empty()) return;
  // Each replicate estimates the whole as R times its part: its part of g is g / R, and the odd
  // replicates' half is g / 2.
  received_ = variate_received_;
  const double share = 1.0 / static_cast<double>(replicates);
  if (replicates > 1)
    for (std::size_t r = 0; r < replicates; ++r)
      for (std::size_t index = 0; index < size; ++index) received_parts_[r * size + index] = share * received_[index];
  if (auto_storage_)
    for (std::size_t index = 0; index < size; ++index) received_half_[index] = 0.5 * received_[index];
}

void Solver::add_coarse_nodes(std::vector<std::vector<MeshNode>>& events) {
  // D = E + rho G - b_c jumps wherever b_c does, at every coarse element's ends: value jumps there
  // let the storage hold D as it is (photons leave from its coefficients), not smoothed across.
  const Scene& scene = *scene_;
  coarse_nodes_per_curve_.assign(scene.curves.size(), 0);
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    const Curve& curve = scene.curves[c];
    if (!scene.holds_light(curve)) continue;
    const std::size_t before = events[c].size();
    for (std::uint32_t local = 0; local < curve.segment_count; ++local) {
      const std::vector<double> ends = coarse_->element_parameters(curve.first_segment + local);
      for (std::size_t i = local == 0 ? 0 : 1; i < ends.size(); ++i) {
        const double u = local + ends[i];
        if (curve.closed || (u > 0.0 && u < curve.segment_count)) events[c].push_back({u, Continuity::Jump});
      }
    }
    coarse_nodes_per_curve_[c] = events[c].size() - before;
  }
}

Status Solver::start_control_variate(std::vector<double>& emission, const std::atomic<bool>* cancel) {
  const auto start = std::chrono::steady_clock::now();
  const std::shared_ptr<const CoarseAnswer> coarse = std::move(coarse_);
  const std::size_t size = emission.size();
  variate_received_.assign(size, 0.0);
  std::vector<double> source(size, 0.0);
  // On a scene of lines the coarse chords are the curves: no model error to estimate.
  const bool modelled = scene_->has_cubics();
  std::vector<double> coarse_received(modelled ? size : 0, 0.0);
  // Curve by curve on the workers (each writes only its own coefficients, so the bits do not depend
  // on the split): a sweep at every quadrature point is most of the variate's set-up.
  const auto project = [&](std::size_t c) {
    project_control_variate(*coarse, *scene_, storage_, static_cast<std::uint32_t>(c), emission, variate_received_,
                            source, modelled ? &coarse_received : nullptr, cancel);
  };
  if (threads_ > 1)
    worker_pool().for_each(scene_->curves.size(), project);
  else
    for (std::size_t c = 0; c < scene_->curves.size(); ++c) project(c);
  if (cancel != nullptr && cancel->load()) return Error{kSolverCancelled};
  // The finer chords' error is the coarse ones' over the model ratio r: g_coarse - g is (r - 1) times
  // it, where both errors scale alike. D carries rho times it too, and the photons pass it on: its
  // later bounces multiply it about as the scene multiplies light (the coarse answer's power over
  // the emitted power).
  if (modelled) {
    variate_bias_.resize(size);
    const double scale = coarse->amplification() / (coarse->model_ratio() - 1.0);
    for (std::size_t i = 0; i < size; ++i) variate_bias_[i] = scale * (coarse_received[i] - variate_received_[i]);
  }
  const auto channels = static_cast<std::size_t>(channels_);
  // The books: the photons carry D (its sum, signed), the coarse light leaves the scene by
  // `escaped`, and the rest of the emitted power is absorbed, exactly (the coarse light that lands
  // on a side less what the side reflects of it, up to the quadrature).
  std::array<double, 3> shot{};
  double magnitude = 0.0;
  for (std::size_t index = 0; index < size; ++index) {
    shot[index % channels] += source[index];
    magnitude += std::fabs(source[index]);
  }
  variate_source_fraction_ = magnitude / emitted_total_;
  const std::array<double, 3> escaped = coarse->escaped();
  for (std::size_t ch = 0; ch < channels; ++ch) {
    variate_escaped_[ch] = escaped[ch];
    variate_absorbed_[ch] = emitted_[ch] - shot[ch] - escaped[ch];
  }
  variate_elements_ = coarse->elements();
  variate_seconds_ =
      coarse->seconds() + std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  emission = std::move(source);
  signed_pool_ = true;
  return ok_status();
}

double Solver::coefficient_bound(const Scene& scene, const SolverSettings& settings) {
  return flatland::coefficient_bound(scene, plan_storage(scene, settings));
}

Status Solver::check_settings_on(const Scene& scene, const SolverSettings& settings) {
  if (Status status = check_scene(scene, settings); !status) return status;
  if (Result<std::vector<std::uint32_t>> region = importance_curves(scene, settings); !region) return region.error();
  return ok_status();
}

Result<Solver> Solver::create(const Scene& scene, const SolverSettings& settings, const std::atomic<bool>* cancel,
                              std::shared_ptr<const CoarseAnswer> coarse) {
  const auto cancelled = [cancel] { return cancel != nullptr && cancel->load(std::memory_order_relaxed); };
  if (Status status = check_scene(scene, settings); !status) return status.error();
  // The curves importance favours, refused before any work when the scene lacks them.
  Result<std::vector<std::uint32_t>> region = importance_curves(scene, settings);
  if (!region) return region.error();
  Solver solver;
  solver.scene_ = &scene;
  solver.settings_ = settings;
  solver.settings_.estimator = resolve_estimator(settings.estimator, settings.basis);
  // Auto is create_solver's choice, made before this call: given a coarse answer it chose Coarse.
  if (settings.control_variate == ControlVariate::Auto)
    solver.settings_.control_variate = coarse != nullptr ? ControlVariate::Coarse : ControlVariate::None;
  // The replicates' layout follows the variate (settings.hpp, ReplicateLayout::Auto).
  if (settings.replicate_layout == ReplicateLayout::Auto)
    solver.settings_.replicate_layout = solver.settings_.control_variate == ControlVariate::Coarse
                                            ? ReplicateLayout::Blocks
                                            : ReplicateLayout::Independent;
  solver.channels_ = scene.channels;
  solver.threads_ = settings.threads != 0 ? settings.threads : std::max(1u, std::thread::hardware_concurrency());
  solver.auto_storage_ = settings.elements == kAutoElements;
  // 1. How fine the storage may go, and whether it fits the memory.
  const StoragePlan plan = plan_storage(scene, settings);
  if (Status status = check_memory(scene, settings, plan, solver.threads_); !status) return status.error();
  // 2. The ray caster's tree, and the storage mesh's extra nodes from the geometry.
  std::vector<SegmentGeometry> geometry;
  geometry.reserve(scene.segments.size());
  for (const SceneSegment& segment : scene.segments) geometry.push_back(segment.geometry);
  SegmentAccelerator accelerator(std::move(geometry));
  std::vector<std::vector<double>> walls;
  std::vector<std::vector<MeshNode>> events = solver.find_events(accelerator, plan, walls, cancel);
  if (cancelled()) return Error{kSolverCancelled};
  // The coarse control variate's elements' ends as storage nodes.
  if (solver.settings_.control_variate == ControlVariate::Coarse) {
    if (coarse == nullptr)
      return Error{
          "control variate: coarse needs the coarse reference's answer; create the solver with "
          "create_solver (reference/coarse_answer.hpp)"};
    solver.coarse_ = std::move(coarse);
    solver.add_coarse_nodes(events);
  }
  solver.shooter_ = PhotonShooter(scene, solver.settings_, std::move(accelerator), std::move(walls));
  // 3. Every curve's storage, its levels and the coefficients' layout.
  Result<SceneStorage> storage =
      SceneStorage::build(scene, solver.settings_, plan, events, solver.worker_pool(), cancel);
  if (!storage || cancelled()) return Error{kSolverCancelled};
  solver.storage_ = std::move(*storage);
  solver.count_node_sources(events);
  // 4. Importance: each curve side's weight from the adjoint solve.
  if (!region->empty()) {
    Result<ImportanceSolve> importance =
        solve_importance(scene, *region, settings, flatland::importance_photons(settings), cancel);
    if (!importance) return importance.error();
    solver.importance_ = std::move(importance->side_weight);
    solver.importance_photons_ = importance->photons;
    solver.importance_seconds_ = importance->seconds;
  }
  // 5. The transport, starting from the emitted power, and the footprints' tables.
  if (Status status = solver.start_transport(cancel); !status) return status.error();
  if (!solver.shooter_.prepare_footprints(solver.storage_, cancel) || cancelled()) return Error{kSolverCancelled};
  return solver;
}

}  // namespace flatland
