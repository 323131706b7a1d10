#include "flatland/results/converge.hpp"

#include <algorithm>
#include <cstdlib>
#include <vector>
#include <sstream>

#include "flatland/transport/footprint.hpp"
#include "flatland/base/text.hpp"

namespace flatland {

Result<ConvergeMethod> parse_converge_method(const std::string& text, const SolverSettings& defaults) {
  ConvergeMethod method{text, defaults};
  std::stringstream parts(text);
  std::string part;
  std::vector<std::string> keys;  // given so far: a key given twice would silently take its last value
  while (std::getline(parts, part, '+')) {
    const auto equals = part.find('=');
    const std::string key = equals == std::string::npos ? "basis" : part.substr(0, equals);
    const std::string value = equals == std::string::npos ? part : part.substr(equals + 1);
    SolverSettings& s = method.settings;
    const std::string where = "--methods: '" + text + "': ";
    if (std::find(keys.begin(), keys.end(), key) != keys.end())
      return Error{where + key + " is given twice; give each key once"};
    keys.push_back(key);
    if (key == "basis") {
      const std::optional<BasisKind> basis = basis_from_string(value);
      if (!basis) return Error{where + "basis must be constant, linear, cubic or hermite"};
      s.basis = *basis;
    } else if (key == "sampling") {
      const std::optional<PositionSampling> sampling = sampling_from_string(value);
      if (!sampling) return Error{where + "sampling must be uniform or reconstructed"};
      s.sampling = *sampling;
    } else if (key == "discontinuities") {
      const std::optional<DiscontinuityMode> mode = discontinuity_mode_from_string(value);
      if (!mode) return Error{where + "discontinuities must be none, scene, auto or secondary"};
      s.discontinuities = *mode;
    } else if (key == "estimator") {
      const std::optional<Estimator> estimator = estimator_from_string(value);
      if (!estimator) return Error{where + "estimator must be lumped, galerkin, local or auto"};
      s.estimator = *estimator;
    } else if (key == "elements") {
      const std::optional<int> count = elements_from_string(value, kMaxElements);
      if (!count) return Error{where + "elements must be auto or a whole number from 1 to " + std::to_string(kMaxElements)};
      s.elements = *count;
    } else if (key == "ray-width") {
      char* end = nullptr;
      s.ray_width = std::strtod(value.c_str(), &end);
      if (end == value.c_str() || *end != '\0') return Error{where + "ray-width must be a number"};
    } else if (key == "ray-mode") {
      const std::optional<RayMode> mode = ray_mode_from_string(value);
      if (!mode) return Error{where + "ray-mode must be footprint or band"};
      s.ray_mode = *mode;
    } else if (key == "band-rays") {
      const std::optional<int> count = whole_number(value);
      if (!count) return Error{where + "band-rays must be a whole number"};
      s.band_rays = *count;
    } else if (key == "tolerance") {
      char* end = nullptr;
      s.tolerance = std::strtod(value.c_str(), &end);
      if (end == value.c_str() || *end != '\0') return Error{where + "tolerance must be a number"};
    } else if (key == "ray-profile") {
      Result<RayProfile> profile = parse_ray_profile(value);
      if (!profile) return Error{where + profile.error().message};
      s.ray_profile = *profile;
    } else if (key == "sampler") {
      const std::optional<SamplerKind> sampler = sampler_from_string(value);
      if (!sampler) return Error{where + "sampler must be random or sobol"};
      s.sampler = *sampler;
    } else if (key == "transport") {
      const std::optional<Transport> transport = transport_from_string(value);
      if (!transport) return Error{where + "transport must be shooting or walk"};
      s.transport = *transport;
    } else {
      return Error{where + "unknown key '" + key +
                   "'; keys: basis, sampling, discontinuities, estimator, elements, ray-width, "
                   "ray-mode, ray-profile, band-rays, tolerance, sampler, transport"};
    }
  }
  if (Status status = validate(method.settings); !status) return Error{"--methods: '" + text + "': " + status.error().message};
  return method;
}

Result<ConvergeRow> converge_run(const Scene& scene, const SolverSettings& settings, const SampledResult& reference,
                                 Measure measure, std::optional<std::size_t> curve, int samples,
                                 const std::atomic<bool>* cancel, const ProgressCallback& progress) {
  Result<Solver> solver = Solver::create(scene, settings, cancel);
  if (!solver) return solver.error();
  solver->run(cancel, progress);
  if (solver->stop_reason() == StopReason::Cancelled) return Error{kConvergeCancelled};
  Result<Comparison> comparison = compare_sampled(
      sample_radiosity(scene, samples, [&](std::uint32_t c, Side side, double u) { return solver->radiosity(c, side, u); }),
      reference, measure);
  if (!comparison) return Error{"--reference: " + comparison.error().message};
  if (curve && *curve >= comparison->curves.size()) return Error{"--curve: no such curve in the reference"};
  const EnergyBooks books = solver->books();
  ConvergeRow row;
  row.seed = settings.seed;
  row.photons = solver->photons_shot();
  row.rounds = solver->rounds();
  row.unshot = books.emitted > 0.0 ? books.unshot / books.emitted : 0.0;
  row.seconds = solver->seconds();
  row.error = curve ? comparison->curves[*curve].norms : comparison->scene;
  row.rays = solver->rays_traced();
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
  };
}

}  // namespace flatland
