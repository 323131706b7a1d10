#include "flatland/transport/settings.hpp"

#include <algorithm>
#include <cmath>

#include "flatland/base/text.hpp"

namespace flatland {

const char* to_string(RayMode mode) { return mode == RayMode::Footprint ? "footprint" : "band"; }

const char* to_string(SamplerKind sampler) { return sampler == SamplerKind::Random ? "random" : "sobol"; }

const char* to_string(ReplicateLayout layout) {
  switch (layout) {
    case ReplicateLayout::Independent: return "independent";
    case ReplicateLayout::Blocks: return "blocks";
    case ReplicateLayout::Auto: return "auto";
  }
  return "auto";
}

bool replicates_stratified(const SolverSettings& settings) {
  return settings.replicate_layout == ReplicateLayout::Blocks && settings.sampler == SamplerKind::Sobol;
}

double stratification_factor(double blocks, double pairs, int replicates) {
  if (replicates < 4) return 1.0;
  const double n = replicates;
  const double m = n / 2.0;
  const double v1 = blocks / (n * (n - 1.0));
  const double v2 = pairs / (m * (m - 1.0));
  if (!(v1 > 0.0) || !(v2 >= 0.0)) return 1.0;
  return std::pow(std::clamp(v2 / v1, kFewestPairRatio, 1.0), std::log2(n));
}

const char* to_string(Estimator estimator) {
  switch (estimator) {
    case Estimator::Lumped: return "lumped";
    case Estimator::Galerkin: return "galerkin";
    case Estimator::Local: return "local";
    case Estimator::Auto: return "auto";
  }
  return "?";
}

Estimator resolve_estimator(Estimator estimator, BasisKind basis) {
  if (estimator != Estimator::Auto) return estimator;
  return basis == BasisKind::Hermite ? Estimator::Local : Estimator::Galerkin;
}

const char* to_string(Transport transport) {
  return transport == Transport::Shooting ? "shooting" : transport == Transport::Walk ? "walk" : "jacobi";
}

const char* to_string(WalkScore score) {
  return score == WalkScore::Collision ? "collision" : score == WalkScore::Absorption ? "absorption" : "survival";
}

const char* to_string(GatherMode gather) {
  return gather == GatherMode::None ? "none" : gather == GatherMode::Samples ? "samples" : "auto";
}

const char* to_string(ControlVariate variate) {
  return variate == ControlVariate::None ? "none" : variate == ControlVariate::Coarse ? "coarse" : "auto";
}

const char* to_string(PositionSampling sampling) {
  return sampling == PositionSampling::Uniform ? "uniform" : "reconstructed";
}

Status validate(const SolverSettings& settings) {
  // The options' names as options.hpp gives them; each front end spells them its own way.
  if (settings.photons < 1) return Error{"photons: must be at least 1"};
  if (settings.photons > kMaxPhotons) return Error{"photons: at most 2^50 (about 1.1e15) photons per solve"};
  if (settings.elements != kAutoElements && (settings.elements < 1 || settings.elements > kMaxElements))
    return Error{"elements: must be auto or between 1 and " + std::to_string(kMaxElements)};
  if (!std::isfinite(settings.tolerance) || settings.tolerance <= 0.0 || settings.tolerance >= 1.0)
    return Error{"tolerance: must be a number in (0, 1), e.g. 1e-3"};
  if (settings.threads > 1024) return Error{"threads: at most 1024 (0 uses every core)"};
  if (!std::isfinite(settings.ray_width) || settings.ray_width < 0.0)
    return Error{"ray width: must be a finite width >= 0 in scene units (0: point rays)"};
  if (settings.band_rays < 1 || settings.band_rays > 256) return Error{"band rays: must be between 1 and 256"};
  if (settings.replicates < 1 || settings.replicates > kMaxReplicates ||
      (settings.replicates > 1 && settings.replicates % 2 != 0))
    return Error{"replicates: must be 1 or an even number up to " + std::to_string(kMaxReplicates)};
  // Every round shoots a multiple of the replicates (each an equal share of it), so a smaller
  // budget would shoot nothing and report all the light unshot.
  if (settings.photons < static_cast<std::uint64_t>(settings.replicates))
    return Error{"photons: every round shoots a multiple of the " + std::to_string(settings.replicates) +
                 " replicates, so " + std::to_string(settings.photons) + " photons would shoot none; give at least " +
                 std::to_string(settings.replicates) + " (or fewer replicates)"};
  if (!(settings.confidence >= 0.5 && settings.confidence <= 0.999))
    return Error{"confidence: must be a probability from 0.5 to 0.999, e.g. 0.95"};
  if (!(settings.target_error >= 0.0 && settings.target_error < 1.0))
    return Error{"target error: must be a relative error in (0, 1), e.g. 1e-3 (0: no target)"};
  if (settings.target_error > 0.0 && settings.replicates < 2)
    return Error{
        "target error: the error is estimated from the replicates' spread, so it needs at least 2 "
        "replicates (8 is the default)"};
  if (settings.replicates == 1 && settings.elements == kAutoElements)
    return Error{
        "replicates: automatic storage chooses its levels by comparing halves of the photons, so it needs at "
        "least 2 replicates (or give a fixed number of elements)"};
  if (settings.transport == Transport::Walk && settings.ray_width > 0.0 && settings.ray_mode == RayMode::Band)
    return Error{
        "transport: a walk goes on from where its photon lands, and a band's sub-rays land in many "
        "places; use ray mode footprint with walks (or transport shooting with bands)"};
  if (settings.transport != Transport::Walk && settings.walk_score != WalkScore::Collision)
    return Error{std::string("walk score: ") + to_string(settings.walk_score) +
                 " scores random walks, and the photons of shooting and of Jacobi iterations make one hop each; use "
                 "transport walk with it "
                 "(or leave the walk score at collision)"};
  if (settings.transport == Transport::Walk && !settings.importance.empty())
    return Error{
        "importance: it shares shooting's rounds among the sources, and every walk starts afresh from an "
        "emitter; use transport shooting with it (or no importance)"};
  if (settings.transport == Transport::Jacobi && !settings.importance.empty())
    return Error{
        "importance: it keeps unshot power in shooting's pool, and Jacobi iterations shoot all the reflected "
        "light every iteration; use transport shooting with it (or no importance)"};
  if (settings.control_variate == ControlVariate::Coarse) {
    // The difference D is signed light leaving diffusely from the storage's coefficients: it needs
    // rounds that shoot a pool (not walks from the emitters, nor iterations of all the reflected
    // light), reconstructed origins on B-spline storage (a coefficient's sign is its photons'), and
    // every side's share of the round by its power alone.
    if (settings.transport != Transport::Shooting)
      return Error{std::string("control variate: coarse shoots what a coarse answer leaves in progressive "
                               "shooting's rounds, and transport ") +
                   to_string(settings.transport) + " does not shoot rounds of a pool; use transport shooting with it"};
    if (settings.sampling != PositionSampling::Reconstructed)
      return Error{
          "control variate: coarse shoots signed light whose sign changes along a curve, so photons must leave "
          "from the storage's coefficients; use sampling reconstructed with it"};
    if (settings.basis == BasisKind::Hermite)
      return Error{
          "control variate: coarse needs a B-spline basis (constant, linear or cubic), whose coefficients carry "
          "the signed light; Hermite storage's origins follow a positive density"};
    if (!settings.importance.empty())
      return Error{"control variate: coarse is not combined with importance yet; use one or the other"};
    if (settings.estimator == Estimator::Local)
      return Error{
          "control variate: coarse shoots its difference from the storage's estimate of it, and the local "
          "estimator does not keep a signed side's power; use estimator galerkin, lumped or auto with it"};
  }
  return ok_status();
}

}  // namespace flatland
