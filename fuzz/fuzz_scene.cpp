// libFuzzer target: the scene reader and the set-up a solve does before its first photon.
//
// The bytes are a scene file. When parse_scene accepts them, Solver::create builds what a solve
// needs first (the ray-casting accelerator, visibility events, storage bases and meshes, the
// emittance projected onto them) and the result document that `solve --out` would write is formed
// and serialised (every curve sampled, the scene's strings echoed). No photon is shot: that cost
// depends on the budget, not on the input, and would only slow the fuzzer down.
//
// Rejected input is fine (both functions return errors); a crash, a sanitizer report, an
// exception escaping, an assertion or a hang is a bug. docs/fuzzing.md says how to run it.
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "flatland/results/result_io.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/transport/solver.hpp"

namespace {

// The solver settings that change what create() builds, chosen by a hash of the input so that a
// run covers every basis, discontinuity mode and ray kind while any input reproduces exactly.
flatland::SolverSettings settings_for(std::string_view text) {
  std::uint64_t hash = 1469598103934665603ull;  // FNV-1a
  for (const char byte : text) hash = (hash ^ static_cast<unsigned char>(byte)) * 1099511628211ull;
  flatland::SolverSettings settings;
  settings.threads = 1;  // no worker threads: create() starts none, and the fuzzer stays single-threaded
  settings.photons = 1000;
  settings.elements = 4;  // small: the storage set-up is linear in it and the input decides the rest
  constexpr flatland::BasisKind kBases[] = {flatland::BasisKind::Constant, flatland::BasisKind::Linear,
                                            flatland::BasisKind::Cubic, flatland::BasisKind::Hermite};
  settings.basis = kBases[hash % 4];
  hash /= 4;
  // Visibility events (Auto) are the costliest and most intricate part of the set-up: half the runs.
  constexpr flatland::DiscontinuityMode kModes[] = {
      flatland::DiscontinuityMode::Auto, flatland::DiscontinuityMode::Auto, flatland::DiscontinuityMode::Scene,
      flatland::DiscontinuityMode::None};
  settings.discontinuities = kModes[hash % 4];
  hash /= 4;
  settings.sampling = hash % 2 == 0 ? flatland::PositionSampling::Reconstructed : flatland::PositionSampling::Uniform;
  hash /= 2;
  switch (hash % 3) {
    case 0: break;  // point rays
    case 1:
      settings.ray_width = 0.05;
      settings.ray_mode = flatland::RayMode::Footprint;
      break;
    default:
      settings.ray_width = 0.05;
      settings.ray_mode = flatland::RayMode::Band;
      settings.band_rays = 5;
      settings.ray_profile = flatland::RayProfile::Gauss;
      break;
  }
  return settings;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  flatland::Result<flatland::Scene> scene = flatland::parse_scene(text, "fuzz.json");
  if (!scene) return 0;
  flatland::Result<flatland::Solver> solver = flatland::Solver::create(*scene, settings_for(text));
  if (!solver) return 0;
  const std::string written = flatland::json_text(flatland::result_to_json(*solver, 4));
  return 0;
}
