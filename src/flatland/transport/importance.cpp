#include "flatland/transport/importance.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "flatland/base/text.hpp"
#include "flatland/transport/solver.hpp"

namespace flatland {

namespace {
constexpr double kTallyReflectivity = 1e-9;
}  // namespace

Result<std::vector<std::uint32_t>> importance_curves(const Scene& scene, const SolverSettings& settings) {
  std::vector<std::uint32_t> region;
  std::vector<std::string> ids;
  ids.reserve(scene.curves.size());
  for (const Curve& curve : scene.curves) ids.push_back(curve.id);
  for (const std::string& id : settings.importance) {
    const auto found = std::find(ids.begin(), ids.end(), id);
    if (found == ids.end()) {
      std::string message = "importance: " + scene.source + " has no curve '" + id + "'";
      if (const auto hint = closest_match(id, ids))
        message += "; did you mean '" + *hint + "'?";
      else
        message += "; name curves by their \"id\"";
      return Error{message};
    }
    const auto c = static_cast<std::uint32_t>(found - ids.begin());
    const Curve& curve = scene.curves[c];
    if (!scene.holds_light(curve))
      return Error{"importance: curve '" + id +
                   "' keeps no diffuse light (a mirror, glass or detector has no radiosity to make accurate); "
                   "name the diffuse curves that its light reaches"};
    if (!scene.reflects_light(curve))
      return Error{"importance: curve '" + id +
                   "' reflects no light (its B is its emittance, exact whatever the photons do); name the "
                   "curves that reflect the light you want accurate"};
    region.push_back(c);
  }
  return region;
}

Scene adjoint_scene(const Scene& scene, const std::vector<std::uint32_t>& region) {
  Scene adjoint = scene;
  for (Material& material : adjoint.materials) {
    material.spectrum.reset();
    // A side that reflects nothing books what it receives as absorbed, not received; the
    // emitters are such sides, and their importance is what they receive here. A reflectivity of
    // kTallyReflectivity has them tally it, and changes the adjoint's answer by as little.
    if (material.optics == Optics::Diffuse)
      for (double& rho : material.reflectivity) rho = std::max(rho, kTallyReflectivity);
  }
  for (Curve& curve : adjoint.curves) {
    curve.emittance = Spectrum{};
    curve.emittance_profile.clear();
    curve.profile_mean = 1.0;
  }
  for (const std::uint32_t c : region) {
    Curve& curve = adjoint.curves[c];
    // A material of its own: the region's light leaves diffusely, whatever its material's
    // emitters do.
    Material material = adjoint.materials[curve.material];
    material.emission = Emission{};
    material.emittance = Spectrum{};
    for (int ch = 0; ch < adjoint.channels; ++ch) material.emittance[static_cast<std::size_t>(ch)] = 1.0;
    adjoint.materials.push_back(material);
    curve.material = static_cast<std::uint32_t>(adjoint.materials.size() - 1);
    curve.emittance = material.emittance;
  }
  return adjoint;
}

std::uint64_t importance_photons(const SolverSettings& settings) {
  constexpr std::uint64_t kFewest = std::uint64_t{1} << 14;
  if (settings.target_error > 0.0) return kFewest;
  return std::clamp<std::uint64_t>(settings.photons / 16, kFewest, std::uint64_t{1} << 20);
}

Result<ImportanceSolve> solve_importance(const Scene& scene, const std::vector<std::uint32_t>& region,
                                         const SolverSettings& settings, std::uint64_t photons,
                                         const std::atomic<bool>* cancel) {
  const auto start = std::chrono::steady_clock::now();
  const Scene adjoint = adjoint_scene(scene, region);
  SolverSettings pilot;
  pilot.photons = photons;
  // A stream of its own: the main solve's photons are not correlated with the weights.
  pilot.seed = settings.seed ^ 0x9e3779b97f4a7c15ull;
  pilot.threads = settings.threads;
  pilot.memory_limit = settings.memory_limit;
  pilot.basis = BasisKind::Constant;
  pilot.elements = 1;
  pilot.replicates = 1;
  pilot.sampling = PositionSampling::Uniform;
  pilot.discontinuities = DiscontinuityMode::None;
  pilot.estimator = Estimator::Lumped;
  pilot.gather = GatherMode::None;
  pilot.tolerance = 1e-2;
  Result<Solver> solver = Solver::create(adjoint, pilot, cancel);
  if (!solver) return solver.error();
  while (solver->step_round(cancel)) {
  }
  if (solver->stop_reason() == StopReason::Cancelled) return Error{kSolverCancelled};
  if (solver->stop_reason() == StopReason::BooksUnbalanced) return Error{"importance: " + solver->books_error()};
  const SceneStorage& storage = solver->scene_storage();
  const std::vector<double>& received = solver->received();
  const auto channels = static_cast<std::size_t>(adjoint.channels);
  ImportanceSolve result;
  result.side_importance.assign(storage.block_count(), 0.0);
  double largest = 0.0;
  for (std::uint32_t block = 0; block < storage.block_count(); ++block) {
    const std::uint32_t offset = storage.block_offset(block);
    if (offset == SceneStorage::kNoBlock) continue;
    const std::size_t count = storage.finest(block / 2).basis.size();
    double power = 0.0;
    for (std::size_t i = offset * channels; i < (offset + count) * channels; ++i) power += received[i];
    result.side_importance[block] = power / (static_cast<double>(channels) * adjoint.curves[block / 2].length);
    largest = std::max(largest, result.side_importance[block]);
  }
  // Relative to the largest, and the weights held to the floor (all 1 when the region's light
  // reaches nothing: no importance at all).
  result.side_weight.assign(storage.block_count(), 0.0);
  for (std::uint32_t block = 0; block < storage.block_count(); ++block) {
    if (storage.block_offset(block) == SceneStorage::kNoBlock) continue;
    double& w = result.side_importance[block];
    w = largest > 0.0 ? w / largest : 1.0;
    result.side_weight[block] = std::max(std::sqrt(w), kImportanceFloor);
  }
  result.photons = solver->photons_shot();
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return result;
}

}  // namespace flatland
