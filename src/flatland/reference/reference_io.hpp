#pragma once
// The reference's result document: the reference sits above results/ (it samples and compares
// with SampledResult), so its document is written here, from results/' pieces.

#include <nlohmann/json.hpp>

#include "flatland/reference/reference.hpp"
#include "flatland/scene/scene.hpp"

namespace flatland {

// The document `flatland reference --out` writes: the reference's settings and statistics, its
// estimated error when `estimate` is given, and `curves` (curves_to_json of its samples).
nlohmann::json reference_result_to_json(const Scene& scene, const ReferenceSettings& settings,
                                        const ReferenceSolution& solution, int samples_per_curve, double seconds,
                                        const ReferenceErrorEstimate* estimate, const nlohmann::json& curves);

}  // namespace flatland
