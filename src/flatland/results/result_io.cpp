#include "flatland/results/result_io.hpp"

#include "flatland/base/version.hpp"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <random>
#include <tuple>

#include <signal.h>
#include <unistd.h>

#include "flatland/base/resources.hpp"
#include "flatland/base/text.hpp"

namespace flatland {

nlohmann::json scene_to_json(const Scene& scene) {
  return {{"name", scene.name},
          {"file", scene.source},
          {"sha256", scene.source_sha256},
          {"content_sha256", scene.content_sha256},
          {"channels", scene.channels}};
}

nlohmann::json program_to_json() {
  return {{"name", "flatland"}, {"version", program_version()}, {"commit", program_commit()}};
}

namespace {

// The result document of `solver` with its sampled result, but for "curves" (an empty array).
nlohmann::json result_without_curves(const Solver& solver, int samples_per_curve, const SampledResult& sampled) {
  const Scene& scene = solver.scene();
  const SolverSettings& settings = solver.settings();
  nlohmann::json result;
  result["flatland_result"] = 1;
  result["program"] = program_to_json();
  result["scene"] = scene_to_json(scene);
  result["settings"] = {
      {"method", to_string(settings.transport)},
      {"transport", to_string(settings.transport)},
      {"photons", settings.photons},
      {"seed", settings.seed},
      {"threads", solver.thread_count()},
      {"processes", solver.round_sharing() != nullptr ? solver.round_sharing()->size() : 1u},
      {"basis", to_string(settings.basis)},
      {"elements", settings.elements == kAutoElements ? nlohmann::json("auto") : nlohmann::json(settings.elements)},
      {"tolerance", settings.tolerance},
      {"sampling", to_string(settings.sampling)},
      {"discontinuities", to_string(settings.discontinuities)},
      {"estimator", to_string(settings.estimator)},
      {"sampler", to_string(settings.sampler)},
      {"ray_width", settings.ray_width},
      {"ray_profile", to_string(settings.ray_profile)},
      {"ray_mode", to_string(settings.ray_mode)},
      {"band_rays", settings.band_rays},
      {"replicates", settings.replicates},
      {"replicate_layout", to_string(settings.replicate_layout)},
      {"confidence", settings.confidence},
      {"target_error", settings.target_error},
      {"samples", samples_per_curve},
      {"final_gather",
       sampled.final_gather ? nlohmann::json{{"element_length", *sampled.final_gather}} : nlohmann::json(false)},
  };
  // What a walk tallied; shooting has no such choice.
  if (settings.transport == Transport::Walk) result["settings"]["walk_score"] = to_string(settings.walk_score);
  // The control variate, where one was used: its coarse reference's elements and the power its
  // photons started from (the magnitude of D) over the emitted power; where auto chose none, why;
  // absent where none was asked for.
  if (settings.control_variate != ControlVariate::None)
    result["settings"]["control_variate"] = {{"kind", to_string(settings.control_variate)},
                                             {"coarse_elements", solver.control_variate_elements()},
                                             {"source_fraction", solver.control_variate_source_fraction()}};
  else if (!solver.control_variate_skipped().empty())
    result["settings"]["control_variate"] = {{"kind", "none"}, {"skipped", solver.control_variate_skipped()}};
  // The region that importance favoured, and the adjoint solve's photons; absent without one.
  if (!settings.importance.empty())
    result["settings"]["importance"] = {{"curves", settings.importance},
                                        {"adjoint_photons", solver.importance_photons()}};
  result["stats"] = stats_to_json(*sampled.stats);
  if (solver.detector_layout().size > 0) result["detectors"] = detectors_to_json(solver);
  result["curves"] = nlohmann::json::array();
  return result;
}

}  // namespace

nlohmann::json detectors_to_json(const Solver& solver) {
  const Scene& scene = solver.scene();
  nlohmann::json list = nlohmann::json::array();
  for (const DetectorReading& reading : solver.detector_readings()) {
    const Curve& curve = scene.curves[reading.curve];
    nlohmann::json entry = {{"id", curve.id}, {"length", curve.length}, {"bins", reading.front.size()}};
    for (const auto& [name, bins, total] : {std::tuple{"front", &reading.front, &reading.front_total},
                                            std::tuple{"back", &reading.back, &reading.back_total}}) {
      nlohmann::json tallies = nlohmann::json::array();
      for (const Spectrum& value : *bins) tallies.push_back(spectrum_to_json(value, scene.channels));
      entry[name] = std::move(tallies);
      entry[std::string(name) + "_total"] = spectrum_to_json(*total, scene.channels);
    }
    list.push_back(std::move(entry));
  }
  return list;
}

std::string detectors_csv(const Solver& solver) {
  const Scene& scene = solver.scene();
  const auto channels = static_cast<std::size_t>(scene.channels);
  std::string text = channels == 1 ? "detector,bin,s_from,s_to,x,y,front,back\n"
                                   : "detector,bin,s_from,s_to,x,y,front_r,front_g,front_b,back_r,back_g,back_b\n";
  char number[40];
  auto add = [&](double value) {
    std::snprintf(number, sizeof number, ",%.17g", value);
    text += number;
  };
  for (const DetectorReading& reading : solver.detector_readings()) {
    const Curve& curve = scene.curves[reading.curve];
    const std::size_t bins = reading.front.size();
    for (std::size_t b = 0; b < bins; ++b) {
      text += csv_field(curve.id) + "," + std::to_string(b);
      const double from = curve.length * static_cast<double>(b) / static_cast<double>(bins);
      const double to = curve.length * static_cast<double>(b + 1) / static_cast<double>(bins);
      const Vec2 middle = point_at_arc_length(scene, curve, 0.5 * (from + to)).position;
      for (double value : {from, to, middle.x, middle.y}) add(value);
      for (std::size_t ch = 0; ch < channels; ++ch) add(reading.front[b][ch]);
      for (std::size_t ch = 0; ch < channels; ++ch) add(reading.back[b][ch]);
      text += "\n";
    }
  }
  return text;
}

nlohmann::json result_to_json(const Solver& solver, int samples_per_curve, const ErrorEstimate* estimate) {
  return result_to_json(solver, samples_per_curve, sample_solver(solver, samples_per_curve, estimate));
}

std::string result_text(const Solver& solver, int samples_per_curve, const ErrorEstimate* estimate) {
  return result_text(solver, samples_per_curve, sample_solver(solver, samples_per_curve, estimate));
}

nlohmann::json result_to_json(const Solver& solver, int samples_per_curve, const SampledResult& sampled) {
  nlohmann::json result = result_without_curves(solver, samples_per_curve, sampled);
  result["curves"] = curves_to_json(sampled);
  return result;
}

std::string result_text(const Solver& solver, int samples_per_curve, const SampledResult& sampled) {
  const std::string outline = json_text(result_without_curves(solver, samples_per_curve, sampled));
  // The outline holds `"curves": []` (keys are sorted, so first); the curves go in its place as
  // dump(1) would write them at that depth: "[", each entry on its own lines two spaces in, "]"
  // one space in.
  const std::string empty = "\"curves\": []";
  const std::size_t at = outline.find(empty);
  if (at == std::string::npos || sampled.curves.empty()) return outline;
  const std::size_t open = at + empty.size() - 2;
  std::string text(outline, 0, open);
  // nlohmann's serializer (a detail of the library, the same from 3.10 to 3.12) writes an entry
  // at a given depth, as dump() does inside a document.
  nlohmann::detail::serializer<nlohmann::json> serializer(nlohmann::detail::output_adapter<char>(text), ' ',
                                                          nlohmann::json::error_handler_t::replace);
  text += "[\n";
  // Room for the whole text (growing by doubling copied it all twice): the numbers every curve
  // writes, at the bytes per number of the first kMeasured curves.
  constexpr std::size_t kMeasured = 64;
  const std::size_t curves = sampled.curves.size();
  std::size_t numbers_measured = 0;
  for (std::size_t c = 0; c < curves; ++c) {
    if (c == kMeasured) {
      std::size_t numbers_left = 0;
      for (std::size_t rest = c; rest < curves; ++rest)
        numbers_left += curve_json_numbers(sampled.curves[rest], sampled.channels);
      const double per_number = static_cast<double>(text.size() - open) / static_cast<double>(numbers_measured);
      text.reserve(text.size() + static_cast<std::size_t>(1.25 * per_number * static_cast<double>(numbers_left)) +
                   outline.size());
    }
    text += c == 0 ? "  " : ",\n  ";
    serializer.dump(curve_to_json(sampled.curves[c], sampled.channels), true, false, 1, 2);
    if (c < kMeasured) numbers_measured += curve_json_numbers(sampled.curves[c], sampled.channels);
  }
  text += "\n ]";
  text.append(outline, open + 2, std::string::npos);
  return text;
}

namespace {

// A relative error, or null where it is unbounded (JSON has no infinity).
nlohmann::json bound_or_null(double value) { return std::isfinite(value) ? nlohmann::json(value) : nlohmann::json(); }

nlohmann::json errors_to_json(const RelativeErrors& errors) {
  return {{"l1", bound_or_null(errors.l1)}, {"l2", bound_or_null(errors.l2)}, {"linf", bound_or_null(errors.linf)}};
}

}  // namespace

nlohmann::json estimated_error_to_json(const ErrorEstimate& estimate) {
  if (!estimate.available) return {{"available", false}, {"reason", estimate.unavailable}};
  nlohmann::json result = errors_to_json(estimate.bound);
  result["available"] = true;
  result["measure"] = "reflected";
  result["confidence"] = estimate.confidence;
  result["replicates"] = estimate.replicates;
  result["bounded"] = estimate.bounded;
  result["parts"] = {{"noise", errors_to_json(estimate.noise)},
                     {"storage", estimate.storage_estimated ? errors_to_json(estimate.storage) : nlohmann::json()},
                     {"unshot", errors_to_json(estimate.unshot)}};
  // A final gather's own discretisation error (docs/result-format.md): only results that gathered.
  if (estimate.gather.l1 > 0.0 || estimate.gather.l2 > 0.0 || estimate.gather.linf > 0.0)
    result["parts"]["gather"] = errors_to_json(estimate.gather);
  if (!estimate.caveat.empty()) result["caveat"] = estimate.caveat;
  nlohmann::json curves = nlohmann::json::object();
  for (const CurveErrorEstimate& curve : estimate.curves)
    curves[curve.id] = curve.measured ? errors_to_json(curve.bound) : nlohmann::json();
  result["curves"] = std::move(curves);
  return result;
}

nlohmann::json stats_to_json(const ResultStats& stats) {
  nlohmann::json result = {
      {"photons", stats.photons},
      {"rounds", stats.rounds},
      {"rays", stats.rays},
      {"seconds", stats.seconds},
      {"stop_reason", to_string(stats.stop_reason)},
      {"emitted_power", stats.books.emitted},
      {"absorbed_power", stats.books.absorbed},
      {"escaped_power", stats.books.escaped},
      {"unshot_power", stats.books.unshot},
  };
  if (stats.specular) {
    result["absorbed_by_mirrors_power"] = stats.books.absorbed_mirrors;
    result["absorbed_in_glass_power"] = stats.books.absorbed_glass;
    result["cut_power"] = stats.books.cut;
    result["chains_cut"] = stats.chains_cut;
  }
  if (stats.estimated_error) result["estimated_error"] = estimated_error_to_json(*stats.estimated_error);
  return result;
}

Result<nlohmann::json> parse_result(std::string_view text, const std::string& source) {
  auto at = [&](std::size_t offset) {
    const TextPosition p = position_of(text, offset);
    return source + ":" + std::to_string(p.line) + ":" + std::to_string(p.column) + ": ";
  };
  nlohmann::json document;
  try {
    document = nlohmann::json::parse(text.begin(), text.end());
  } catch (const nlohmann::json::parse_error& e) {
    return Error{at(e.byte > 0 ? e.byte - 1 : 0) +
                 "not valid JSON; is this a result written by "
                 "'flatland solve --out'?"};
  } catch (const nlohmann::json::out_of_range&) {
    const std::optional<std::size_t> offset = find_overflowing_number(text);
    return Error{(offset ? at(*offset) : source + ": ") +
                 "a number is beyond the range of a double (it overflows to infinity)"};
  } catch (const std::exception& e) {
    return Error{source + ": cannot read the result: " + e.what()};
  }
  if (!document.is_object() || !document.contains("flatland_result"))
    return Error{source +
                 ": not a flatland result (no \"flatland_result\" key); write one with "
                 "'flatland solve --out' or 'flatland reference --out'"};
  if (document["flatland_result"] != 1)
    return Error{source + ": unsupported result version " + document["flatland_result"].dump() +
                 "; this program reads version 1"};
  return document;
}

Result<nlohmann::json> read_result_file(const std::string& path, const std::atomic<bool>* cancel) {
  Result<std::string> text = read_input_file(path, "result file", cancel);
  if (!text) return text.error();
  return parse_result(*text, path);
}

std::string json_text(const nlohmann::json& document) {
  return document.dump(1, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

double result_sample_bytes(const Scene& scene, int samples_per_curve) {
  // One sample as json_text writes it inside a curve (depth 4, one space an indent):
  //     {                         "{" and "}," lines: 12 bytes
  //      "s": 0.5,                a number: 5 + 10 (the longest key, "B_back": ) + 24 + 2 = 41
  //      "B": [                   a spectrum of three: 5 + 11 + 1, three lines of 6 + 24 + 2,
  //       0.1,                    and "],": 8; 121 in all
  // s, x and y are numbers; B, B_back and E are numbers in a grey scene, spectra in colour.
  constexpr double kNumberLine = 41.0;
  constexpr double kSpectrumLines = 121.0;
  constexpr double kBraces = 12.0;
  const double value = scene.channels == 1 ? kNumberLine : kSpectrumLines;
  double bytes = 0.0;
  for (const Curve& curve : scene.curves) {
    const double values = 1.0 + (curve.sides == Sides::Both ? 1.0 : 0.0) + (scene.is_emitter(curve) ? 1.0 : 0.0);
    bytes += kBraces + 3.0 * kNumberLine + values * value;
  }
  return bytes * samples_per_curve;
}

Status check_result_size(const Scene& scene, int samples_per_curve) {
  const double bytes = result_sample_bytes(scene, samples_per_curve);
  if (bytes <= static_cast<double>(kMaxInputBytes)) return ok_status();
  const double per_sample = bytes / samples_per_curve;
  char message[400];
  std::snprintf(message, sizeof message,
                "samples: %d a curve on %zu curves would make a result of up to %s, more than %s, the most "
                "flatland reads back (docs/limits.md); give at most %.0f",
                samples_per_curve, scene.curves.size(), format_bytes(bytes).c_str(),
                format_bytes(static_cast<double>(kMaxInputBytes)).c_str(),
                std::max(1.0, std::floor(static_cast<double>(kMaxInputBytes) / per_sample)));
  return Error{message};
}

}  // namespace flatland
