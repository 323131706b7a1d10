// The web page's program (docs/web.md): the page (index.html) turns its URL into a command line and
// runs it once through callMain. `view ...` opens the viewer on the page's canvas and returns; the
// browser then calls frame() at its display rate (the solve runs inside the frames: the page has
// one thread). `solve ... --out FILE` is the testing hook's solve, exactly the desktop command. The
// page reaches the running viewer through the flatland_* functions below.
#include <emscripten.h>

#include <cstdio>
#include <memory>
#include <string>

#include "app/cli.hpp"
#include "app/commands.hpp"
#include "app/output.hpp"
#include "flatland/transport/options.hpp"
#include "viewer/viewer_app.hpp"

namespace {

using namespace flatland;

std::unique_ptr<viewer::Viewer> the_viewer;

void frame(void*) { the_viewer->frame(); }

}  // namespace

extern "C" {

// Opens a scene file that the page has written (a file picked, dropped or edited) into the
// page's in-memory files: "" when it loaded, else the one-line error (the scene stays as it was).
EMSCRIPTEN_KEEPALIVE const char* flatland_open_scene(const char* path) {
  static std::string error;
  error.clear();
  if (!the_viewer) return "the viewer is not running";
  if (Status status = the_viewer->open_scene(path); !status) error = status.error().message;
  return error.c_str();
}

// The scene file the viewer shows (it may have been chosen in its File menu).
EMSCRIPTEN_KEEPALIVE const char* flatland_scene_path() { return the_viewer ? the_viewer->scene_path().c_str() : ""; }

// The canvas's new size in pixels (the page follows the browser window).
EMSCRIPTEN_KEEPALIVE void flatland_resize(int width, int height) {
  if (the_viewer) the_viewer->resize_window(width, height);
}

// The viewer's state as URL parameters (Copy link): every solve option that differs from its
// default, the inspected curve, presentation mode, the First photons preset, and the paths'
// colouring and count, as "name=value&..." (values URL-safe: the options' texts are names and
// numbers, and importance's curve ids are percent-encoded).
EMSCRIPTEN_KEEPALIVE const char* flatland_state_query() {
  static std::string query;
  query = the_viewer ? the_viewer->link_query() : "";
  return query.c_str();
}

// Photons shot so far in the viewer's solve (the page's measurements read it: bench/web_bench.py).
EMSCRIPTEN_KEEPALIVE double flatland_photons() {
  return the_viewer ? static_cast<double>(the_viewer->session().snapshot()->progress.photons) : 0.0;
}

}  // extern "C"

int main(int argc, char** argv) {
  using namespace flatland::app;
  CommandLine command_line;
  if (const std::optional<int> code = parse_command_line(argc, argv, command_line)) return *code;
  switch (command_line.command) {
    case Command::View: {
      viewer::ViewOptions options;
      if (const std::optional<int> code = make_view_options(command_line.view, options)) return *code;
      options.inline_solve = true;
      Result<std::unique_ptr<viewer::Viewer>> created = viewer::Viewer::create(options);
      if (!created) return input_error(created.error());
      the_viewer = std::move(*created);
      emscripten_set_main_loop_arg(frame, nullptr, 0, false);
      return kExitOk;
    }
    case Command::Solve: return run_solve(command_line.solve);
    default:
      std::fprintf(stderr,
                   "flatland: error: the web page runs view and solve; use the desktop program for the others\n");
      return kExitUsage;
  }
}
