// The subcommands of the flatland executable. Each adds its options to the parser and runs;
// exit codes: 0 success, 1 internal failure, 2 bad input (one-line message), 130 interrupted.
#pragma once

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <optional>
#include <string>

#include <CLI/CLI.hpp>

#include "flatland/reference/reference.hpp"
#include "flatland/results/metrics.hpp"
#include "flatland/transport/options.hpp"
#include "flatland/transport/solver.hpp"

namespace flatland::viewer {
struct ViewOptions;
}

namespace flatland::app {

inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;
inline constexpr int kExitUsage = 2;
inline constexpr int kExitInterrupted = 130;

// A path to write: not empty (an empty value would otherwise read as the option not given, and
// the command would write nothing without a word).
inline CLI::Validator output_path() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        return text.empty() ? "an empty path; give the file to write (or leave the option out)" : std::string();
      },
      "PATH");
}

// A number in [low, high]. CLI::Range lets NaN through (every comparison with NaN is false);
// this check does not: the value must compare inside the range.
inline CLI::Validator finite_range(double low, double high) {
  char description[96];
  std::snprintf(description, sizeof description, "FLOAT in [%g - %g]", low, high);
  return CLI::Validator(
      [low, high](std::string& text) -> std::string {
        char* end = nullptr;
        const double value = std::strtod(text.c_str(), &end);
        if (end == text.c_str() || *end != '\0' || !(value >= low && value <= high)) {
          char message[160];
          std::snprintf(message, sizeof message, "Value %s not in range [%g - %g]", text.c_str(), low, high);
          return message;
        }
        return {};
      },
      description);
}

// Set by SIGINT / SIGTERM (main.cpp installs the handlers); long work checks it between batches.
std::atomic<bool>& interrupt_flag();

struct SolveOptions {
  SolveOptions();
  std::string scene;
  // Each solve option as typed (options.hpp), starting at its default's text; set into `settings`
  // by finish_solver_settings.
  std::map<SolveOption, std::string> text;
  SolverSettings settings;
  int samples = 100;
  std::string out;
  std::string picture;
  std::string detectors;  // CSV of the detectors' tallies
  std::string reference;
  bool quiet = false;
};

struct ReferenceOptions {
  std::string scene;
  double max_element_length = 0.0;
  int elements = 0;
  ReferenceSettings settings;
  int samples = 100;
  std::string out;
  bool quiet = false;
  bool estimate_error = true;
};
// The reference's own error, estimated from two more solves with elements twice and four times as
// long: |R_2h - R_h| / (2^p - 1) with the order p observed from the three (docs/reference.md);
// `fine` is the samples of R_h (sample_radiosity).
Result<ErrorNorms> estimate_reference_error(const Scene& scene, ReferenceSettings settings, int samples,
                                            const SampledResult& fine);
CLI::App* add_reference_command(CLI::App& parent, ReferenceOptions& options);
int run_reference(ReferenceOptions& options);

struct ConvergeOptions {
  std::string scene;
  std::string reference;
  std::string methods = "constant,linear,cubic";
  std::string budgets = "1e4,1e5,1e6";
  std::string times;
  int seeds = 3;
  int samples = 100;
  unsigned threads = 0;
  double tolerance = 1e-6;
  std::string elements = "auto";
  std::string out;
  bool replot = false;
  std::string measure = "reflected";  // "reflected" (B - E) or "total" (B)
  std::string curve;                  // a curve id: that curve's error instead of the scene's
};
CLI::App* add_converge_command(CLI::App& parent, ConvergeOptions& options);
int run_converge(ConvergeOptions& options);
// The checks run_converge makes before any work: --methods, and --budgets or --times, parse.
Status check_converge_options(const ConvergeOptions& options);

struct CompareOptions {
  std::string result;
  std::string reference;
  std::string measure = "reflected";  // "reflected" (B - E) or "total" (B)
  std::string curve;                  // a curve id: print that curve's row only
  bool json = false;                  // print the errors as a JSON document instead of a table
};
CLI::App* add_compare_command(CLI::App& parent, CompareOptions& options);
int run_compare(const CompareOptions& options);

// Prints what `comparison` measures and its per-curve errors as a table, with a last row for the
// whole scene unless `scene_row` is false.
// With `result` (the judged result's document), the result's estimated error beside the errors.
void print_comparison(const Comparison& comparison, bool scene_row = true, const nlohmann::json* result = nullptr);
// The measure named by --measure: "reflected" (B - E) or "total" (B).
Measure parse_measure(const std::string& text);
// The index of the curve with id `id` among `ids`, or a one-line error for --curve that names the
// valid ids.
Result<std::size_t> find_curve(const std::vector<std::string>& ids, const std::string& id);

CLI::App* add_solve_command(CLI::App& parent, SolveOptions& options);
// The solver's options (--photons, --seed, --threads, --basis, ...), shared by solve, view, render.
void add_solver_options(CLI::App* command, SolveOptions& options);
// After a solve: when it was interrupted (exit 130, nothing written) or its books failed (exit 1),
// prints the one-line message and returns the exit code; nothing when the solve ended normally.
std::optional<int> abnormal_stop(const Solver& solver);
// Turns the parsed text options into options.settings and validates them.
Status finish_solver_settings(SolveOptions& options);

int run_solve(SolveOptions& options);

struct ViewCommandOptions {
  SolveOptions solve;  // scene and solver options
  std::string reference;
  int width = 1280;
  int height = 800;
  int frames = 0;
  std::string step = "live";
  bool paused = false;
  std::string screenshot;
  std::string screenshot_ui;
  std::string shaders;
  int keep_paths = 20000;
  int paths_per_frame = 600;
  bool control_points = false;
  std::string select;
  std::string colour_by = "power";
  std::string light = "auto";
  float exposure = 1.0f;
  float fade = 1.0f;
  bool no_ui = false;
  bool present = false;
  bool first_photons = false;
  float ui_scale = 1.0f;
  bool no_vsync = false;
  int max_fps = 0;
  bool report = false;
};
CLI::App* add_view_command(CLI::App& parent, ViewCommandOptions& options);
int run_view(ViewCommandOptions& options);
// The viewer's options from view's, after every check view makes before it opens a window. A bad
// option: its one-line message printed, and the exit code returned (the web page's start uses
// this, then runs the viewer frame by frame).
std::optional<int> make_view_options(ViewCommandOptions& o, viewer::ViewOptions& options);

struct RenderOptions {
  SolveOptions solve;  // scene and solver options
  std::string out;
  std::string result;
  int width = 1280;
  int height = 800;
  int paths = 20000;
  int field_flights = 200000;
  std::string light = "auto";
  float exposure = 1.0f;
  bool graph = true;
  bool band = true;
  bool journey = false;  // the newest photon's journey on top (the viewer's default, not a picture's)
  bool nodes = false;    // the storage's nodes below C1 as diamonds
  bool labels = true;    // the title above the scene, the colour key and legend below it
  std::string shaders;
};
CLI::App* add_render_command(CLI::App& parent, RenderOptions& options);
int run_render(RenderOptions& options);

// "1e6", "250000", "2.5e5" -> 250000; anything not a whole number in [1, kMaxPhotons] (2^50) is an
// error naming the option (parse_photon_count).
Result<std::uint64_t> parse_count(const std::string& text, const std::string& option);

}  // namespace flatland::app
