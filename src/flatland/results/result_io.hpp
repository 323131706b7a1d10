// The result file of `flatland solve` (format "flatland_result": 1, docs/result-format.md).
#pragma once

#include <atomic>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "flatland/base/files.hpp"
#include "flatland/base/status.hpp"
#include "flatland/results/sampled_result.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/transport/solver.hpp"

namespace flatland {

// The whole result document: scene, settings, stats and K samples per curve at s_j = (j+0.5) L/K.
// `estimate`: the solver's estimated error, when already made (else it is made here).
nlohmann::json result_to_json(const Solver& solver, int samples_per_curve, const ErrorEstimate* estimate = nullptr);
// json_text(result_to_json(solver, samples_per_curve)), byte for byte, with the curves written
// one at a time instead of held as one JSON tree, whose many small allocations cost seconds on
// scenes of tens of thousands of curves (docs/performance.md).
std::string result_text(const Solver& solver, int samples_per_curve, const ErrorEstimate* estimate = nullptr);
// The same two of a result already sampled from the solver (a final gather's, reference/final_gather.hpp).
nlohmann::json result_to_json(const Solver& solver, int samples_per_curve, const SampledResult& sampled);
std::string result_text(const Solver& solver, int samples_per_curve, const SampledResult& sampled);

// The detectors' tallies (Solver::detected): per detector curve its id, length, bins and, per bin,
// the power crossing it from its front side to its back ("front") and from the back ("back"),
// a number or [r, g, b]; the "detectors" entry of a result (absent without detectors).
nlohmann::json detectors_to_json(const Solver& solver);
// The same as CSV, one line per detector bin: detector, bin, s_from, s_to (arc length), x, y
// (the bin's middle), then front and back (one column each, or front_r, front_g, front_b, back_r,
// back_g, back_b in colour).
std::string detectors_csv(const Solver& solver);

// The "stats" entry of a solver's result.
nlohmann::json stats_to_json(const ResultStats& stats);
// The "estimated_error" entry of a solver's result's stats (docs/result-format.md).
nlohmann::json estimated_error_to_json(const ErrorEstimate& estimate);
// The "scene" entry of a result.
nlohmann::json scene_to_json(const Scene& scene);
// The program that wrote a result: {"name": "flatland", "version", "commit"} (version.hpp).
nlohmann::json program_to_json();

// A result document from its text (`source` names it in errors): JSON whose top level is an
// object with "flatland_result": 1. Errors name the source, line and column (numbers beyond a
// double's range included) and never throw.
Result<nlohmann::json> parse_result(std::string_view text, const std::string& source);
// The result file at `path`, read by read_input_file (a pipe's wait ends when `cancel` is set).
Result<nlohmann::json> read_result_file(const std::string& path, const std::atomic<bool>* cancel = nullptr);

// The text of a JSON document as every output writes it (one-space indent, a final newline).
// Strings that are not valid UTF-8 (a scene file's name can be any bytes) have the invalid bytes
// replaced by U+FFFD instead of failing.
std::string json_text(const nlohmann::json& document);

// An upper bound of the bytes that `samples_per_curve` samples of every curve take in a result's
// text (json_text): each number at its longest shortest-round-trip form, 24 characters, with the
// keys and indentation around it; a two-sided curve's samples hold B_back, an emitter's E.
double result_sample_bytes(const Scene& scene, int samples_per_curve);
// Refuses, before any work, a result whose samples could take more than kMaxInputBytes, so that
// every result the program writes is one it can read back; the message gives the largest
// --samples that fits.
Status check_result_size(const Scene& scene, int samples_per_curve);

}  // namespace flatland
