#include "flatland/transport/options.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>

#include "flatland/base/text.hpp"

namespace flatland {

namespace {

const std::vector<SolveOptionSpec>& table() {
  static const std::string elements_value = "auto|1.." + std::to_string(kMaxElements);
  // One option a row: option, name, flag, keyword, choices, value, help, per_method.
  // clang-format off
  static const std::vector<SolveOptionSpec> options = {
      {SolveOption::Photons, "photons", "photons", "photons", {}, "N",
       "Total photon budget over all rounds, e.g. 250000 or 1e6 (every round shoots a multiple of the "
       "replicates: at least that many)", false},
      {SolveOption::Seed, "seed", "seed", "seed", {}, "S",
       "Random seed; the same seed gives bit-identical results on any thread count", false},
      {SolveOption::Threads, "threads", "threads", "threads", {}, "T", "Worker threads (0: every core)", false},
      {SolveOption::Basis, "basis", "basis", "basis", {"constant", "linear", "cubic", "hermite"}, "",
       "Illumination along each curve: constant, linear or cubic B-splines, or hermite (cubic Hermite "
       "interpolation of nodal values)"},
      {SolveOption::Elements, "elements", "elements", "elements", {}, elements_value,
       "Storage elements per curve (shared among its segments by arc length, at least one each), or "
       "auto: each curve's mesh follows the photons that land on it, chosen after every round among "
       "nested halvings by least estimated error"},
      {SolveOption::Sampling, "sampling", "sampling", "sampling", {"uniform", "reconstructed"}, "",
       "Where photons leave a source: uniform in arc length (constant radiosity assumption) or "
       "reconstructed (density proportional to the reconstructed unshot radiosity, the paper's method)"},
      {SolveOption::Discontinuities, "discontinuities", "discontinuities", "discontinuities",
       {"none", "scene", "auto", "secondary"}, "",
       "Nodes where illumination may jump or kink: none (smooth everywhere), scene (the scene's joints, "
       "C-1 at corners by default, and C-1 at contacts, where a curve ends on or crosses another) or auto "
       "(those plus C0 nodes at direct-light events: penumbra boundaries from emitters' end points, "
       "corners and silhouettes) or secondary (auto plus the same events of every reflecting curve, as a "
       "source of the light it reflects)"},
      {SolveOption::Estimator, "estimator", "estimator", "estimator", {"lumped", "galerkin", "local", "auto"}, "",
       "Coefficients from deposits: lumped (power over the basis function's length, the paper's; "
       "positive, bias O(h^2) inside and O(h) at ends and nodes), galerkin (L2 projection) or local "
       "(least-variance local quasi-interpolant; Hermite: nodal values); galerkin and local have bias "
       "O(h^(p+1)) everywhere and may dip below zero; auto: local for hermite storage, galerkin for the "
       "others (docs/method.md)"},
      {SolveOption::Sampler, "sampler", "sampler", "sampler", {"random", "sobol"}, "",
       "Where each photon's uniforms come from: random (independent pseudo-random numbers) or sobol "
       "(randomised quasi-Monte Carlo: an Owen-scrambled Sobol' point per photon; same seed, same bits "
       "on any thread count)"},
      {SolveOption::Transport, "transport", "transport", "transport", {"shooting", "walk", "jacobi"}, "",
       "How light travels: shooting (progressive rounds, each shooting the light the last one "
       "reflected: the paper's method), walk (each photon a random walk from an emitter, tallied at "
       "every hit and ended by Russian roulette; photons counts walks, tolerance is not used) or jacobi "
       "(shooting until the pool is below the tolerance, then regular iterations that each shoot all the "
       "reflected light again from the first round's direct light, averaged with it; docs/method.md, Averaged "
       "Jacobi iterations)"},
      {SolveOption::WalkScore, "walk score", "walk-score", "walk_score", {"collision", "absorption", "survival"}, "",
       "What a random walk tallies where it lands (transport walk only): collision (the power that arrived, "
       "at every landing), absorption (that power / (1 - q) where the walk ends, q its chance of going on "
       "there) or survival (power / q where it goes on); the same expected answer, different noise "
       "(docs/method.md, Random walks)"},
      {SolveOption::Gather, "gather", "gather", "gather", {"none", "samples", "auto"}, "",
       "The result's B: none (the storage's own), samples (a final gather: at every sample, one "
       "deterministic bounce of the solution over exactly what the sample sees, with the reference's "
       "elements; direct light then carries no noise; refused where the reference is: glass, curved "
       "mirrors, detectors, emitters that are not diffuse) or auto (samples where the scene allows it and it costs at most about two "
       "seconds on two cores, none elsewhere, saying why)"},
      {SolveOption::Importance, "importance", "importance", "importance", {}, "IDS",
       "Curves whose light matters most, as ids separated by commas (e.g. desk,floor; empty: none; transport "
       "shooting only): each round's photons go to the sources by their unshot power times the square root "
       "of their importance for those curves, from a short solve of the adjoint scene; the same expected answer everywhere, less "
       "noise on those curves and more elsewhere (docs/method.md, Importance)"},
      {SolveOption::ControlVariate, "control variate", "control-variate", "control_variate", {"none", "coarse", "auto"},
       "",
       "none, coarse or auto. coarse: a deterministic reference solve on coarse elements (a 50th of the scene's size) "
       "gives an answer whose transport is added exactly, and the photons shoot only the signed difference it "
       "leaves, a few per cent of the light (transport shooting with reconstructed origins on constant, linear or "
       "cubic storage; diffuse scenes: no mirrors, glass, detectors or spectra; docs/method.md, A coarse answer as "
       "control variate). auto: coarse where the scene and the other settings allow it and its set-up costs at "
       "most about two seconds on two cores, none elsewhere, saying why"},
      {SolveOption::RayWidth, "ray width", "ray-width", "ray_width", {}, "W",
       "Width of extended rays in scene units (0: point rays, no extended-ray code runs)"},
      {SolveOption::RayProfile, "ray profile", "ray-profile", "ray_profile",
       {"box", "tent", "epanechnikov", "cosine", "gauss"}, "",
       "Energy profile across an extended ray: box, tent, epanechnikov, cosine or gauss (truncated at "
       "3 sigma)"},
      {SolveOption::RayMode, "ray mode", "ray-mode", "ray_mode", {"footprint", "band"}, "",
       "footprint: spread the centre ray's power along the receiver over the projected width; band: "
       "trace band-rays parallel sub-rays across the width"},
      {SolveOption::BandRays, "band rays", "band-rays", "band_rays", {}, "K", "Sub-rays per photon in band mode"},
      {SolveOption::Tolerance, "tolerance", "tolerance", "tolerance", {}, "X",
       "Stop when the unshot power falls below this fraction of the emitted power (transport jacobi: begin the "
       "iterations then; control variate coarse: of the power its difference carries, in magnitude)"},
      {SolveOption::Replicates, "replicates", "replicates", "replicates", {}, "R",
       "Independent randomisations every round's photons are split into (1, or an even number up to 64): "
       "their spread gives the result's estimated error; 1 gives none (and is refused with --elements auto and "
       "with --target-error)"},
      {SolveOption::ReplicateLayout, "replicate layout", "replicate-layout", "replicate_layout",
       {"independent", "blocks", "auto"}, "",
       "How a round's photons form the replicates: independent (photon i in replicate i mod R, each its own "
       "scrambled net: the estimated error is sharpest, but R nets of N / R points stratify less than one net), "
       "blocks (the round is one net and the replicates are its blocks of consecutive photons: the answer "
       "keeps the whole net's accuracy, and the estimated error is more conservative) or auto (blocks where the "
       "coarse control variate runs, independent elsewhere; docs/estimated-error.md)"},
      {SolveOption::TargetError, "target error", "target-error", "target_error", {}, "X",
       "Keep shooting until the estimated relative L1 error of B - E is at most X (e.g. 1e-3), with photons "
       "as the cap; 0: no target, the photon budget and tolerance decide"},
      {SolveOption::Confidence, "confidence", "confidence", "confidence", {}, "C",
       "Confidence of the estimated error's bound, from 0.5 to 0.999 (the probability that the true error is "
       "below it)"},
  };
  // clang-format on
  return options;
}

// "a, b, c or d".
std::string listed(const std::vector<std::string_view>& names) {
  std::string text;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i > 0) text += i + 1 == names.size() ? " or " : ", ";
    text += names[i];
  }
  return text;
}

Error option_error(const SolveOptionSpec& spec, const std::string& what) {
  return Error{std::string(spec.name) + ": " + what};
}

// The index of `text` among the option's choices, or an error naming them (with a likely one).
Result<std::size_t> choice_of(const SolveOptionSpec& spec, std::string_view text) {
  for (std::size_t i = 0; i < spec.choices.size(); ++i)
    if (spec.choices[i] == text) return i;
  std::string message = "expected " + listed(spec.choices) + ", got '" + std::string(text) + "'";
  const std::vector<std::string> names(spec.choices.begin(), spec.choices.end());
  if (const auto hint = closest_match(text, names)) message += "; did you mean '" + *hint + "'?";
  return option_error(spec, message);
}

// A finite number written in full (strtod's grammar, nothing after it).
std::optional<double> real_number(std::string_view text) {
  const std::string copy(text);
  char* end = nullptr;
  const double value = std::strtod(copy.c_str(), &end);
  if (copy.empty() || end != copy.c_str() + copy.size() || !std::isfinite(value)) return std::nullopt;
  return value;
}

}  // namespace

std::span<const SolveOptionSpec> solve_options() { return table(); }

const SolveOptionSpec& spec_of(SolveOption option) {
  for (const SolveOptionSpec& spec : table())
    if (spec.option == option) return spec;
  return table().front();
}

std::optional<SolveOption> option_by_flag(std::string_view flag) {
  for (const SolveOptionSpec& spec : table())
    if (spec.flag == flag) return spec.option;
  return std::nullopt;
}

std::optional<SolveOption> option_by_keyword(std::string_view keyword) {
  for (const SolveOptionSpec& spec : table())
    if (spec.keyword == keyword) return spec.option;
  return std::nullopt;
}

Result<std::uint64_t> parse_photon_count(std::string_view text, std::string_view name) {
  const std::string prefix = std::string(name) + ": ";
  const std::optional<double> value = real_number(text);
  if (!value || *value != std::floor(*value))
    return Error{prefix + "expected a whole number such as 250000 or 1e6, got '" + std::string(text) + "'"};
  if (*value < 1.0) return Error{prefix + "must be at least 1, got '" + std::string(text) + "'"};
  if (*value > static_cast<double>(kMaxPhotons))
    return Error{prefix + "at most 2^50 (about 1.1e15), got '" + std::string(text) + "'"};
  return static_cast<std::uint64_t>(*value);
}

Result<std::uint64_t> parse_seed(std::string_view text, std::string_view name) {
  const Error error{std::string(name) + ": expected a whole number from 0 to 18446744073709551615, got '" +
                    std::string(text) + "'"};
  if (text.empty() || text.size() > 20 || text.find_first_not_of("0123456789") != std::string_view::npos) return error;
  std::uint64_t value = 0;
  for (const char digit : text) {
    const auto d = static_cast<std::uint64_t>(digit - '0');
    if (value > (UINT64_MAX - d) / 10) return error;  // value * 10 + d would pass 2^64 - 1
    value = value * 10 + d;
  }
  return value;
}

Status set_solve_option(SolverSettings& s, SolveOption option, std::string_view text) {
  const SolveOptionSpec& spec = spec_of(option);
  // An option that takes one of a list: its index among the names, in the enum's order.
  Result<std::size_t> index = spec.choices.empty() ? Result<std::size_t>(0) : choice_of(spec, text);
  if (!index) return index.error();
  const auto whole = [&](long low, long high, const char* what) -> Result<int> {
    const std::optional<int> value = whole_number(std::string(text));
    if (!value || *value < low || *value > high)
      return option_error(spec, std::string("expected ") + what + ", got '" + std::string(text) + "'");
    return *value;
  };
  switch (option) {
    case SolveOption::Photons: {
      Result<std::uint64_t> count = parse_photon_count(text, spec.name);
      if (!count) return count.error();
      s.photons = *count;
      return ok_status();
    }
    case SolveOption::Seed: {
      Result<std::uint64_t> seed = parse_seed(text, spec.name);
      if (!seed) return seed.error();
      s.seed = *seed;
      return ok_status();
    }
    case SolveOption::Threads: {
      Result<int> threads = whole(0, 1024, "a whole number from 0 (every core) to 1024");
      if (!threads) return threads.error();
      s.threads = static_cast<unsigned>(*threads);
      return ok_status();
    }
    case SolveOption::Elements: {
      if (text == "auto") {
        s.elements = kAutoElements;
        return ok_status();
      }
      Result<int> elements =
          whole(1, kMaxElements, ("auto or a whole number from 1 to " + std::to_string(kMaxElements)).c_str());
      if (!elements) return elements.error();
      s.elements = *elements;
      return ok_status();
    }
    case SolveOption::Replicates: {
      const std::string accepted = "1 or an even number up to " + std::to_string(kMaxReplicates);
      Result<int> replicates = whole(1, kMaxReplicates, accepted.c_str());
      if (!replicates) return replicates.error();
      if (*replicates > 1 && *replicates % 2 != 0)
        return option_error(spec, "expected " + accepted + ", got '" + std::string(text) + "'");
      s.replicates = *replicates;
      return ok_status();
    }
    case SolveOption::BandRays: {
      Result<int> rays = whole(1, 256, "a whole number from 1 to 256");
      if (!rays) return rays.error();
      s.band_rays = *rays;
      return ok_status();
    }
    case SolveOption::RayWidth: {
      const std::optional<double> width = real_number(text);
      if (!width || *width < 0.0)
        return option_error(spec,
                            "expected a width >= 0 in scene units (0: point rays), got '" + std::string(text) + "'");
      s.ray_width = *width;
      return ok_status();
    }
    case SolveOption::TargetError: {
      const std::optional<double> target = real_number(text);
      if (!target || !(*target >= 0.0 && *target < 1.0))
        return option_error(
            spec, "expected a relative error in (0, 1) such as 1e-3 (0: no target), got '" + std::string(text) + "'");
      s.target_error = *target;
      return ok_status();
    }
    case SolveOption::Confidence: {
      const std::optional<double> confidence = real_number(text);
      if (!confidence || !(*confidence >= 0.5 && *confidence <= 0.999))
        return option_error(spec,
                            "expected a probability from 0.5 to 0.999 such as 0.95, got '" + std::string(text) + "'");
      s.confidence = *confidence;
      return ok_status();
    }
    case SolveOption::Tolerance: {
      const std::optional<double> tolerance = real_number(text);
      if (!tolerance || !(*tolerance > 0.0 && *tolerance < 1.0))
        return option_error(spec, "expected a number in (0, 1) such as 1e-3, got '" + std::string(text) + "'");
      s.tolerance = *tolerance;
      return ok_status();
    }
    case SolveOption::Importance: {
      std::vector<std::string> ids;
      std::size_t start = 0;
      while (!text.empty() && start <= text.size()) {
        const std::size_t comma = std::min(text.find(',', start), text.size());
        const std::string id(text.substr(start, comma - start));
        if (id.empty())
          return option_error(spec, "expected curve ids separated by commas such as desk,floor, got '" +
                                        std::string(text) + "' (an empty id)");
        if (std::find(ids.begin(), ids.end(), id) != ids.end())
          return option_error(spec, "'" + id + "' is named twice in '" + std::string(text) + "'; name each curve once");
        ids.push_back(id);
        start = comma + 1;
      }
      s.importance = std::move(ids);
      return ok_status();
    }
    case SolveOption::Basis: s.basis = static_cast<BasisKind>(*index); return ok_status();
    case SolveOption::Sampling: s.sampling = static_cast<PositionSampling>(*index); return ok_status();
    case SolveOption::Discontinuities: s.discontinuities = static_cast<DiscontinuityMode>(*index); return ok_status();
    case SolveOption::Estimator: s.estimator = static_cast<Estimator>(*index); return ok_status();
    case SolveOption::Sampler: s.sampler = static_cast<SamplerKind>(*index); return ok_status();
    case SolveOption::Transport: s.transport = static_cast<Transport>(*index); return ok_status();
    case SolveOption::WalkScore: s.walk_score = static_cast<WalkScore>(*index); return ok_status();
    case SolveOption::Gather: s.gather = static_cast<GatherMode>(*index); return ok_status();
    case SolveOption::ControlVariate: s.control_variate = static_cast<ControlVariate>(*index); return ok_status();
    case SolveOption::RayProfile: s.ray_profile = static_cast<RayProfile>(*index); return ok_status();
    case SolveOption::RayMode: s.ray_mode = static_cast<RayMode>(*index); return ok_status();
    case SolveOption::ReplicateLayout: s.replicate_layout = static_cast<ReplicateLayout>(*index); return ok_status();
  }
  return ok_status();
}

std::string solve_option_text(const SolverSettings& s, SolveOption option) {
  const SolveOptionSpec& spec = spec_of(option);
  const auto name = [&](auto value) { return std::string(spec.choices[static_cast<std::size_t>(value)]); };
  switch (option) {
    case SolveOption::Photons: {
      // A power of ten times a digit as "1e6", as people write budgets; anything else in digits.
      std::uint64_t mantissa = s.photons;
      int exponent = 0;
      while (mantissa % 10 == 0 && mantissa > 0) {
        mantissa /= 10;
        ++exponent;
      }
      if (exponent >= 3 && mantissa < 10) return std::to_string(mantissa) + "e" + std::to_string(exponent);
      return std::to_string(s.photons);
    }
    case SolveOption::Seed: return std::to_string(s.seed);
    case SolveOption::Threads: return std::to_string(s.threads);
    case SolveOption::Elements: return s.elements == kAutoElements ? "auto" : std::to_string(s.elements);
    case SolveOption::BandRays: return std::to_string(s.band_rays);
    case SolveOption::Replicates: return std::to_string(s.replicates);
    case SolveOption::RayWidth: return format_number(s.ray_width);
    case SolveOption::Tolerance: return format_number(s.tolerance);
    case SolveOption::Confidence: return format_number(s.confidence);
    case SolveOption::TargetError: return format_number(s.target_error);
    case SolveOption::Importance: {
      std::string ids;
      for (const std::string& id : s.importance) ids += (ids.empty() ? "" : ",") + id;
      return ids;
    }
    case SolveOption::Basis: return name(s.basis);
    case SolveOption::Sampling: return name(s.sampling);
    case SolveOption::Discontinuities: return name(s.discontinuities);
    case SolveOption::Estimator: return name(s.estimator);
    case SolveOption::Sampler: return name(s.sampler);
    case SolveOption::Transport: return name(s.transport);
    case SolveOption::WalkScore: return name(s.walk_score);
    case SolveOption::Gather: return name(s.gather);
    case SolveOption::ControlVariate: return name(s.control_variate);
    case SolveOption::RayProfile: return name(s.ray_profile);
    case SolveOption::RayMode: return name(s.ray_mode);
    case SolveOption::ReplicateLayout: return name(s.replicate_layout);
  }
  return {};
}

std::string spelled(std::string_view message, Spelling spelling) {
  // The solve's options, and those of the reference, the result and a convergence study that the
  // core's messages also begin with.
  struct Names {
    std::string_view name, flag, keyword;
  };
  static const Names kOthers[] = {
      {"samples", "samples", "samples"},
      {"methods", "methods", "methods"},
      {"budgets", "budgets", "budgets"},
      {"seeds", "seeds", "seeds"},
      {"reference", "reference", "reference"},
      {"curve", "curve", "curve"},
      {"measure", "measure", "measure"},
      {"quadrature", "quadrature", "quadrature"},
      {"max element length", "max-element-length", "max_element_length"},
      {"max iterations", "max-iterations", "max_iterations"},
  };
  std::vector<Names> names;
  for (const SolveOptionSpec& spec : table()) names.push_back({spec.name, spec.flag, spec.keyword});
  names.insert(names.end(), std::begin(kOthers), std::end(kOthers));
  for (const Names& option : names) {
    if (message.size() <= option.name.size() || message.substr(0, option.name.size()) != option.name ||
        message[option.name.size()] != ':')
      continue;
    const std::string spelling_of =
        spelling == Spelling::CommandLine ? "--" + std::string(option.flag) : std::string(option.keyword);
    return spelling_of + std::string(message.substr(option.name.size()));
  }
  return std::string(message);
}

}  // namespace flatland
