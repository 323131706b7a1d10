// flatland render: solve, then draw the viewer's picture offscreen (EGL, no display needed) with
// the viewer's own shaders.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>

#include "app/commands.hpp"
#include "app/output.hpp"
#include "app/progress.hpp"
#include "flatland/base/resources.hpp"
#include "flatland/base/version.hpp"
#include "flatland/reference/coarse_answer.hpp"
#include "flatland/reference/final_gather.hpp"
#include "flatland/results/result_io.hpp"
#include "flatland/transport/options.hpp"
#include "png/png_io.hpp"
#include "viewer/offscreen.hpp"
#include "viewer/picture_labels.hpp"
#include "viewer/renderer.hpp"
#include "viewer/session.hpp"
#include "viewer/viewer_app.hpp"

namespace flatland::app {

CLI::App* add_render_command(CLI::App& parent, RenderOptions& o) {
  CLI::App* cmd = parent.add_subcommand(
      "render",
      "Solve a scene and render the viewer's picture to a PNG file offscreen (no display needed): the "
      "light as a field (the fluence of the photons' flights, tone mapped; or the photon paths, each in its "
      "light's colour and brightness: --light); along every lit side of a curve a band "
      "coloured by its radiosity B and a graph of B (a thin line offset along the normal, higher where B "
      "is larger); mirrors steel blue, glass cyan, detectors green. docs/viewer.md says more.");
  cmd->add_option("scene", o.solve.scene, "Scene file (JSON, docs/scene-format.md)")->required();
  // The viewer's defaults (viewer_app.hpp: no control variate): the picture is of the photons'
  // flights, which with the variate would be a signed correction, not the light.
  o.solve.settings = viewer::view_default_settings();
  for (const SolveOptionSpec& spec : solve_options())
    o.solve.text[spec.option] = solve_option_text(o.solve.settings, spec.option);
  add_solver_options(cmd, o.solve);
  cmd->add_option("--out", o.out, "The picture (PNG)")->required()->check(output_path());
  cmd->add_option("--result", o.result, "Also write the result as JSON (as solve --out)")->check(output_path());
  cmd->add_option("--samples", o.solve.samples, "Radiosity samples per curve in the --result file")
      ->capture_default_str()
      ->check(CLI::Range(1, 1000000));
  cmd->add_option("--width", o.width, "Picture width in pixels")->capture_default_str()->check(CLI::Range(16, 16384));
  cmd->add_option("--height", o.height, "Picture height in pixels")
      ->capture_default_str()
      ->check(CLI::Range(16, 16384));
  cmd->add_option("--paths", o.paths,
                  "Photon paths drawn, spread over the rounds in proportion to their photons (0: none)")
      ->capture_default_str()
      ->check(CLI::Range(0, 10000000));
  cmd->add_option("--light", o.light,
                  "How the light is drawn: paths, each flight a line (every kept path, fading by age); field, the "
                  "light of the whole solve as a field (the flights' power per unit length per unit area, every "
                  "recorded flight standing for its share of the photons, tone mapped so that beams, caustics "
                  "and reflections stand out of the interreflected haze); auto, the field once at least 4096 "
                  "paths are drawn (--paths), else the paths")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "paths", "field"}));
  cmd->add_option("--field-flights", o.field_flights,
                  "Flights recorded for the light field, spread over the rounds as --paths is (more: a smoother "
                  "field, for a little more time; 0: no field, the paths are drawn)")
      ->capture_default_str()
      ->check(CLI::Range(0, 100000000));
  cmd->add_option("--exposure", o.exposure, "Exposure of the photon paths")
      ->capture_default_str()
      ->check(finite_range(1e-3, 1e3));
  cmd->add_flag("--graph,!--no-graph", o.graph,
                "Draw B(s) as a graph along each curve's normal (on unless --no-graph)");
  cmd->add_flag("--band,!--no-band", o.band, "Draw the colour band of B along each curve (on unless --no-band)");
  cmd->add_flag("--labels,!--no-labels", o.labels,
                "Write a title above the scene (what is drawn, how it was solved) and the colour key with the "
                "materials' legend below it (on unless --no-labels; pictures under 320x240 have none)");
  cmd->add_flag("--journey", o.journey,
                "Also draw the newest photon's journey on top (its hops numbered and coloured by bounce), as "
                "the viewer does");
  cmd->add_flag("--nodes", o.nodes,
                "Also mark the storage's nodes below C1 as diamonds (C-1 red, C0 green), as the viewer does");
  cmd->add_option("--shaders", o.shaders,
                  "Load the GLSL shaders from this directory instead of the built-in copies of shaders/");
  cmd->add_flag("--quiet", o.solve.quiet, "No progress line and no summary (errors only)");
  return cmd;
}

int run_render(RenderOptions& o) {
  if (Status status = finish_solver_settings(o.solve); !status) {
    std::fprintf(stderr, "flatland: error: %s\n", status.error().message.c_str());
    return kExitUsage;
  }
  Result<Scene> loaded = load_scene(o.solve.scene, &interrupt_flag());
  if (!loaded) return input_error(loaded.error());
  auto scene = std::make_shared<const Scene>(std::move(*loaded));
  if (const std::optional<int> code =
          check_outputs({{"--out", o.out}, {"--result", o.result}}, {{"scene file", o.solve.scene}}))
    return *code;
  if (!o.result.empty())
    if (Status status = check_result_size(*scene, o.solve.samples); !status) return usage_error(status.error().message);
  // Drawing holds every curve's trace and overlay at once: refused now if it cannot fit (the solve
  // checks its own storage against the same budget).
  const int field_resolution = std::clamp(std::max(o.width, o.height) / 2, 16, 2048);
  // The field's grid and image, and one round's record of flights (a PhotonPath each).
  const double field_bytes =
      o.field_flights > 0 ? 40.0 * field_resolution * field_resolution + 160.0 * o.field_flights : 0.0;
  const double drawing = viewer::render_memory_bound(*scene, static_cast<std::size_t>(o.paths)) + field_bytes;
  if (const double budget = static_cast<double>(default_memory_budget()); drawing > budget)
    return usage_error(o.solve.scene + ": drawing its " + std::to_string(scene->curves.size()) + " curves and " +
                       std::to_string(o.paths) + " paths would take about " + format_bytes(drawing) +
                       ", more than the " + format_bytes(budget) +
                       " this process may give it; draw a smaller scene or fewer --paths, or use flatland solve "
                       "--out for the result alone");
  // GL before the solve: a machine that cannot render says so at once.
  Result<std::unique_ptr<viewer::OffscreenContext>> context = viewer::OffscreenContext::create(o.width, o.height);
  if (!context) {
    std::fprintf(stderr, "flatland: error: %s\n", context.error().message.c_str());
    return kExitUsage;
  }
  Result<std::unique_ptr<viewer::Renderer>> renderer = viewer::Renderer::create(o.shaders);
  if (!renderer) {
    std::fprintf(stderr, "flatland: error: %s\n", renderer.error().message.c_str());
    return kExitUsage;
  }
  // The --result file's samples are gathered as solve's are (the picture is the storage's B).
  Result<GatherChoice> choice = choose_gather(*scene, o.solve.settings, o.solve.samples, &interrupt_flag());
  if (!choice) {
    if (interrupt_flag().load()) return interrupted();
    std::fprintf(stderr, "flatland: error: --gather samples: %s\n", choice.error().message.c_str());
    return kExitUsage;
  }
  Result<Solver> created = create_solver(*scene, o.solve.settings, &interrupt_flag());
  if (!created) {
    if (interrupt_flag().load()) return interrupted();
    std::fprintf(stderr, "flatland: error: %s\n", created.error().message.c_str());
    return kExitUsage;
  }
  Solver& solver = *created;
  if (choice->gather) solver.check_target_through(choice->gather.get());

  // Paths from every round, in proportion to its photons.
  std::vector<PhotonPath> paths;
  std::vector<std::uint32_t> rounds;
  // The light field of the recorded flights, each round's standing for all its photons.
  // (A cell on about two pixels: bilinear filtering between cell centres smooths the rest.)
  Result<LightField> field = LightField::for_scene(*scene, field_resolution);
  if (!field) return usage_error(field.error().message);
  const std::size_t recorded = static_cast<std::size_t>(std::max(o.paths, o.field_flights));
  std::vector<PhotonPath> round_paths;
  std::size_t field_flights = 0;
  {
    ProgressLine line(!o.solve.quiet);
    const auto report = [&](const SolverProgress& p) { line.update(p); };
    while (!solver.stopped()) {
      const std::uint32_t round = solver.rounds();
      const std::uint64_t shot_before = solver.photons_shot();
      round_paths.clear();
      if (solver.step_photons(1, &interrupt_flag(), &round_paths, recorded > 0 ? 1 : 0) == 0) break;
      const double share = static_cast<double>(solver.round_photons()) / static_cast<double>(o.solve.settings.photons);
      const auto wanted = static_cast<std::size_t>(std::ceil(o.paths * share));
      const auto field_wanted = static_cast<std::size_t>(std::ceil(o.field_flights * share));
      if (solver.round_open())
        solver.step_photons(solver.round_photons() - solver.round_photons_done(), &interrupt_flag(), &round_paths,
                            std::max(wanted, field_wanted), report);
      if (o.field_flights > 0)
        field->add_record(round_paths, solver.photons_shot() - shot_before, solver.settings().transport);
      field_flights += round_paths.size();
      truncate_record(round_paths, wanted, solver.settings().transport);
      paths.insert(paths.end(), std::make_move_iterator(round_paths.begin()),
                   std::make_move_iterator(round_paths.end()));
      rounds.resize(paths.size(), round);
    }
  }
  if (const std::optional<int> code = abnormal_stop(solver)) return *code;
  if (!o.solve.quiet && !solver.thread_shortfall().empty())
    note(solver.thread_shortfall() + "; the results are the same bits on any thread count");

  viewer::Snapshot snapshot;
  snapshot.scene = scene;
  auto traces = std::make_shared<const std::vector<viewer::CurveTrace>>(viewer::trace_curves(*scene));
  snapshot.traces = traces;
  viewer::describe_solver(solver, *traces, snapshot);
  std::uint64_t serial = 0;
  for (std::size_t i = 0; i < paths.size(); ++i)
    viewer::append_path_records(paths[i], *scene, serial, rounds[i], snapshot.paths);
  if (o.field_flights > 0) snapshot.field = viewer::field_image(*field);
  viewer::DrawOptions draw;
  draw.light = o.light == "paths"   ? viewer::LightView::Paths
               : o.light == "field" ? viewer::LightView::Field
                                    : viewer::LightView::Auto;
  draw.graph = o.graph;
  draw.band = o.band;
  draw.journey = o.journey;
  draw.discontinuities = o.nodes;
  draw.fade = 0.0f;  // no ages in a finished solve
  // The scene on the stage between the title and the key (the whole picture with --no-labels).
  const viewer::PictureLayout layout = viewer::picture_layout(o.width, o.height, o.labels);
  const viewer::ViewTransform view = viewer::fit_view(scene->bounds, o.width, o.height, layout.stage);
  viewer::PathLayer layer;
  const viewer::PathDraw path_draw = layer.update(snapshot, draw, view, snapshot.paths.size(), snapshot.paths.size());
  if (Status drawn =
          (*renderer)->draw(viewer::build_overlay(snapshot, draw), path_draw, view, o.exposure, &layout.stage);
      !drawn) {
    std::fprintf(stderr, "flatland: error: %s\n", drawn.error().message.c_str());
    return kExitUsage;
  }
  const bool field_shown = viewer::shows_field(snapshot, draw);
  const SolverSettings& used = solver.settings();
  char what[512];
  std::snprintf(
      what, sizeof what, "%s%s%s",
      field_shown ? "the light as a field (fluence, tone mapped at its 99th percentile)"
                  : "photon paths, each in its light's colour and brightness",
      o.band ? "; along every lit side a band of B" : "",
      o.graph ? (o.band ? " and its graph (the thin line off the side)" : "; B's graph off every lit side") : "");
  // The commit shortened to 12 digits, keeping its "-dirty" mark (uncommitted changes).
  const std::string commit = program_commit();
  const bool dirty = commit.size() > 6 && commit.compare(commit.size() - 6, 6, "-dirty") == 0;
  const std::string short_commit = commit.substr(0, 12) + (dirty ? "-dirty" : "");
  std::string transport = used.transport == Transport::Walk     ? "random walks"
                          : used.transport == Transport::Jacobi ? "averaged Jacobi iterations"
                                                                : "shooting";
  if (used.transport == Transport::Walk && used.walk_score != WalkScore::Collision)
    transport += std::string(", ") + to_string(used.walk_score) + " score";
  if (!used.importance.empty()) transport += ", importance " + solve_option_text(used, SolveOption::Importance);
  char how[512];
  std::snprintf(how, sizeof how, "%llu %s, %u rounds, %s basis, %s, seed %llu; flatland %s (%s)",
                static_cast<unsigned long long>(solver.photons_shot()),
                used.transport == Transport::Walk ? "walks" : "photons", solver.rounds(), to_string(used.basis),
                transport.c_str(), static_cast<unsigned long long>(used.seed), program_version(), short_commit.c_str());
  const std::vector<std::string> title = {scene->name + ": " + what, how};
  if (Status labelled = viewer::draw_picture_labels(snapshot, draw, layout, o.width, o.height, title); !labelled) {
    std::fprintf(stderr, "flatland: error: %s\n", labelled.error().message.c_str());
    return kExitUsage;
  }
  png::PngImage image{o.width, o.height, 4, viewer::Renderer::read_pixels(o.width, o.height)};
  for (std::size_t i = 3; i < image.pixels.size(); i += 4) image.pixels[i] = 255;

  OutputFiles files(&interrupt_flag());
  if (!o.result.empty())
    if (Status status = files.stage(
            o.result, choice->gather
                          ? result_text(solver, o.solve.samples, choice->gather->gather_result(solver, o.solve.samples))
                          : result_text(solver, o.solve.samples));
        !status)
      return usage_error(status.error().message);
  Result<std::string> png = png::encode_png(image);
  if (!png) return usage_error(o.out + ": " + png.error().message);
  if (Status status = files.stage(o.out, *png); !status) return usage_error(status.error().message);
  if (const std::optional<int> code = commit_outputs(files)) return *code;
  if (!o.solve.quiet) {
    std::FILE* out = report_stream();
    if (!o.result.empty()) std::fprintf(out, "wrote     %s\n", o.result.c_str());
    std::fprintf(out, "solved    %llu %s (%llu rays) in %u rounds, %.3f s\n",
                 static_cast<unsigned long long>(solver.photons_shot()),
                 solver.settings().transport == Transport::Walk ? "walks" : "photons",
                 static_cast<unsigned long long>(solver.rays_traced()), solver.rounds(), solver.seconds());
    if (field_shown)
      std::fprintf(out, "wrote     %s (%dx%d, the light as a field of %zu recorded flights)\n", o.out.c_str(), o.width,
                   o.height, field_flights);
    else
      std::fprintf(out, "wrote     %s (%dx%d, %zu paths)\n", o.out.c_str(), o.width, o.height, paths.size());
  }
  return kExitOk;
}

}  // namespace flatland::app
