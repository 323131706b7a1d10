#include "flatland/reference/reference_io.hpp"

#include <cmath>

#include "flatland/results/result_io.hpp"

namespace flatland {

nlohmann::json reference_result_to_json(const Scene& scene, const ReferenceSettings& settings,
                                        const ReferenceSolution& solution, int samples_per_curve, double seconds,
                                        const ReferenceErrorEstimate* estimate, const nlohmann::json& curves) {
  nlohmann::json result;
  result["flatland_result"] = 1;
  result["program"] = program_to_json();
  result["scene"] = scene_to_json(scene);
  result["settings"] = {
      {"method", "reference"},
      {"max_element_length", settings.max_element_length > 0.0 ? settings.max_element_length : scene.scale / 400.0},
      {"quadrature", settings.quadrature},
      {"tolerance", settings.tolerance},
      {"samples", samples_per_curve}};
  result["stats"] = {{"elements", solution.elements()},
                     {"iterations", solution.iterations()},
                     {"residual", solution.residual()},
                     {"error_bound", solution.error_bound()},
                     {"seconds", seconds},
                     {"form_factor_seconds", solution.form_factor_seconds()},
                     {"solve_seconds", solution.solve_seconds()}};
  if (estimate != nullptr) {
    const ErrorNorms& e = estimate->error;
    result["stats"]["estimated_error"] = {{"l1", e.l1}, {"l2", e.l2}, {"linf", e.linf}};
    // null where no order could be observed (differences at round-off).
    auto number_or_null = [](double value) {
      return std::isnan(value) ? nlohmann::json(nullptr) : nlohmann::json(value);
    };
    result["stats"]["observed_order"] = number_or_null(estimate->observed_order);
    result["stats"]["estimate_order"] = number_or_null(estimate->order);
    if (!estimate->note.empty()) result["stats"]["estimate_note"] = estimate->note;
  }
  result["curves"] = curves;
  return result;
}

}  // namespace flatland
