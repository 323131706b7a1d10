#include "flatland/studies/converge.hpp"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <sstream>
#include <vector>

#include "flatland/base/text.hpp"
#include "flatland/reference/coarse_answer.hpp"
#include "flatland/reference/final_gather.hpp"
#include "flatland/transport/footprint.hpp"
#include "flatland/transport/options.hpp"

namespace flatland {

Result<ConvergeMethod> parse_converge_method(const std::string& text, const SolverSettings& defaults) {
  ConvergeMethod method{text, defaults};
  const std::string where = "methods: '" + text + "': ";
  // The keys a method may set: the solve's options but photons, seed and threads, which belong to
  // the study.
  std::vector<std::string> keys;
  for (const SolveOptionSpec& spec : solve_options())
    if (spec.per_method) keys.emplace_back(spec.flag);
  std::vector<std::string> given;  // a key given twice would silently take its last value
  std::stringstream parts(text);
  std::string part;
  while (std::getline(parts, part, '+')) {
    const auto equals = part.find('=');
    const std::string key = equals == std::string::npos ? "basis" : part.substr(0, equals);
    const std::string value = equals == std::string::npos ? part : part.substr(equals + 1);
    const std::optional<SolveOption> option = option_by_flag(key);
    if (!option || !spec_of(*option).per_method) {
      std::string message = where + "unknown key '" + key + "'";
      if (const auto hint = closest_match(key, keys)) message += "; did you mean '" + *hint + "'?";
      message += "; keys:";
      for (const std::string& name : keys) message += " " + name;
      return Error{message};
    }
    if (std::find(given.begin(), given.end(), key) != given.end())
      return Error{where + key + " is given twice; give each key once"};
    given.push_back(key);
    if (Status status = set_solve_option(method.settings, *option, value); !status)
      return Error{where + status.error().message};
  }
  if (Status status = validate(method.settings); !status) return Error{where + status.error().message};
  return method;
}

Status check_converge_budget(double budget, const std::vector<ConvergeMethod>& methods) {
  for (const ConvergeMethod& method : methods)
    if (budget < method.settings.replicates)
      return Error{"budgets: " + std::to_string(static_cast<long long>(budget)) + " photons is fewer than the " +
                   std::to_string(method.settings.replicates) + " replicates of method '" + method.name +
                   "', whose every round shoots a multiple of them; give at least that many"};
  return ok_status();
}

ControlVariate converge_variate(const Scene& scene, SolverSettings settings, std::uint64_t photons,
                                std::string& skipped) {
  skipped.clear();
  if (settings.control_variate != ControlVariate::Auto) return settings.control_variate;
  settings.photons = photons;
  skipped = control_variate_auto_skip(scene, settings);
  return skipped.empty() ? ControlVariate::Coarse : ControlVariate::None;
}

Result<ConvergeRow> converge_run(const Scene& scene, const SolverSettings& settings, const SampledResult& reference,
                                 Measure measure, std::optional<std::size_t> curve, int samples,
                                 const std::atomic<bool>* cancel, const ProgressCallback& progress) {
  // A method that gathers is timed with its gather (its elements, the sweeps, and the estimate
  // through them, also when a target error is checked).
  std::unique_ptr<FinalGather> gather;
  std::optional<SampledResult> gathered;
  double gather_seconds = 0.0;
  const auto seconds_since = [](std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  {
    const auto start = std::chrono::steady_clock::now();
    Result<GatherChoice> choice = choose_gather(scene, settings, samples, cancel);
    if (!choice) return choice.error();
    gather = std::move(choice->gather);
    gather_seconds += seconds_since(start);
  }
  Result<Solver> solver = create_solver(scene, settings, cancel);
  if (!solver) return solver.error();
  if (gather) solver->check_target_through(gather.get());
  solver->run(cancel, progress);
  if (solver->stop_reason() == StopReason::Cancelled) return Error{kConvergeCancelled};
  if (gather) {
    const auto start = std::chrono::steady_clock::now();
    gathered = gather->gather_result(*solver, samples);
    gather_seconds += seconds_since(start);
    if (gather->cancelled()) return Error{kConvergeCancelled};
  }
  Result<Comparison> comparison = compare_sampled(
      gathered ? *gathered
               : sample_radiosity(scene, samples,
                                  [&](std::uint32_t c, Side side, double u) { return solver->radiosity(c, side, u); }),
      reference, measure);
  if (!comparison) return Error{"reference: " + comparison.error().message};
  if (curve && *curve >= comparison->curves.size()) return Error{"curve: no such curve in the reference"};
  const EnergyBooks books = solver->books();
  ConvergeRow row;
  row.seed = settings.seed;
  row.photons = solver->photons_shot();
  row.rounds = solver->rounds();
  row.unshot = books.emitted > 0.0 ? books.unshot / books.emitted : 0.0;
  // (The control variate's coarse solve and projections are part of the method's time.)
  row.seconds = solver->seconds() + solver->control_variate_seconds() + gather_seconds;
  row.error = curve ? comparison->curves[*curve].norms : comparison->scene;
  row.rays = solver->rays_traced();
  row.gathered = gather != nullptr;
  if (measure == Measure::Reflected) {
    const ErrorEstimate estimate =
        gathered ? *gathered->stats->estimated_error : estimate_error(*solver, {settings.confidence, samples});
    if (estimate.available) {
      const RelativeErrors& bound = curve ? estimate.curves[*curve].bound : estimate.bound;
      row.estimated = {bound.l1, bound.l2, bound.linf};
    }
  }
  return row;
}

std::vector<ConvergeField> converge_fields(const std::string& method, const SolverSettings& settings,
                                           const ConvergeRow& row, Measure measure, const std::string& curve) {
  const SolverSettings& s = settings;
  auto whole = [](auto value) { return static_cast<std::int64_t>(value); };
  using Value = std::variant<std::string, std::int64_t, double>;
  return {
      {"method", method},
      {"basis", to_string(s.basis)},
      {"sampling", to_string(s.sampling)},
      {"discontinuities", to_string(s.discontinuities)},
      {"estimator", to_string(resolve_estimator(s.estimator, s.basis))},
      {"elements", s.elements == kAutoElements ? Value(std::string("auto")) : Value(whole(s.elements))},
      {"ray_width", s.ray_width, 17},
      {"ray_mode", to_string(s.ray_mode)},
      {"ray_profile", to_string(s.ray_profile)},
      {"band_rays", whole(s.band_rays)},
      {"tolerance", s.tolerance},
      {"seed", whole(row.seed)},
      {"photons", whole(row.photons)},
      {"rounds", whole(row.rounds)},
      {"unshot", row.unshot},
      {"seconds", row.seconds},
      {"rel_l1", row.error.l1},
      {"rel_l2", row.error.l2},
      {"rel_linf", row.error.linf},
      {"measure", to_string(measure)},
      {"curve", curve},
      {"sampler", to_string(s.sampler)},
      {"transport", to_string(s.transport)},
      {"rays", whole(row.rays)},
      {"est_l1", row.estimated.l1},
      {"est_l2", row.estimated.l2},
      {"est_linf", row.estimated.linf},
      {"gather", row.gathered ? "samples" : "none"},
  };
}

}  // namespace flatland
