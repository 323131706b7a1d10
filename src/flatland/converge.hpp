// One run of a convergence study (flatland converge, flatland.converge in Python): a method named
// as on the command line, solved at a budget and seed, its error against a reference.
#pragma once

#include <atomic>
#include <cstdint>
#include <optional>
#include <string>

#include "flatland/metrics.hpp"
#include "flatland/result.hpp"
#include "flatland/sampled_result.hpp"
#include "flatland/scene.hpp"
#include "flatland/solver.hpp"

namespace flatland {

struct ConvergeMethod {
  std::string name;  // as written
  SolverSettings settings;
};

// "cubic", or settings joined by '+': "basis=cubic+sampling=uniform+ray-width=0.05+...", keys
// named as the solve command's options; the rest from `defaults`. Errors begin "--methods: 'TEXT': ".
Result<ConvergeMethod> parse_converge_method(const std::string& text, const SolverSettings& defaults);

struct ConvergeRow {
  std::size_t method = 0;  // index into the study's methods
  std::size_t budget = 0;  // index into its budgets
  std::uint64_t seed = 0;
  std::uint64_t photons = 0;  // shot
  std::uint32_t rounds = 0;
  double unshot = 0.0;  // unshot / emitted power when the solve stopped
  double seconds = 0.0;
  ErrorNorms error;
  std::uint64_t rays = 0;  // rays cast (a walk casts several)
};

// Solves `scene` with `settings` and compares the result, sampled `samples` times per curve, with
// `reference` by `measure`, over the scene or the curve with index `curve`.
// The error kConvergeCancelled when `cancel` stopped the solve; `progress` as Solver::run calls it.
inline constexpr const char* kConvergeCancelled = "the run was cancelled";
Result<ConvergeRow> converge_run(const Scene& scene, const SolverSettings& settings, const SampledResult& reference,
                                 Measure measure, std::optional<std::size_t> curve, int samples,
                                 const std::atomic<bool>* cancel = nullptr, const ProgressCallback& progress = {});

}  // namespace flatland
