// `flatland view`: the interactive viewer (a window of window.hpp: SDL2 and OpenGL 3.3 core on the
// desktop, GLFW and WebGL2 in the browser; Dear ImGui panels). It drives a Session (the core's
// Solver on a worker thread, or between frames) and draws each frame from the latest snapshot with
// the Renderer. Headless runs (--frames N --screenshot FILE) and the UI tests use
// the same object.
#pragma once

#include <atomic>

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "flatland/base/status.hpp"
#include "flatland/transport/options.hpp"
#include "flatland/transport/solver.hpp"
#include "viewer/session.hpp"

namespace flatland::viewer {

// The viewer's solver settings before any option: the solver's defaults without the control
// variate. The viewer is for watching photons carry the light; with the variate they carry a signed
// correction to a coarse answer, from everywhere at once (the "coarse variate" box, or
// --control-variate, turns it on).
SolverSettings view_default_settings();

struct ViewOptions {
  std::string scene;      // scene file; empty: the default scene
  std::string reference;  // a reference result to measure the error against (optional)
  SolverSettings settings = view_default_settings();
  int width = 1280;
  int height = 800;
  int frames = 0;  // 0: until the window is closed
  // What each frame does: "live" (the solve runs on its own, as fast as it can), "photons=N",
  // "batches=N" or "rounds=N" (that many, finished before the frame is drawn: deterministic).
  std::string step = "live";
  bool paused = false;           // start paused (interactive)
  std::string screenshot;        // after the last frame: the scene view, without panels (PNG)
  std::string screenshot_ui;     // after the last frame: the whole window, panels included (PNG)
  std::string shader_directory;  // load shaders from here instead of the built-in copies
  std::size_t keep_paths = 20'000;
  std::size_t path_budget = 600;  // new paths drawn per frame at most (newest first)
  bool show_control_points = false;
  std::string select;               // a curve to inspect at start: its id or index
  std::string colour_by = "power";  // photon paths coloured by "power", "round" or "bounce"
  std::string light = "auto";       // the light layer: "auto", "paths" or "field" (LightView)
  float path_exposure = 1.0f;
  float path_fade = 1.0f;  // 0: every kept path equally bright; 1: the oldest fade to about 5 %
  bool show_ui = true;
  bool present = false;        // start in presentation mode
  bool first_photons = false;  // start with the First photons lecture preset (key 1)
  // Size of the panels' text and widgets (and their columns): 1 at a desk, 1.5-2 on a projector.
  float ui_scale = 1.0f;
  bool vsync = true;
  // Frames per second at most: 0 chooses 40 with a software OpenGL renderer (it draws on the
  // solver's cores) and no limit otherwise (vsync paces the frames); negative is no limit.
  int max_fps = 0;
  bool report = false;  // print frame and photon rates at the end
  // Solve between frames on the drawing thread instead of on a worker thread (the web build has
  // one thread): each frame spends about kInlineSolveSeconds on it.
  bool inline_solve = false;
  // Ends a wait for the scene or reference file (a FIFO with no writer yet) when set: Ctrl-C.
  const std::atomic<bool>* cancel = nullptr;
};

// How each frame steps the solve (parsed from ViewOptions::step).
struct FrameStep {
  enum class Mode { Live, Photons, Batches, Rounds } mode = Mode::Live;
  std::uint64_t count = 0;
};
Result<FrameStep> parse_frame_step(const std::string& text);

// Seconds since the first call (a steady clock), for frame timing and messages.
double seconds_since_start();
// "100000", "1e6" -> 1000000; anything not a whole number in [1, 2^53] is an error naming `what`.
Result<std::uint64_t> parse_whole_number(const std::string& text, const std::string& what);

// The default scene: scenes2d/default.json beside the source tree or the working directory.
std::string default_scene_path();

struct WindowEvent;

class Viewer {
 public:
  // An inline solve's share of a frame (ViewOptions::inline_solve).
  static constexpr double kInlineSolveSeconds = 0.02;
  // Opens the window and the GL context. Errors: no display (one line: what to do instead),
  // shader compile or link errors (with the GL log), a bad scene or reference file.
  static Result<std::unique_ptr<Viewer>> create(const ViewOptions& options);
  ~Viewer();
  Viewer(const Viewer&) = delete;
  Viewer& operator=(const Viewer&) = delete;

  // Handles input, steps the solve as the options say, draws and shows one frame. False once the
  // user has closed the window.
  bool frame();
  // Runs frames until closed or until options.frames are done; writes the screenshots asked for.
  Status run();

  Session& session() { return *session_; }
  const SolverSettings& settings() const { return settings_; }
  const Scene& scene() const { return *scene_; }
  int selected_curve() const { return draw_.selected_curve; }
  PathColour path_colour() const { return draw_.path_colour; }
  LightView light_view() const { return draw_.light; }
  // The view as URL parameters, "name=value&..." (the web page's Copy link, and --report's link
  // line): every solve option that differs from its default (threads aside), the inspected curve
  // (by index), presentation mode, the First photons preset while it steps, and the paths kept,
  // their colouring and the light's view where they differ from the defaults (ViewOptions). The
  // values are names and numbers: URL-safe as they are.
  std::string link_query() const;
  // The view (scene to window pixels), the docked layout of the last frame, and the rectangle of
  // a panel ("Solve", "Display", "Status", "Curve") drawn in the last frame.
  const ViewTransform& view() const { return view_; }
  const StageLayout& layout() const { return layout_; }
  std::optional<PixelRect> panel_rect(const std::string& name) const;
  // Whether that panel's content was taller than the panel (it showed a scroll bar), or wider (cut
  // off at its right edge).
  bool panel_scrolls(const std::string& name) const;
  bool panel_clips(const std::string& name) const;
  // Presentation mode (M): no panels; the photon counter above the stage, the inspected curve's
  // B(s) beside it, the colour key under it (presentation_layout).
  bool presentation() const { return presentation_; }
  std::size_t paths_drawn() const;  // photon paths in the path buffer after the last frame

  // UI automation for tests: the rectangle (x0, y0, x1, y1, pixels) of the widget drawn last
  // frame with this label, and a queued left click at a pixel (applied over the next frames).
  std::optional<std::array<float, 4>> widget_rect(const std::string& label) const;
  void queue_click(float x, float y);
  void queue_drag(float from_x, float from_y, float to_x, float to_y);
  void queue_key(int key, bool ctrl = false);  // a key of window.hpp (keys::)
  // Resizes the window (as a user dragging its border would); the next frames lay out again.
  void resize_window(int width, int height);
  // The "first photons" preset for a lecture: random walks, paths coloured by bounce, a few kept,
  // the solve restarted and stepped one photon every `kFirstPhotonsSeconds` so a class can follow
  // each journey. Any step or Run key ends the slow stepping.
  void first_photons();
  static constexpr double kFirstPhotonsSeconds = 0.8;
  bool slow_stepping() const { return slow_stepping_; }
  // What a link to this view carries besides the solve settings (the web page's Copy link).
  std::size_t paths_kept() const { return static_cast<std::size_t>(keep_slider_); }
  // Opens another scene file (as File > Open scene does); a file that does not load leaves the
  // scene as it was, and its one-line error is the result (and the status panel's message).
  Status open_scene(const std::string& path);
  const std::string& scene_path() const { return scene_path_; }
  void select_curve(int curve) { draw_.selected_curve = curve; }

  // The scene view without panels, as a PNG (--screenshot-ui takes the whole window).
  Status save_screenshot(const std::string& path);

 private:
  Viewer() = default;
  struct Impl;
  // The steps of create, in order; each error is what create reports.
  Status apply_options(const ViewOptions& options);
  Status load_first_scene(const ViewOptions& options);
  Status set_path_style(const ViewOptions& options);
  Result<std::shared_ptr<const SampledResult>> load_reference(const ViewOptions& options);
  Result<std::unique_ptr<Impl>> open_window(const ViewOptions& options) const;
  Status create_renderer(Impl& impl, const ViewOptions& options);
  static void start_imgui(Impl& impl, float ui_scale);
  Status start_session(const ViewOptions& options, const std::shared_ptr<const SampledResult>& reference);
  void restart();
  // open_scene from the viewer's own controls (the status panel shows an error).
  void load_scene_file(const std::string& path) { static_cast<void>(open_scene(path)); }
  // The main loop's parts.
  void handle_events();
  void step_solve();
  void handle_scene_mouse(const Snapshot& snapshot);
  void draw(const std::shared_ptr<const Snapshot>& snapshot);
  Status save_window_picture(const std::string& path);
  void handle_event(const WindowEvent& event);
  void handle_key(int key, bool ctrl);
  // Panels (panels.cpp).
  void draw_ui(const Snapshot& snapshot);
  void draw_menu(const Snapshot& snapshot);
  void draw_solve_panel(const Snapshot& snapshot);
  void draw_display_panel();
  void draw_status_panel(const Snapshot& snapshot);
  void draw_curve_panel(const Snapshot& snapshot);
  // B(s) along curve c, in the curve panel (with the captions that explain it) or an overlay.
  void draw_curve_plot(const Snapshot& snapshot, std::size_t c, bool captions = true);
  void draw_detector_plot(const Snapshot& snapshot, std::size_t c, bool captions);
  void draw_colour_key(const Snapshot& snapshot);
  void draw_key_strip(const Snapshot& snapshot);
  void draw_counter_overlay(const Snapshot& snapshot);
  void draw_curve_overlay(const Snapshot& snapshot);
  void draw_help_panel();
  void track(const char* label);
  // ImGui::Combo with every item tracked as "label:item" for the UI tests.
  bool combo(const char* label, int* index, const char* const* names, int count);
  // A combo of a solve option's names (options.hpp), labelled with its name, with `tooltip` (if
  // any) while it is hovered; true when changed.
  bool option_combo(SolveOption option, const char* tooltip = nullptr);
  // The inspected curve c's "importance" checkbox: whether it is one of the curves the solve's
  // importance favours; true when it was toggled.
  bool importance_checkbox(std::size_t c);
  // `stage`: the part of the window the scene is drawn on (none: all of it).
  void render_scene(const Snapshot& snapshot, const ViewTransform& view, const PixelRect* stage = nullptr);
  // Records the current ImGui window's rectangle as panel `name` (call between Begin and End).
  void record_panel(const char* name);
  void apply_edit();
  void drop_reference(const std::string& why);
  void check_file_changed();
  void set_message(std::string text);
  // A file written for the user (Window::deliver: a download in the browser).
  void deliver(const std::string& path);

  std::unique_ptr<Impl> impl_;  // window, GL context, ImGui state, renderer
  ViewOptions options_;
  FrameStep frame_step_;
  std::unique_ptr<Session> session_;
  std::shared_ptr<const Scene> scene_;
  std::string scene_path_;
  std::string reference_path_;
  SolverSettings settings_;
  std::string budget_text_;
  DrawOptions draw_;
  ViewTransform view_;
  bool view_fitted_ = false;
  // Whether the view is the fitted one (no zoom or pan since): it follows the stage when the
  // panels change, and a scene screenshot fits the whole picture.
  bool view_auto_ = true;
  StageLayout layout_;
  bool panels_visible_ = true;
  std::map<std::string, PixelRect> panel_rects_;
  std::map<std::string, bool> panel_scrolls_;
  std::map<std::string, bool> panel_clips_;
  float display_height_ = 0.0f;    // the Display panel's height in the last frame
  bool display_on_right_ = false;  // it is docked under Status (the left column was too short)
  bool presentation_ = false;
  std::uint64_t overlay_generation_ = ~0ull;
  std::shared_ptr<const Snapshot> overlay_snapshot_;
  std::vector<LineVertex> overlay_;
  PathLayer path_layer_;
  std::map<std::string, std::array<float, 4>> widget_rects_;
  struct QueuedInput {
    float x = 0.0f;
    float y = 0.0f;
    bool down = false;
    int key = 0;  // a key press instead of mouse input
    bool ctrl = false;
  };
  std::vector<QueuedInput> queued_;
  // Mouse interaction with the scene.
  bool panning_ = false;
  int dragging_point_ = -1;
  double last_edit_time_ = 0.0;
  bool edit_pending_ = false;
  Scene edited_;
  int hovered_point_ = -1;
  std::int64_t file_time_ = 0;
  double last_file_check_ = 0.0;
  std::string message_;
  double message_time_ = 0.0;
  bool show_help_ = false;
  bool slow_stepping_ = false;  // the first-photons preset's timed steps
  double last_slow_step_ = -1e9;
  std::string window_picture_;                // Ctrl+S: the whole window, legends included, after this frame
  Status screenshot_ui_saved_ = ok_status();  // how writing --screenshot-ui went
  bool quit_ = false;
  bool software_renderer_ = false;  // GL_RENDERER is llvmpipe or softpipe
  int frames_done_ = 0;
  std::vector<double> frame_seconds_;
  double keep_slider_ = 20'000;
};

}  // namespace flatland::viewer
