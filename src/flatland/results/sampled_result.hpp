// A result as data: each curve's samples of B (and of B_back and the emitted part E), its stored
// spline and the solve's statistics. Comparisons, convergence runs, the viewer and the Python module
// work on this; JSON is only the edge (result_io: the files `solve --out` and `reference --out`
// write, and documents read back).
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "flatland/base/status.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/storage/curve_storage.hpp"
#include "flatland/transport/error_estimate.hpp"
#include "flatland/transport/solver.hpp"

namespace flatland {

struct ResultSample {
  double s = 0.0;  // arc length from the curve's start
  double x = 0.0;
  double y = 0.0;
  Spectrum B{};                    // the main side (front, or back on a back-only curve)
  std::optional<Spectrum> B_back;  // two-sided curves
  std::optional<Spectrum> E;       // the emitted part, on emitters
};

// The spline a solver stored along a curve: B(u) = E + sum_k b_k phi_k(u) with phi_k the B-splines
// of `degree` on `knots` (docs/result-format.md).
struct StoredSpline {
  int degree = 0;
  int elements = 0;  // the mesh in use (auto storage: the level chosen)
  bool periodic = false;
  std::optional<Continuity> closing;  // closed curves
  std::vector<double> knots;
  std::vector<MeshNode> continuity;       // nodes below C1
  std::vector<double> coefficients;       // main side; empty when it reflects nothing
  std::vector<double> coefficients_back;  // two-sided curves
};

struct ResultCurve {
  std::string id;
  double length = 0.0;
  Sides sides = Sides::Front;
  int segments = 0;
  std::optional<Spectrum> emittance;   // absent in documents that do not say
  std::vector<ResultSample> samples;   // at s_j = (j + 0.5) L / K
  std::optional<StoredSpline> spline;  // results of a solver
};

struct ResultStats {
  std::uint64_t photons = 0;
  std::uint32_t rounds = 0;
  std::uint64_t rays = 0;
  double seconds = 0.0;
  StopReason stop_reason = StopReason::Running;
  EnergyBooks books;
  // Scenes with mirrors, glass or detectors: the books' chain lines are written, and the photons
  // cut at the chain limit.
  bool specular = false;
  std::uint64_t chains_cut = 0;
  // The solver's own estimate of its error (absent in documents that do not have one).
  std::optional<ErrorEstimate> estimated_error;
};

struct SampledResult {
  int channels = 1;  // 1 (grey) or 3; a grey value is channel 0 of its Spectrum
  // The SHA-256 of the scene the result was made from (hex; Scene::content_sha256), or where the
  // result does not record that, of the scene file's bytes; empty where neither is known (a
  // document without "scene"). Results of different scenes are never compared.
  std::string scene_sha256;
  std::vector<ResultCurve> curves;
  std::optional<ResultStats> stats;  // results of a solver
  // Results whose B is a final gather of the solver's (reference/final_gather.hpp): its element
  // length h.
  std::optional<double> final_gather;
};

// Radiosity as JSON: a number for grey scenes, [r,g,b] for colour ones.
nlohmann::json spectrum_to_json(const Spectrum& value, int channels);

// Radiosity leaving a side of a curve at curve parameter u.
using RadiosityFunction = std::function<Spectrum(std::uint32_t curve, Side side, double u)>;

// K samples per curve of any method's radiosity (no spline, no stats).
SampledResult sample_radiosity(const Scene& scene, int samples_per_curve, const RadiosityFunction& radiosity);
// A solver's result: its radiosity sampled, its stored splines and its statistics, with its
// estimated error (`estimate`, or estimate_error at these samples and the settings' confidence).
SampledResult sample_solver(const Solver& solver, int samples_per_curve, const ErrorEstimate* estimate = nullptr);

// The "curves" array of a result document (with the splines when the result has them), and one
// entry of it.
nlohmann::json curves_to_json(const SampledResult& result);
nlohmann::json curve_to_json(const ResultCurve& curve, int channels);
// About how many numbers curve_to_json writes for the curve (each sample counted with all its
// optional spectra): what result_text reserves room by.
std::size_t curve_json_numbers(const ResultCurve& curve, int channels);
// The curves of a result document. `what` names it in errors ("the result", "the reference");
// `suffix` is appended to the place of a malformed value (" (reference)").
Result<SampledResult> sampled_from_json(const nlohmann::json& document, const std::string& what,
                                        const std::string& suffix = "");

// Whether `reference` is of `scene` (made from the same file, by the SHA-256 it records, and with
// the same curves' ids, in order) and, when `samples` > 0, sampled
// `samples` times per curve; the error says what differs ("the reference describes another scene
// than FILE ..." or "the reference has N samples per curve, the runs M").
Status check_reference_of(const SampledResult& reference, const Scene& scene, int samples = 0);

}  // namespace flatland
