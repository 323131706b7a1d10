// The result file of `flatland solve` (format "flatland_result": 1, docs/result-format.md) and the
// atomic file writing every output goes through.
#pragma once

#include <functional>
#include <string>

#include <nlohmann/json.hpp>

#include "flatland/result.hpp"
#include "flatland/scene.hpp"
#include "flatland/solver.hpp"

namespace flatland {

// Radiosity as JSON: a number for grey scenes, [r,g,b] for colour ones.
nlohmann::json spectrum_to_json(const Spectrum& value, int channels);

// The whole result document: scene, settings, stats and K samples per curve at s_j = (j+0.5) L/K.
nlohmann::json result_to_json(const Solver& solver, int samples_per_curve);

// The "curves" array of a result for any method: per curve id, length, sides and K samples of
// the radiosity given by `radiosity(curve, side, u)` (B of the main side, B_back on two-sided
// curves).
using RadiosityFunction = std::function<Spectrum(std::uint32_t curve, Side side, double u)>;
nlohmann::json sampled_curves_to_json(const Scene& scene, int samples_per_curve,
                                      const RadiosityFunction& radiosity);
// The "scene" entry of a result.
nlohmann::json scene_to_json(const Scene& scene);

// Writes `contents` to a temporary file beside `path`, then renames it over `path`: a failed or
// interrupted write never leaves a partial file. The error names the path and the reason.
Status write_file_atomically(const std::string& path, const std::string& contents);

}  // namespace flatland
