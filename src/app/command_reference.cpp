// flatland reference: the deterministic reference solution of a scene (constant elements on
// chords, exact visibility, a linear solve and a final gather at the output samples).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <thread>

#include "app/commands.hpp"
#include "app/output.hpp"
#include "app/progress.hpp"
#include "flatland/reference/reference.hpp"
#include "flatland/reference/reference_io.hpp"
#include "flatland/results/result_io.hpp"

namespace flatland::app {

CLI::App* add_reference_command(CLI::App& parent, ReferenceOptions& o) {
  CLI::App* cmd = parent.add_subcommand(
      "reference",
      "Solve a scene deterministically (constant elements on fine chords, form factors with exact "
      "visibility, GMRES, final gather at the samples) and write the same result format as "
      "solve, with \"method\": \"reference\"");
  cmd->add_option("scene", o.scene, "Scene file (JSON, docs/scene-format.md)")->required();
  auto* length = cmd->add_option("--max-element-length", o.max_element_length,
                                 "Longest element in scene units (default: scene size / 400)")
                     ->check(CLI::Validator(
                         [](std::string& text) -> std::string {
                           char* end = nullptr;
                           const double value = std::strtod(text.c_str(), &end);
                           if (end == text.c_str() || *end != '\0' || !(value > 0.0) || !std::isfinite(value))
                             return "must be a positive length in scene units, not " + text;
                           return {};
                         },
                         "LENGTH"));
  auto* elements = cmd->add_option("--elements", o.elements,
                                   "Elements across the scene: the longest element is the scene's "
                                   "size (bounding-box diagonal) / N")
                       ->check(CLI::Range(1, 1 << 20));
  length->excludes(elements);
  cmd->add_option("--quadrature", o.settings.quadrature, "Gauss-Legendre points per element for the form factors")
      ->capture_default_str()
      ->check(CLI::Range(1, 64));
  cmd->add_option("--tolerance", o.settings.tolerance,
                  "Relative error of the linear solve (guaranteed by its residual)")
      ->capture_default_str();
  cmd->add_flag("!--no-error-estimate", o.estimate_error,
                "Skip the two extra solves, with elements twice and four times as long, that "
                "estimate the reference's own discretisation error: |R_2h - R_h| / (2^p - 1) with "
                "the order p observed from the three (stats.estimated_error, stats.observed_order)");
  cmd->add_option("--threads", o.settings.threads, "Worker threads (0: every core)")
      ->capture_default_str()
      ->check(CLI::Range(0u, 1024u));
  cmd->add_option("--samples", o.samples, "Radiosity samples per curve in the result, at arc length (j + 0.5) L / K")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000000));
  cmd->add_option("--out", o.out, "Write the result as JSON to this file (docs/result-format.md)")
      ->check(output_path());
  cmd->add_flag("--quiet", o.quiet, "No summary (errors only)");
  return cmd;
}

namespace {

int reference_failure(const Error& error) {
  return interrupt_flag().load() ? interrupted() : usage_error(error.message);
}

void warn_about_reference_size(const Scene& scene, const ReferenceSettings& settings, bool quiet) {
  // Form factors cost about 4.5e-7 s x N^2 on two cores (docs/reference.md: 12,530 elements of
  // the default scene take 70 s), more with many occluders.
  const double elements = reference_element_count(scene, settings);
  if (quiet || elements < 10'000 || elements > static_cast<double>(kMaxReferenceElements)) return;
  const unsigned threads = settings.threads != 0 ? settings.threads : std::max(1u, std::thread::hardware_concurrency());
  const double seconds = 4.5e-7 * elements * elements * 2.0 / threads;
  std::fprintf(stderr,
               "reference: %.0f elements: the form factors take time and memory growing as the "
               "square of the count (roughly %s here); Ctrl-C stops it\n",
               elements, human_duration(seconds).c_str());
}

}  // namespace

Result<ErrorNorms> estimate_reference_error(const Scene& scene, ReferenceSettings settings, int samples,
                                            const SampledResult& fine) {
  // Solves at 2h and 4h and extrapolates with the observed order (docs/reference.md).
  Result<ReferenceErrorEstimate> estimate = estimate_discretisation_error(scene, settings, samples, fine);
  if (!estimate) return estimate.error();
  return estimate->error;
}

int run_reference(ReferenceOptions& o) {
  Result<Scene> scene = load_scene(o.scene, &interrupt_flag());
  if (!scene) return input_error(scene.error());
  if (o.max_element_length != 0.0) {
    if (!(o.max_element_length > 0.0) || !std::isfinite(o.max_element_length))
      return usage_error("--max-element-length: must be a positive length");
    o.settings.max_element_length = o.max_element_length;
  } else if (o.elements > 0) {
    o.settings.max_element_length = scene->scale / o.elements;
  }
  if (Status status = validate(o.settings); !status) return usage_error(status.error().message);
  if (const std::optional<int> code = check_outputs({{"--out", o.out}}, {{"scene file", o.scene}})) return *code;
  if (!o.out.empty())
    if (Status status = check_result_size(*scene, o.samples); !status) return usage_error(status.error().message);
  o.settings.cancel = &interrupt_flag();
  warn_about_reference_size(*scene, o.settings, o.quiet);
  const auto start = std::chrono::steady_clock::now();
  // Progress of the form factors on a terminal: the solve's, then the error estimate's.
  ProgressLine line(!o.quiet);
  std::string phase = o.estimate_error ? "reference, resolution 1 of 3" : "reference";
  auto phase_start = start;
  o.settings.progress = [&](std::size_t done, std::size_t rows) {
    const double elapsed = std::chrono::duration<double>(std::chrono::steady_clock::now() - phase_start).count();
    const double left =
        elapsed * static_cast<double>(rows - done) / static_cast<double>(std::max<std::size_t>(done, 1));
    char text[200];
    std::snprintf(text, sizeof text, "%s: form factors %.0f%% (%zu / %zu rows), %.0f s, about %s left", phase.c_str(),
                  100.0 * static_cast<double>(done) / static_cast<double>(rows), done, rows, elapsed,
                  human_duration(left).c_str());
    line.show(text);
  };
  Result<ReferenceSolution> solution = solve_reference(*scene, o.settings);
  line.finish();
  if (!solution) return reference_failure(solution.error());
  if (!o.quiet && !solution->thread_shortfall().empty())
    note(solution->thread_shortfall() + "; the reference is the same on any thread count");
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const ReferenceSolution& reference = *solution;
  const SampledResult sampled = sample_radiosity(*scene, o.samples, [&reference](std::uint32_t c, Side side, double u) {
    return reference.radiosity(c, side, u);
  });
  const nlohmann::json curves = curves_to_json(sampled);
  std::optional<ReferenceErrorEstimate> estimated;
  if (o.estimate_error) {
    const auto starting = [&](int level) {
      line.finish();
      phase = level == 1 ? "error estimate, resolution 2 of 3 (elements twice as long)"
                         : "error estimate, resolution 3 of 3 (elements four times as long)";
      phase_start = std::chrono::steady_clock::now();
    };
    Result<ReferenceErrorEstimate> estimate =
        estimate_discretisation_error(*scene, o.settings, o.samples, sampled, starting);
    line.finish();
    if (!estimate) return reference_failure(estimate.error());
    estimated = *estimate;
  }
  if (!o.quiet) {
    std::FILE* out = report_stream();
    std::fprintf(out, "scene     %s (%s): %zu curves\n", scene->name.c_str(), scene->source.c_str(),
                 scene->curves.size());
    std::fprintf(out, "reference %zu elements, %d GMRES steps, residual %.2g, linear-solve error below %.2g%s\n",
                 solution->elements(), solution->iterations(), solution->residual(), solution->error_bound(),
                 solution->error_bound() > o.settings.tolerance ? " (tolerance not reached: round-off)" : "");
    std::fprintf(out, "time      %.3f s (form factors %.3f s, solve %.3f s)\n", seconds,
                 solution->form_factor_seconds(), solution->solve_seconds());
    if (estimated) {
      const ErrorNorms& e = estimated->error;
      if (std::isnan(estimated->order))
        std::fprintf(out, "accuracy  estimated relative error L1 %.2g, L2 %.2g, Linf %.2g (no order: %s)\n", e.l1, e.l2,
                     e.linf, estimated->note.c_str());
      else
        std::fprintf(out,
                     "accuracy  estimated relative error L1 %.2g, L2 %.2g, Linf %.2g (observed order %.2f "
                     "from elements 1, 2 and 4 times as long%s%s)\n",
                     e.l1, e.l2, e.linf, estimated->order, estimated->note.empty() ? "" : ": ",
                     estimated->note.c_str());
    }
  }
  if (!o.out.empty()) {
    const nlohmann::json result = reference_result_to_json(*scene, o.settings, *solution, o.samples, seconds,
                                                           estimated ? &*estimated : nullptr, curves);
    OutputFiles files(&interrupt_flag());
    if (Status status = files.stage(o.out, json_text(result)); !status) return usage_error(status.error().message);
    if (const std::optional<int> code = commit_outputs(files)) return *code;
    if (!o.quiet) std::fprintf(report_stream(), "wrote     %s\n", o.out.c_str());
  }
  return kExitOk;
}

}  // namespace flatland::app
