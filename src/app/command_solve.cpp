// flatland solve: progressive Monte Carlo shooting on one scene.
#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <optional>
#include <string>
#include <thread>

#include "app/commands.hpp"
#include "app/output.hpp"
#include "app/picture.hpp"
#include "app/processes.hpp"
#include "app/progress.hpp"
#include "flatland/base/text.hpp"
#include "flatland/reference/coarse_answer.hpp"
#include "flatland/reference/final_gather.hpp"
#include "flatland/results/result_io.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/transport/importance.hpp"
#include "flatland/transport/options.hpp"

namespace flatland::app {

Result<std::uint64_t> parse_count(const std::string& text, const std::string& option) {
  return parse_photon_count(text, option);
}

SolveOptions::SolveOptions() {
  const SolverSettings defaults;
  for (const SolveOptionSpec& spec : solve_options()) text[spec.option] = solve_option_text(defaults, spec.option);
}

void add_solver_options(CLI::App* cmd, SolveOptions& o) {
  // Every option of options.hpp, with its help and what it accepts; the values are checked by
  // finish_solver_settings, as Python's and converge's are.
  for (const SolveOptionSpec& spec : solve_options()) {
    // What it takes, as the help shows it: its names (basis: constant|linear|cubic|hermite) or a
    // letter for a number.
    std::string takes(spec.value);
    for (std::size_t i = 0; i < spec.choices.size(); ++i) takes += (i > 0 ? "|" : "") + std::string(spec.choices[i]);
    cmd->add_option("--" + std::string(spec.flag), o.text[spec.option], std::string(spec.help))
        ->capture_default_str()
        ->type_name(takes);
  }
}

CLI::App* add_solve_command(CLI::App& parent, SolveOptions& o) {
  CLI::App* cmd = parent.add_subcommand(
      "solve", "Solve a scene by progressive Monte Carlo shooting and report the radiosity along every curve.");
  cmd->add_option("scene", o.scene, "Scene file (JSON, docs/scene-format.md)")->required();
  add_solver_options(cmd, o);
  cmd->add_option("--samples", o.samples, "Radiosity samples per curve in the result, at arc length (j + 0.5) L / K")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000000));
  cmd->add_option("--out", o.out, "Write the result as JSON to this file (docs/result-format.md)")
      ->check(output_path());
  cmd->add_option("--picture", o.picture, "Write a PNG picture of the curves coloured by their radiosity")
      ->check(output_path());
  cmd->add_option("--detectors", o.detectors,
                  "Write the power crossing each bin of the scene's detector curves as CSV to this file "
                  "(docs/result-format.md)")
      ->check(output_path());
  cmd->add_option("--reference", o.reference,
                  "A reference result (same scene, same --samples): print the errors against it");
  cmd->add_flag("--quiet", o.quiet, "No progress line and no summary (errors only)");
  return cmd;
}

namespace {

// "error     ~ 0.042 % (L1 of B - E, at most, 95 % confidence; L2 0.05 %, Linf 0.2 %)", or why there
// is none; its caveat on a line of its own.
// ", gather 0.0012 %" where a final gather estimated its own error; empty otherwise.
std::string gather_part(const ErrorEstimate& estimate) {
  if (!(estimate.gather.l1 > 0.0)) return "";
  return ", gather " + format_number(100.0 * estimate.gather.l1, 2) + " %";
}

// " (8 blocks of one net)": how the replicates the noise part is read from were laid out. With the
// random sampler there is no net: blocks and independent replicates are alike independent photons.
std::string replicates_part(const SolverSettings& settings) {
  const char* kind = settings.sampler != SamplerKind::Sobol                 ? " replicates"
                     : settings.replicate_layout == ReplicateLayout::Blocks ? " blocks of one net"
                                                                            : " independent nets";
  return " (" + std::to_string(settings.replicates) + kind + ")";
}

void print_estimated_error(std::FILE* out, const ErrorEstimate& estimate, const SolverSettings& settings) {
  if (!estimate.available) {
    std::fprintf(out, "error     not estimated: %s\n", estimate.unavailable.c_str());
    return;
  }
  if (estimate.bounded)
    std::fprintf(
        out,
        "error     ~ %.2g %% or less (relative L1 of B - E at %g %% confidence; L2 %.2g %%, Linf %.2g %%; "
        "noise %.2g %%%s, storage %s, unshot %.2g %%%s)\n",
        100.0 * estimate.bound.l1, 100.0 * estimate.confidence, 100.0 * estimate.bound.l2, 100.0 * estimate.bound.linf,
        100.0 * estimate.noise.l1, replicates_part(settings).c_str(),
        estimate.storage_estimated ? (format_number(100.0 * estimate.storage.l1, 2) + " %").c_str() : "not estimated",
        100.0 * estimate.unshot.l1, gather_part(estimate).c_str());
  else
    std::fprintf(out, "error     unbounded at %g %% confidence\n", 100.0 * estimate.confidence);
  if (!estimate.caveat.empty()) std::fprintf(out, "          (%s)\n", estimate.caveat.c_str());
}

void print_summary(const Solver& solver, const ErrorEstimate& estimate) {
  std::FILE* out = report_stream();
  const Scene& scene = solver.scene();
  std::size_t cubic_segments = 0;
  for (const SceneSegment& segment : scene.segments)
    if (segment.geometry.kind == SegmentKind::Cubic) ++cubic_segments;
  const EnergyBooks books = solver.books();
  const double rate = solver.seconds() > 0.0 ? static_cast<double>(solver.photons_shot()) / solver.seconds() : 0.0;
  std::fprintf(out, "scene     %s (%s): %zu curves, %zu segments (%zu cubic), %s\n", scene.name.c_str(),
               scene.source.c_str(), scene.curves.size(), scene.segments.size(), cubic_segments,
               scene.channels == 1 ? "grey" : "colour");
  const SolverSettings& settings = solver.settings();
  char rays[160] = "point rays";
  if (settings.ray_width > 0.0) {
    if (settings.ray_mode == RayMode::Band)
      std::snprintf(rays, sizeof rays, "band of %d rays %g wide (%s)", settings.band_rays, settings.ray_width,
                    to_string(settings.ray_profile));
    else
      std::snprintf(rays, sizeof rays, "footprint rays %g wide (%s)", settings.ray_width,
                    to_string(settings.ray_profile));
  }
  // The storage mesh: fixed, or with auto storage the elements each curve chose (min .. max).
  char storage_text[96];
  if (solver.auto_storage()) {
    int fewest = std::numeric_limits<int>::max();
    int most = 0;
    for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
      const Spectrum& rho = scene.material_of(scene.curves[c]).reflectivity;
      if (!(rho[0] + rho[1] + rho[2] > 0.0)) continue;  // nothing to estimate: the finest is kept
      fewest = std::min(fewest, solver.storage_elements(c));
      most = std::max(most, solver.storage_elements(c));
    }
    std::snprintf(storage_text, sizeof storage_text, "auto elements (%d .. %d per reflecting curve chosen)",
                  most == 0 ? 0 : fewest, most);
  } else {
    std::snprintf(storage_text, sizeof storage_text, "%d elements per curve", settings.elements);
  }
  std::string walks_text;
  if (settings.transport == Transport::Walk)
    walks_text = std::string("random walks (") + to_string(settings.walk_score) + " score), ";
  if (settings.transport == Transport::Jacobi)
    walks_text = solver.jacobi_iterations() > 0
                     ? "averaged Jacobi iterations (" + std::to_string(solver.jacobi_iterations()) +
                           (settings.target_error > 0.0 ? " in the last pass), " : " after the increments), ")
                     : std::string(
                           "averaged Jacobi iterations (none finished: the increments did not reach the "
                           "tolerance with photons to spare, or nothing reflects; this is shooting's answer), ");
  std::fprintf(out,
               "method    %s%s basis (%s), %s, %s positions, discontinuities %s, "
               "%s, %s sampler\n",
               walks_text.c_str(), to_string(settings.basis), to_string(settings.estimator), storage_text,
               to_string(settings.sampling), to_string(settings.discontinuities), rays, to_string(settings.sampler));
  // What the scene made the solver use (and so what it left out).
  std::fprintf(
      out,
      "features  %s (%d channel%s), %s, %zu discontinuity nodes (%zu at the scene's corners and joints, %zu "
      "at contacts, %zu at visibility events%s), %zu storage coefficients\n",
      scene.channels == 1 ? "grey" : "colour", scene.channels, scene.channels == 1 ? "" : "s",
      cubic_segments == 0                       ? "lines only (no cubic solver)"
      : cubic_segments == scene.segments.size() ? "cubics only"
                                                : "lines and cubics",
      solver.discontinuity_nodes(), solver.node_sources().scene, solver.node_sources().contacts,
      solver.node_sources().events,
      solver.node_sources().variate > 0
          ? (", " + std::to_string(solver.node_sources().variate) + " at the coarse variate's element ends").c_str()
          : "",
      solver.coefficient_count());
  if (scene.has_specular()) {
    std::size_t count[4] = {};
    for (const Curve& curve : scene.curves) ++count[static_cast<std::size_t>(scene.material_of(curve).optics)];
    std::fprintf(out, "optics    %zu mirror, %zu dielectric and %zu detector curves (chains of up to %u events)\n",
                 count[static_cast<std::size_t>(Optics::Mirror)], count[static_cast<std::size_t>(Optics::Dielectric)],
                 count[static_cast<std::size_t>(Optics::Detector)], kChainLimit);
  }
  if (!settings.importance.empty())
    std::fprintf(out,
                 "importance %s: sources drawn by power times sqrt(importance), from an adjoint solve of %s photons "
                 "(%.3f s); the least weight is 1/%.0f of the most\n",
                 solve_option_text(settings, SolveOption::Importance).c_str(),
                 human_count(static_cast<double>(solver.importance_photons())).c_str(), solver.importance_seconds(),
                 1.0 / kImportanceFloor);
  if (settings.control_variate == ControlVariate::Coarse)
    std::fprintf(out,
                 "variate   a coarse reference's answer (%zu elements, %.3f s with its projections) is carried "
                 "without photons; they shoot the signed difference it leaves, %.3g%% of the emitted power\n",
                 solver.control_variate_elements(), solver.control_variate_seconds(),
                 100.0 * solver.control_variate_source_fraction());
  else if (!solver.control_variate_skipped().empty())
    std::fprintf(out, "variate   no: %s (--control-variate auto)\n", solver.control_variate_skipped().c_str());
  const bool walks = settings.transport == Transport::Walk;
  char workers[64];
  if (process_count() > 1)
    std::snprintf(workers, sizeof workers, "%u processes x %u threads", process_count(), solver.thread_count());
  else
    std::snprintf(workers, sizeof workers, "%u threads", solver.thread_count());
  std::fprintf(out, "solved    %s %s (%s rays) in %u rounds, %.3f s, %s %s/s on %s\n",
               human_count(static_cast<double>(solver.photons_shot())).c_str(), walks ? "walks" : "photons",
               human_count(static_cast<double>(solver.rays_traced())).c_str(), solver.rounds(), solver.seconds(),
               human_count(rate).c_str(), walks ? "walks" : "photons", workers);
  if (walks)
    std::fprintf(out, "stopped   %s (walks end by themselves: nothing is left unshot)\n",
                 to_string(solver.stop_reason()));
  else if (solver.jacobi_iterations() > 0)
    std::fprintf(out, "stopped   %s: the books' unshot power, the average's residual, %.3g%% of emitted\n",
                 to_string(solver.stop_reason()), 100.0 * books.unshot / books.emitted);
  else if (settings.control_variate == ControlVariate::Coarse)
    std::fprintf(out,
                 "stopped   %s: unshot power %.3g%% of emitted, its magnitude %.3g%% (tolerance %.3g%% of the "
                 "difference's %.3g%%)\n",
                 to_string(solver.stop_reason()), 100.0 * books.unshot / books.emitted,
                 100.0 * solver.pool_magnitude() / books.emitted, 100.0 * solver.settings().tolerance,
                 100.0 * solver.control_variate_source_fraction());
  else
    std::fprintf(out, "stopped   %s: unshot power %.3g%% of emitted (tolerance %.3g%%)\n",
                 to_string(solver.stop_reason()), 100.0 * books.unshot / books.emitted,
                 100.0 * solver.settings().tolerance);
  if (const RoundSharing* sharing = solver.round_sharing(); sharing != nullptr && solver.rounds() > 0)
    std::fprintf(out, "shared    %u processes summed %s bytes per round (%s in all, %u rounds)\n", sharing->size(),
                 human_count(static_cast<double>(solver.bytes_shared()) / solver.rounds()).c_str(),
                 human_count(static_cast<double>(solver.bytes_shared())).c_str(), solver.rounds());
  if (solver.scene().has_specular()) {
    std::fprintf(out,
                 "energy    emitted %.6g = absorbed %.6g + escaped %.6g + unshot %.6g + by mirrors %.6g + in glass "
                 "%.6g + cut %.6g (imbalance %.2g)\n",
                 books.emitted, books.absorbed, books.escaped, books.unshot, books.absorbed_mirrors,
                 books.absorbed_glass, books.cut, books.imbalance());
    if (solver.chains_cut() > 0)
      std::fprintf(out, "chains    %s photons cut after %u specular events (power %.3g%% of emitted)\n",
                   human_count(static_cast<double>(solver.chains_cut())).c_str(), kChainLimit,
                   100.0 * books.cut / books.emitted);
  } else {
    std::fprintf(out, "energy    emitted %.6g = absorbed %.6g + escaped %.6g + unshot %.6g (imbalance %.2g)\n",
                 books.emitted, books.absorbed, books.escaped, books.unshot, books.imbalance());
  }
  // Each detector's totals, channels summed: the power that crossed it each way.
  for (const DetectorReading& reading : solver.detector_readings()) {
    const double front = reading.front_total[0] + reading.front_total[1] + reading.front_total[2];
    const double back = reading.back_total[0] + reading.back_total[1] + reading.back_total[2];
    std::fprintf(out,
                 "detector  %s: %.6g crossed from its front, %.6g from its back (%.3g%% and %.3g%% of emitted; light "
                 "that crosses it more than once counts each time)\n",
                 scene.curves[reading.curve].id.c_str(), front, back, 100.0 * front / books.emitted,
                 100.0 * back / books.emitted);
  }
  print_estimated_error(out, estimate, solver.settings());
  if (const double target = solver.settings().target_error; target > 0.0) {
    if (solver.stop_reason() == StopReason::TargetReached)
      std::fprintf(out, "target    %.3g %% reached (estimated %.3g %% when checked%s)\n", 100.0 * target,
                   100.0 * solver.checked_error(),
                   solver.passes() > 0 ? (", after " + std::to_string(solver.passes()) + " passes").c_str() : "");
    else
      std::fprintf(out, "target    %.3g %% not reached: %s first (give a larger --photons cap)\n", 100.0 * target,
                   to_string(solver.stop_reason()));
  }
}

}  // namespace

std::optional<int> abnormal_stop(const Solver& solver) {
  // Every process of a shared solve stops alike; rank 0 says why.
  if (!speaks_for_the_run()) {
    if (solver.stop_reason() == StopReason::Cancelled) return kExitInterrupted;
    if (solver.stop_reason() == StopReason::BooksUnbalanced) return kExitFailure;
    return std::nullopt;
  }
  if (solver.stop_reason() == StopReason::Cancelled) {
    std::fprintf(stderr, "flatland: interrupted after %s photons; nothing written\n",
                 human_count(static_cast<double>(solver.photons_traced())).c_str());
    return kExitInterrupted;
  }
  if (solver.stop_reason() == StopReason::BooksUnbalanced) {
    std::fprintf(stderr, "flatland: internal error: %s\n", solver.books_error().c_str());
    return kExitFailure;
  }
  return std::nullopt;
}

Status finish_solver_settings(SolveOptions& o) {
  for (const SolveOptionSpec& spec : solve_options())
    if (Status status = set_solve_option(o.settings, spec.option, o.text[spec.option]); !status)
      return Error{spelled(status.error().message, Spelling::CommandLine)};
  if (Status status = validate(o.settings); !status)
    return Error{spelled(status.error().message, Spelling::CommandLine)};
  return ok_status();
}

int run_solve(SolveOptions& o) {
  std::optional<Scene> scene;
  std::optional<nlohmann::json> reference;
  std::optional<Solver> solver_slot;
  std::unique_ptr<FinalGather> gather;
  std::string gather_skipped;  // why --gather auto gathers nothing
  // Under mpirun every process loads the scene and sets up the same solver; rank 0 alone checks
  // and writes the outputs. All agree to go on before the set-up and after it (processes.hpp).
  auto prepare = [&]() -> std::optional<int> {
    if (Status status = finish_solver_settings(o); !status) return usage_error(status.error().message);
    Result<Scene> loaded = load_scene(o.scene, &interrupt_flag());
    if (!loaded) return input_error(loaded.error());
    scene = std::move(*loaded);
    // Everything the solve's end needs is checked before it starts: the output paths, the size of
    // the result, and the reference (read now, so a bad one costs no solve).
    if (speaks_for_the_run()) {
      if (const std::optional<int> code =
              check_outputs({{"--out", o.out}, {"--picture", o.picture}, {"--detectors", o.detectors}},
                            {{"scene file", o.scene}, {"--reference", o.reference}}))
        return *code;
      if (!o.detectors.empty() && detector_layout(*scene).size == 0)
        return usage_error("--detectors: " + o.scene +
                           " has no detector curves; give a curve a material of type \"detector\" "
                           "(docs/scene-format.md)");
      if (!o.out.empty() || !o.reference.empty())
        if (Status status = check_result_size(*scene, o.samples); !status) return usage_error(status.error().message);
      if (!o.reference.empty()) {
        Result<nlohmann::json> read = read_result_file(o.reference, &interrupt_flag());
        if (!read) return input_error(read.error(), "--reference: ");
        // Of this scene file, sampled as the result will be: said now, not after the solve.
        Result<SampledResult> given = sampled_from_json(*read, "the reference");
        if (!given) return usage_error("--reference " + o.reference + ": " + given.error().message);
        if (Status status = check_reference_of(*given, *scene, o.samples); !status)
          return usage_error("--reference " + o.reference + ": " + status.error().message);
        reference = std::move(*read);
      }
    }
    return std::nullopt;
  };
  if (const std::optional<int> code = agree(prepare())) return *code;
  if (const std::optional<int> code = agree_on_digest("scene file", o.scene, scene->source_sha256)) return *code;
  // Set-up can take a while (storage for a large budget): only once every process may go on.
  auto create = [&]() -> std::optional<int> {
    // The gather's elements are made (and the scene checked for it) before any photon is shot.
    Result<GatherChoice> choice = choose_gather(*scene, o.settings, o.samples, &interrupt_flag());
    if (!choice)
      return interrupt_flag().load() ? interrupted() : usage_error("--gather samples: " + choice.error().message);
    gather = std::move(choice->gather);
    gather_skipped = choice->skipped;
    Result<Solver> created = create_solver(*scene, o.settings, &interrupt_flag());
    if (!created) return interrupt_flag().load() ? interrupted() : usage_error(created.error().message);
    solver_slot.emplace(std::move(*created));
    return std::nullopt;
  };
  if (const std::optional<int> code = agree(create())) return *code;
  Solver& solver = *solver_slot;
  solver.share_rounds(shared_processes());
  if (gather) solver.check_target_through(gather.get());

  {
    ProgressLine line(!o.quiet && speaks_for_the_run());
    solver.run(&interrupt_flag(), [&](const SolverProgress& p) { line.update(p); });
  }
  if (const std::optional<int> code = abnormal_stop(solver)) return *code;
  // The other processes have the same solution; rank 0 reports and writes it.
  if (!speaks_for_the_run()) return kExitOk;
  if (!o.quiet && !solver.thread_shortfall().empty())
    note(solver.thread_shortfall() + "; the results are the same bits on any thread count");
  // With a gather, the result and its estimated error are the gathered ones.
  std::optional<SampledResult> gathered;
  if (gather) {
    gathered = gather->gather_result(solver, o.samples);
    if (gather->cancelled()) return interrupted();
  }
  const ErrorEstimate estimate =
      gathered ? *gathered->stats->estimated_error : estimate_error(solver, {solver.settings().confidence, o.samples});
  if (!o.quiet) {
    print_summary(solver, estimate);
    if (!gather_skipped.empty())
      std::fprintf(report_stream(), "gathered  no: %s (--gather auto)\n", gather_skipped.c_str());
    if (gather)
      std::fprintf(report_stream(),
                   "gathered  B at %d samples per curve: one bounce over %zu elements (h = %.3g), %.3f s\n", o.samples,
                   gather->elements(), gather->max_element_length(), gather->sweep_seconds());
  }

  OutputFiles files(&interrupt_flag());
  if (reference) {
    const nlohmann::json document =
        gathered ? result_to_json(solver, o.samples, *gathered) : result_to_json(solver, o.samples, &estimate);
    Result<Comparison> comparison = compare_results(document, *reference);
    if (!comparison) return usage_error("--reference " + o.reference + ": " + comparison.error().message);
    if (!o.quiet) print_comparison(*comparison, true, &document);
    if (!o.out.empty())
      if (Status status = files.stage(o.out, json_text(document)); !status) return usage_error(status.error().message);
  } else if (!o.out.empty()) {
    // The same text, without holding the whole document as a JSON tree (result_io.hpp).
    if (Status status = files.stage(
            o.out, gathered ? result_text(solver, o.samples, *gathered) : result_text(solver, o.samples, &estimate));
        !status)
      return usage_error(status.error().message);
  }
  if (!o.picture.empty()) {
    Result<std::string> png = encode_png(draw_picture(solver));
    if (!png) return usage_error(o.picture + ": " + png.error().message);
    if (Status status = files.stage(o.picture, *png); !status) return usage_error(status.error().message);
  }
  if (!o.detectors.empty())
    if (Status status = files.stage(o.detectors, detectors_csv(solver)); !status)
      return usage_error(status.error().message);
  if (const std::optional<int> code = commit_outputs(files)) return *code;
  if (!o.quiet) {
    if (!o.out.empty()) std::fprintf(report_stream(), "wrote     %s\n", o.out.c_str());
    if (!o.picture.empty()) std::fprintf(report_stream(), "wrote     %s\n", o.picture.c_str());
    if (!o.detectors.empty()) std::fprintf(report_stream(), "wrote     %s\n", o.detectors.c_str());
  }
  return kExitOk;
}

}  // namespace flatland::app
