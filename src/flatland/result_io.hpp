// The result file of `flatland solve` (format "flatland_result": 1, docs/result-format.md) and the
// atomic file writing every output goes through.
#pragma once

#include <atomic>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "flatland/result.hpp"
#include "flatland/scene.hpp"
#include "flatland/solver.hpp"
#include "flatland/reference.hpp"
#include "flatland/sampled_result.hpp"

namespace flatland {


// The whole result document: scene, settings, stats and K samples per curve at s_j = (j+0.5) L/K.
nlohmann::json result_to_json(const Solver& solver, int samples_per_curve);
// json_text(result_to_json(solver, samples_per_curve)), byte for byte, with the curves written
// one at a time instead of held as one JSON tree: a scene of 65,536 curves spent 6 s building
// that tree (small allocations, page faults) and 3 s writing it out.
std::string result_text(const Solver& solver, int samples_per_curve);

// The document `flatland reference --out` writes: the reference's settings and statistics, its
// estimated error when `estimate` is given, and `curves` (curves_to_json of its samples).
nlohmann::json reference_result_to_json(const Scene& scene, const ReferenceSettings& settings,
                                        const ReferenceSolution& solution, int samples_per_curve,
                                        double seconds, const ReferenceErrorEstimate* estimate,
                                        const nlohmann::json& curves);

// The "stats" entry of a solver's result.
nlohmann::json stats_to_json(const ResultStats& stats);
// The "scene" entry of a result.
nlohmann::json scene_to_json(const Scene& scene);
// The program that wrote a result: {"name": "flatland", "version", "commit"} (version.hpp).
nlohmann::json program_to_json();

// A result document from its text (`source` names it in errors): JSON whose top level is an
// object with "flatland_result": 1. Errors name the source, line and column (numbers beyond a
// double's range included) and never throw.
Result<nlohmann::json> parse_result(std::string_view text, const std::string& source);
Result<nlohmann::json> read_result_file(const std::string& path);

// The text of a JSON document as every output writes it (one-space indent, a final newline).
// Strings that are not valid UTF-8 (a scene file's name can be any bytes) have the invalid bytes
// replaced by U+FFFD instead of failing.
std::string json_text(const nlohmann::json& document);

// Checks, before any work starts, that `path` can be written as a file: it names a file (not a
// directory) in a directory that exists and is writable. The error names the path and the fix.
Status check_output_file(const std::string& path);

// Output files written all or nothing. stage() writes each file's contents to a temporary file
// beside it (.NAME.tmpPID-RANDOM, in the same directory, so the rename is atomic); commit()
// renames them all over their targets. Files staged but not committed (an error, an interrupt)
// are removed when the object goes away, so no partial output is ever left. A temporary file
// that a killed process (SIGKILL, power loss) left behind is removed by the next stage() of the
// same target once its process no longer runs.
class OutputFiles {
 public:
  OutputFiles() = default;
  OutputFiles(const OutputFiles&) = delete;
  OutputFiles& operator=(const OutputFiles&) = delete;
  ~OutputFiles();

  Status stage(const std::string& path, const std::string& contents);
  // Renames every staged file over its target, in staging order.
  Status commit();
  // Removes every staged file that is not committed yet.
  void discard();

 private:
  struct Staged {
    std::string target;
    std::string temporary;
  };
  std::vector<Staged> staged_;
};

// At most this many radiosity samples in one result (curves x samples, two-sided curves twice):
// about 100 bytes of JSON each, so 1 GB of text and several GB while it is built.
inline constexpr double kMaxResultSamples = 1e7;
// Refuses, before any work, a result that would hold more samples than that.
Status check_result_size(const Scene& scene, int samples_per_curve);

// Writes `contents` to a temporary file beside `path`, then renames it over `path`: a failed or
// interrupted write never leaves a partial file. The error names the path and the reason.
Status write_file_atomically(const std::string& path, const std::string& contents);

}  // namespace flatland
