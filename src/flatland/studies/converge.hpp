// One run of a convergence study (flatland converge, flatland.converge in Python): a method named
// as on the command line, solved at a budget and seed, its error against a reference.
#pragma once

#include <atomic>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <variant>
#include <vector>

#include "flatland/base/status.hpp"
#include "flatland/results/metrics.hpp"
#include "flatland/results/sampled_result.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/transport/solver.hpp"

namespace flatland {

struct ConvergeMethod {
  std::string name;  // as written
  SolverSettings settings;
};

// "cubic", or settings joined by '+': "basis=cubic+sampling=uniform+ray-width=0.05+...", keys
// named as the solve command's options; the rest from `defaults`. Errors begin "methods: 'TEXT': ".
Result<ConvergeMethod> parse_converge_method(const std::string& text, const SolverSettings& defaults);

// Whether every method can shoot a budget of `budget` photons: at least its replicates, since every
// round shoots a multiple of them (a smaller budget would shoot nothing). Errors begin "budgets: ".
Status check_converge_budget(double budget, const std::vector<ConvergeMethod>& methods);

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
  bool gathered = false;   // the samples were a final gather (gather samples, or auto where it gathers)
  // The solver's estimated bound of the same error (error_estimate.hpp, under Measure::Reflected;
  // NaN where it has none: one replicate, Measure::Total, or unbounded).
  ErrorNorms estimated{std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::quiet_NaN(),
                       std::numeric_limits<double>::quiet_NaN()};
};

// One column of a row of a convergence study, named as in convergence.csv and in the dicts that
// flatland.converge returns: text, a whole number, or a real the CSV writes with `digits`
// significant digits.
struct ConvergeField {
  const char* name;
  std::variant<std::string, std::int64_t, double> value;
  int digits = 9;
};
// A row's columns, in the CSV's order: the method (its name and its settings, the estimator
// resolved), the run (seed, photons shot, rounds, unshot fraction, seconds), its errors, what they
// measure (`measure`, over the curve with id `curve` or, empty, the scene), the rays cast and the
// solver's estimated bound of the errors (est_l1, est_l2, est_linf). The
// command line and the Python module both write their rows from this, so the two cannot drift.
std::vector<ConvergeField> converge_fields(const std::string& method, const SolverSettings& settings,
                                           const ConvergeRow& row, Measure measure, const std::string& curve);

// `--control-variate auto` in a study: auto's choice grows with the photons (the storage does), so a
// study makes it once per method, at the method's largest budget `photons`, so that a method is the
// same method at every budget, in every front end and on every process. Returns ControlVariate::Coarse
// or None for a method asking for auto (`skipped`: auto's reason where it does without), and the
// method's own variate otherwise.
ControlVariate converge_variate(const Scene& scene, SolverSettings settings, std::uint64_t photons,
                                std::string& skipped);

// Solves `scene` with `settings` and compares the result, sampled `samples` times per curve, with
// `reference` by `measure`, over the scene or the curve with index `curve`.
// The error kConvergeCancelled when `cancel` stopped the solve; `progress` as Solver::run calls it.
inline constexpr const char* kConvergeCancelled = "the run was cancelled";
Result<ConvergeRow> converge_run(const Scene& scene, const SolverSettings& settings, const SampledResult& reference,
                                 Measure measure, std::optional<std::size_t> curve, int samples,
                                 const std::atomic<bool>* cancel = nullptr, const ProgressCallback& progress = {});

}  // namespace flatland
