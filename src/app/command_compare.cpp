// flatland compare: errors of a result against a reference along arc length.
#include <cstdio>

#include "app/commands.hpp"
#include "app/output.hpp"
#include "flatland/results/result_io.hpp"

namespace flatland::app {

Measure parse_measure(const std::string& text) { return text == "total" ? Measure::Total : Measure::Reflected; }

Result<std::size_t> find_curve(const std::vector<std::string>& ids, const std::string& id) {
  for (std::size_t c = 0; c < ids.size(); ++c)
    if (ids[c] == id) return c;
  // The valid ids, the first 20 of them: the message stays one line on a scene of many curves.
  std::string choices;
  for (std::size_t c = 0; c < ids.size() && c < 20; ++c) choices += (c > 0 ? ", " : "") + ids[c];
  if (ids.size() > 20) choices += ", ... (" + std::to_string(ids.size() - 20) + " more)";
  return Error{"--curve: no curve with id '" + id + "'; the curves are: " + choices};
}

namespace {

// The result's estimated error (its stats' "estimated_error") where it has one that measures
// what the comparison does; null otherwise.
const nlohmann::json* estimated_error_of(const nlohmann::json* result, Measure measure) {
  if (result == nullptr || measure != Measure::Reflected || !result->contains("stats")) return nullptr;
  const nlohmann::json& stats = (*result)["stats"];
  if (!stats.is_object() || !stats.contains("estimated_error")) return nullptr;
  const nlohmann::json& estimate = stats["estimated_error"];
  if (!estimate.is_object() || !estimate.value("available", false)) return nullptr;
  return &estimate;
}

// " 1.2345e-03" for a number, "   unbounded" for null (an estimate as large as B - E), blank else.
std::string bound_text(const nlohmann::json& errors, const char* key) {
  char text[32];
  if (errors.is_object() && errors.contains(key) && errors[key].is_number()) {
    std::snprintf(text, sizeof text, " %12.4e", errors[key].get<double>());
    return text;
  }
  return errors.is_object() && errors.contains(key) && errors[key].is_null() ? "    unbounded" : "             ";
}

std::string bounds_text(const nlohmann::json* errors) {
  if (errors == nullptr) return {};
  return bound_text(*errors, "l1") + bound_text(*errors, "l2") + bound_text(*errors, "linf");
}

}  // namespace

nlohmann::json comparison_to_json(const Comparison& comparison, const std::string& result, const std::string& reference,
                                  const nlohmann::json* result_document) {
  auto norms = [](const ErrorNorms& n) { return nlohmann::json{{"l1", n.l1}, {"l2", n.l2}, {"linf", n.linf}}; };
  nlohmann::json curves = nlohmann::json::array();
  for (const CurveError& curve : comparison.curves) {
    nlohmann::json entry = {{"id", curve.id}, {"measured", curve.measured}};
    if (curve.measured) entry.update(norms(curve.norms));
    curves.push_back(std::move(entry));
  }
  nlohmann::json document = {{"measure", comparison.measure == Measure::Reflected ? "reflected" : "total"},
                             {"result", result},
                             {"reference", reference},
                             {"curves", std::move(curves)},
                             {"scene", norms(comparison.scene)}};
  if (const nlohmann::json* estimate = estimated_error_of(result_document, comparison.measure))
    document["estimated_error"] = *estimate;
  return document;
}

void print_comparison(const Comparison& comparison, bool scene_row, const nlohmann::json* result) {
  const nlohmann::json* estimate = estimated_error_of(result, comparison.measure);
  std::fprintf(report_stream(), "%s\n",
               comparison.measure == Measure::Reflected
                   ? "errors of the reflected part B - E (emitted light E is exact in every method)"
                   : "errors of the radiosity B (emitted + reflected)");
  if (estimate != nullptr)
    std::fprintf(report_stream(), "%-24s %12s %12s %12s   estimated bound at %g %% confidence:\n", "", "", "", "",
                 100.0 * estimate->value("confidence", 0.0));
  std::fprintf(report_stream(), "%-24s %12s %12s %12s%s\n", "curve", "rel. L1", "rel. L2", "rel. Linf",
               estimate != nullptr ? "      est. L1      est. L2    est. Linf" : "");
  auto curve_bounds = [&](const std::string& id) -> std::string {
    if (estimate == nullptr || !estimate->contains("curves") || !(*estimate)["curves"].is_object()) return {};
    const nlohmann::json& curves = (*estimate)["curves"];
    return curves.contains(id) ? bounds_text(&curves[id]) : std::string();
  };
  for (const CurveError& curve : comparison.curves) {
    if (curve.measured)
      std::fprintf(report_stream(), "%-24s %12.4e %12.4e %12.4e%s\n", curve.id.c_str(), curve.norms.l1, curve.norms.l2,
                   curve.norms.linf, curve_bounds(curve.id).c_str());
    else
      std::fprintf(report_stream(), "%-24s %38s\n", curve.id.c_str(), "(reflects no light in the reference)");
  }
  if (scene_row)
    std::fprintf(report_stream(), "%-24s %12.4e %12.4e %12.4e%s\n", "(scene)", comparison.scene.l1, comparison.scene.l2,
                 comparison.scene.linf, bounds_text(estimate).c_str());
}

CLI::App* add_compare_command(CLI::App& parent, CompareOptions& o) {
  CLI::App* cmd =
      parent.add_subcommand("compare",
                            "Relative L1, L2 and L-infinity errors along arc length, of the reflected part B - E by "
                            "default, per curve and for the scene, of RESULT against REFERENCE (both written by "
                            "'flatland solve --out' or 'flatland reference --out' with the same --samples)");
  cmd->add_option("result", o.result, "The result to judge (JSON)")->required();
  cmd->add_option("reference", o.reference, "The reference result (JSON)")->required();
  cmd->add_option("--measure", o.measure,
                  "What is measured: 'reflected' (B - E, relative to the reference's B - E; the "
                  "emitters' exact E left out) or 'total' (B)")
      ->capture_default_str()
      ->check(CLI::IsMember({"reflected", "total"}));
  cmd->add_option("--curve", o.curve, "Print only the curve with this id (as in the scene file)");
  cmd->add_flag("--json", o.json,
                "Print the errors as one JSON document (measure, per-curve and scene L1, L2, "
                "Linf; docs/result-format.md) instead of a table");
  return cmd;
}

int run_compare(const CompareOptions& o) {
  Result<nlohmann::json> result = read_result_file(o.result, &interrupt_flag());
  if (!result) return input_error(result.error());
  Result<nlohmann::json> reference = read_result_file(o.reference, &interrupt_flag());
  if (!reference) return input_error(reference.error());
  const Measure measure = parse_measure(o.measure);
  Result<Comparison> comparison = compare_results(*result, *reference, measure);
  if (!comparison) {
    const std::string& message = comparison.error().message;
    return usage_error(o.result + " and " + o.reference + ": " + message +
                       (message == kNothingReflected ? " (--measure total)" : ""));
  }
  if (!o.curve.empty()) {
    std::vector<std::string> ids;
    for (const CurveError& curve : comparison->curves) ids.push_back(curve.id);
    Result<std::size_t> index = find_curve(ids, o.curve);
    if (!index) return usage_error(index.error().message);
    const CurveError chosen = comparison->curves[*index];
    if (!chosen.measured)
      return usage_error("--curve: '" + o.curve +
                         "' reflects no light in the reference (B - E is zero "
                         "along it), so it has no relative error of B - E; use --measure total");
    comparison->curves = {chosen};
  }
  if (o.json) {
    std::printf("%s\n", comparison_to_json(*comparison, o.result, o.reference, &*result)
                            .dump(2, ' ', false, nlohmann::json::error_handler_t::replace)
                            .c_str());
  } else {
    print_comparison(*comparison, o.curve.empty(), &*result);
  }
  return kExitOk;
}

}  // namespace flatland::app
