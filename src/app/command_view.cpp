// flatland view: the interactive viewer (src/viewer), and its headless mode for tests and figures.
#include <cstdio>

#include "app/commands.hpp"
#include "app/output.hpp"
#include "viewer/viewer_app.hpp"

namespace flatland::app {

CLI::App* add_view_command(CLI::App& parent, ViewCommandOptions& o) {
  CLI::App* cmd = parent.add_subcommand(
      "view",
      "Open the interactive viewer: photon paths and the reconstructed illumination drawn live as the "
      "solve runs (docs/viewer.md; press F1 in the window for the keyboard shortcuts).");
  cmd->add_option("scene", o.solve.scene, "Scene file (JSON); the default scene when omitted");
  // The viewer's own defaults (viewer_app.hpp: no control variate), shown as such by --help.
  o.solve.settings = viewer::view_default_settings();
  for (const SolveOptionSpec& spec : solve_options())
    o.solve.text[spec.option] = solve_option_text(o.solve.settings, spec.option);
  add_solver_options(cmd, o.solve);
  cmd->add_option("--reference", o.reference,
                  "A reference result of the same scene (flatland reference --out): show the error "
                  "so far and the reference's B(s)");
  cmd->add_option("--width", o.width, "Window width in pixels")->capture_default_str()->check(CLI::Range(64, 16384));
  cmd->add_option("--height", o.height, "Window height in pixels")->capture_default_str()->check(CLI::Range(64, 16384));
  cmd->add_option("--frames", o.frames,
                  "Draw this many frames, then write the screenshots and exit (0: until the window is "
                  "closed)")
      ->capture_default_str()
      ->check(CLI::Range(0, 100000000));
  cmd->add_option("--step", o.step,
                  "What each frame does: live (the solve runs freely), or photons=N, batches=N, "
                  "rounds=N (shot before the frame is drawn, so a headless run is deterministic)")
      ->capture_default_str();
  cmd->add_flag("--paused", o.paused, "Start paused (Space runs)");
  cmd->add_option("--screenshot", o.screenshot,
                  "After the last frame, write the scene view (no panels) to this PNG file")
      ->check(output_path());
  cmd->add_option("--screenshot-ui", o.screenshot_ui,
                  "After the last frame, write the whole window, panels included, to this PNG file")
      ->check(output_path());
  cmd->add_option("--keep-paths", o.keep_paths, "Photon paths kept on screen")
      ->capture_default_str()
      ->check(CLI::Range(0, 10000000));
  cmd->add_option("--paths-per-frame", o.paths_per_frame,
                  "New photon paths drawn per frame at most, newest first (lower it if frames are slow)")
      ->capture_default_str()
      ->check(CLI::Range(1, 10000000));
  cmd->add_flag("--control-points", o.control_points, "Show control points (drag them to edit the scene)");
  cmd->add_option("--select", o.select, "Inspect this curve from the start (its id or index)");
  cmd->add_option("--colour-by", o.colour_by,
                  "Colour photon paths by their power (and light colour), by round, or by bounce "
                  "(reflections before the flight: a walk's hops, shooting's rounds)")
      ->capture_default_str()
      ->check(CLI::IsMember({"power", "round", "bounce"}));
  cmd->add_option("--light", o.light,
                  "How the light is drawn: paths, each flight a line (every kept path, fading by age); field, the "
                  "light of the whole solve as a field (the flights' power per unit length per unit area, every "
                  "recorded flight standing for its share of the photons, tone mapped so that beams, caustics "
                  "and reflections stand out of the interreflected haze); auto, the field once at least 4096 "
                  "paths are kept and the paths are coloured by power, else the paths")
      ->capture_default_str()
      ->check(CLI::IsMember({"auto", "paths", "field"}));
  cmd->add_option("--fade", o.fade,
                  "Fading of the photon paths by age: 0 keeps every kept path equally bright, 1 fades "
                  "the oldest to about 5 %")
      ->capture_default_str()
      ->check(finite_range(0.0, 1.0));
  cmd->add_option("--exposure", o.exposure, "Exposure of the photon paths")
      ->capture_default_str()
      ->check(finite_range(1e-3, 1e3));
  cmd->add_flag("--no-ui", o.no_ui, "Hide the panels");
  cmd->add_flag("--present", o.present,
                "Start in presentation mode (M): no panels; the photon counter above the stage, the inspected "
                "curve's B(s) beside it and the colour key under it, none on it");
  cmd->add_flag("--first-photons", o.first_photons,
                "Start with the First photons lecture preset (key 1): random walks shot one at a time, a new "
                "one every 0.8 s, coloured by bounce, the newest journey on top (Space runs on, '.' steps)");
  cmd->add_option("--ui-scale", o.ui_scale,
                  "Size of the panels' text and widgets, and of their columns (1.5-2 for a projector)")
      ->capture_default_str()
      ->check(finite_range(0.5, 4.0));
  cmd->add_flag("--no-vsync", o.no_vsync, "Do not wait for the display's refresh (to measure frame rates)");
  cmd->add_option("--max-fps", o.max_fps,
                  "Frames per second at most (0: 40 with software OpenGL, which draws on the solver's "
                  "cores, otherwise no limit; -1: no limit)")
      ->capture_default_str()
      ->check(CLI::Range(-1, 1000));
  cmd->add_flag("--report", o.report,
                "At the end, print the frame rate, the photon rate and the view's link (the web page's URL "
                "parameters for it, as Copy link gives them)");
  cmd->add_option("--shaders", o.shaders,
                  "Load the GLSL shaders from this directory instead of the built-in copies of shaders/");
  return cmd;
}

std::optional<int> make_view_options(ViewCommandOptions& o, viewer::ViewOptions& options) {
  // The budget of an interactive solve defaults higher than solve's: it runs until paused.
  if (Status status = finish_solver_settings(o.solve); !status) {
    std::fprintf(stderr, "flatland: error: %s\n", status.error().message.c_str());
    return kExitUsage;
  }
  if (Result<viewer::FrameStep> step = viewer::parse_frame_step(o.step); !step) {
    std::fprintf(stderr, "flatland: error: %s\n", step.error().message.c_str());
    return kExitUsage;
  }
  if ((!o.screenshot.empty() || !o.screenshot_ui.empty()) && o.frames == 0) {
    std::fprintf(stderr, "flatland: error: --screenshot needs --frames N (the frame after which to take it)\n");
    return kExitUsage;
  }
  // The pictures are written after the last frame: their paths are checked before the first.
  if (const std::optional<int> code =
          check_outputs({{"--screenshot", o.screenshot}, {"--screenshot-ui", o.screenshot_ui}},
                        {{"scene file", o.solve.scene}, {"--reference", o.reference}}))
    return *code;
  options.scene = o.solve.scene;
  options.reference = o.reference;
  options.settings = o.solve.settings;
  options.width = o.width;
  options.height = o.height;
  options.frames = o.frames;
  options.step = o.step;
  options.paused = o.paused;
  options.screenshot = o.screenshot;
  options.screenshot_ui = o.screenshot_ui;
  options.shader_directory = o.shaders;
  options.keep_paths = static_cast<std::size_t>(o.keep_paths);
  options.path_budget = static_cast<std::size_t>(o.paths_per_frame);
  options.show_control_points = o.control_points;
  options.select = o.select;
  options.colour_by = o.colour_by;
  options.light = o.light;
  options.path_exposure = o.exposure;
  options.path_fade = o.fade;
  options.show_ui = !o.no_ui;
  options.present = o.present;
  options.first_photons = o.first_photons;
  options.ui_scale = o.ui_scale;
  options.vsync = !o.no_vsync;
  options.max_fps = o.max_fps;
  options.report = o.report;
  options.cancel = &interrupt_flag();
  return std::nullopt;
}

int run_view(ViewCommandOptions& o) {
  viewer::ViewOptions options;
  if (const std::optional<int> code = make_view_options(o, options)) return *code;
  Result<std::unique_ptr<viewer::Viewer>> viewer = viewer::Viewer::create(options);
  if (!viewer) return input_error(viewer.error());
  if (Status status = (*viewer)->run(); !status) {
    std::fprintf(stderr, "flatland: error: %s\n", status.error().message.c_str());
    return kExitUsage;
  }
  return kExitOk;
}

}  // namespace flatland::app
