#include "viewer/viewer_app.hpp"

#include <imgui.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <thread>

#include "flatland/results/result_io.hpp"
#include "flatland/transport/importance.hpp"
#include "png/png_io.hpp"
#include "viewer/gl.hpp"
#include "viewer/renderer.hpp"
#include "viewer/window.hpp"

namespace flatland::viewer {

SolverSettings view_default_settings() {
  SolverSettings settings;
  settings.control_variate = ControlVariate::None;
  return settings;
}

using png::PngImage;
using png::write_png;

namespace {

using Clock = std::chrono::steady_clock;

// How far frame pacing may fall behind and still make it up (Viewer::run).
constexpr double kPaceCatchUp = 0.25;  // seconds

std::int64_t file_time(const std::string& path) {
  std::error_code error;
  const auto time = std::filesystem::last_write_time(path, error);
  if (error) return 0;
  return static_cast<std::int64_t>(time.time_since_epoch().count());
}

}  // namespace

struct Viewer::Impl {
  std::unique_ptr<Window> window;  // goes last: the GL objects below live in its context
  std::unique_ptr<Renderer> renderer;
  GLuint screenshot_framebuffer = 0;
  GLuint screenshot_colour = 0;

  ~Impl() {
    renderer.reset();
    if (screenshot_framebuffer != 0) glDeleteFramebuffers(1, &screenshot_framebuffer);
    if (screenshot_colour != 0) glDeleteRenderbuffers(1, &screenshot_colour);
    window.reset();
  }
};

double seconds_since_start() {
  static const Clock::time_point start = Clock::now();
  return std::chrono::duration<double>(Clock::now() - start).count();
}

Result<std::uint64_t> parse_whole_number(const std::string& text, const std::string& what) {
  char* end = nullptr;
  const double value = std::strtod(text.c_str(), &end);
  if (text.empty() || end == nullptr || *end != '\0' || !(value >= 1.0) || value > 9007199254740992.0 ||
      value != std::floor(value))
    return Error{what + ": expected a whole number >= 1 (e.g. 100000 or 1e6), got '" + text + "'"};
  return static_cast<std::uint64_t>(value);
}

Result<FrameStep> parse_frame_step(const std::string& text) {
  FrameStep step;
  if (text == "live") return step;
  const std::size_t equals = text.find('=');
  const std::string kind = text.substr(0, equals);
  if (equals == std::string::npos || (kind != "photons" && kind != "batches" && kind != "rounds"))
    return Error{"--step: expected live, photons=N, batches=N or rounds=N, got '" + text + "'"};
  Result<std::uint64_t> count = parse_whole_number(text.substr(equals + 1), "--step " + kind);
  if (!count) return count.error();
  step.mode = kind == "photons"   ? FrameStep::Mode::Photons
              : kind == "batches" ? FrameStep::Mode::Batches
                                  : FrameStep::Mode::Rounds;
  step.count = *count;
  return step;
}

std::string default_scene_path() {
#ifdef FLATLAND_SOURCE_SCENES
  const std::string installed = FLATLAND_SOURCE_SCENES "/default.json";
#else
  const std::string installed;
#endif
  for (const std::string& candidate : {std::string("scenes2d/default.json"), installed})
    if (!candidate.empty() && std::filesystem::exists(candidate)) return candidate;
  return "scenes2d/default.json";
}

Result<std::unique_ptr<Viewer>> Viewer::create(const ViewOptions& options) {
  std::unique_ptr<Viewer> viewer(new Viewer());
  if (Status applied = viewer->apply_options(options); !applied) return applied.error();

  // The scene and the reference first: a bad file is reported before any window opens.
  if (Status loaded = viewer->load_first_scene(options); !loaded) return loaded.error();
  if (Status styled = viewer->set_path_style(options); !styled) return styled.error();
  Result<std::shared_ptr<const SampledResult>> reference = viewer->load_reference(options);
  if (!reference) return reference.error();

  Result<std::unique_ptr<Impl>> opened = viewer->open_window(options);
  if (!opened) return opened.error();
  std::unique_ptr<Impl> impl = std::move(*opened);
  if (Status created = viewer->create_renderer(*impl, options); !created) return created.error();
  start_imgui(*impl, options.ui_scale);
  viewer->impl_ = std::move(impl);

  if (Status started = viewer->start_session(options, *reference); !started) return started.error();
  return viewer;
}

// The settings, the frame steps and the drawing options that need no file.
Status Viewer::apply_options(const ViewOptions& options) {
  options_ = options;
  settings_ = options.settings;
  draw_.control_points = options.show_control_points;
  presentation_ = options.present;
  keep_slider_ = static_cast<double>(options.keep_paths);
  Result<FrameStep> step = parse_frame_step(options.step);
  if (!step) return step.error();
  frame_step_ = *step;
  return validate(options.settings);
}

// The scene file (the default scene without one) and the curve that --select names.
Status Viewer::load_first_scene(const ViewOptions& options) {
  scene_path_ = options.scene.empty() ? default_scene_path() : options.scene;
  Result<Scene> scene = load_scene(scene_path_, options.cancel);
  if (!scene) return scene.error();
  scene_ = std::make_shared<const Scene>(std::move(*scene));
  file_time_ = file_time(scene_path_);
  if (!options.select.empty()) {
    const Scene& loaded = *scene_;
    for (std::size_t c = 0; c < loaded.curves.size(); ++c)
      if (loaded.curves[c].id == options.select || std::to_string(c) == options.select)
        draw_.selected_curve = static_cast<int>(c);
    if (draw_.selected_curve < 0)
      return Error{"--select: the scene has no curve '" + options.select + "' (give an id or an index below " +
                   std::to_string(loaded.curves.size()) + ")"};
  }
  return ok_status();
}

// How the photon paths are coloured, exposed and faded.
Status Viewer::set_path_style(const ViewOptions& options) {
  if (options.colour_by != "power" && options.colour_by != "round" && options.colour_by != "bounce")
    return Error{"--colour-by: expected power, round or bounce, got '" + options.colour_by + "'"};
  draw_.path_colour = options.colour_by == "round"    ? PathColour::Round
                      : options.colour_by == "bounce" ? PathColour::Bounce
                                                      : PathColour::Power;
  if (options.light != "auto" && options.light != "paths" && options.light != "field")
    return Error{"--light: expected auto, paths or field, got '" + options.light + "'"};
  draw_.light = options.light == "paths"   ? LightView::Paths
                : options.light == "field" ? LightView::Field
                                           : LightView::Auto;
  draw_.path_exposure = options.path_exposure;
  draw_.fade = options.path_fade;
  return ok_status();
}

// The reference result of --reference (null without one), checked to be of the loaded scene.
Result<std::shared_ptr<const SampledResult>> Viewer::load_reference(const ViewOptions& options) {
  if (options.reference.empty()) return std::shared_ptr<const SampledResult>();
  Result<nlohmann::json> read = read_result_file(options.reference, options.cancel);
  if (!read) return Error{"--reference: " + read.error().message};
  nlohmann::json document = std::move(*read);
  if (!document.contains("curves") || !document["curves"].is_array())
    return Error{options.reference +
                 ": not a flatland result (no \"curves\"; write one with 'flatland reference SCENE --out FILE')"};
  Result<SampledResult> sampled = sampled_from_json(document, "the reference");
  if (!sampled) return Error{"--reference: " + options.reference + ": " + sampled.error().message};
  // The same scene: its curves, by id, in order (compare checks the rest as the solve goes).
  if (Status status = check_reference_of(*sampled, *scene_); !status)
    return Error{options.reference + ": " + status.error().message};
  auto reference = std::make_shared<const SampledResult>(std::move(*sampled));
  reference_path_ = options.reference;
  return reference;
}

// The window and its GL context, titled with the scene's name.
Result<std::unique_ptr<Viewer::Impl>> Viewer::open_window(const ViewOptions& options) const {
  Result<std::unique_ptr<Window>> window =
      Window::open("flatland - " + scene_->name, options.width, options.height, options.vsync);
  if (!window) return window.error();
  auto impl = std::make_unique<Impl>();
  impl->window = std::move(*window);
  return impl;
}

// The renderer on the current GL context, and whether that GL draws in software.
Status Viewer::create_renderer(Impl& impl, const ViewOptions& options) {
  // Mesa's software rasterisers (llvmpipe, softpipe) share the CPU with the solver.
  const auto* gl_renderer = reinterpret_cast<const char*>(glGetString(GL_RENDERER));
  software_renderer_ = gl_renderer != nullptr && (std::strstr(gl_renderer, "llvmpipe") != nullptr ||
                                                  std::strstr(gl_renderer, "softpipe") != nullptr);
  Result<std::unique_ptr<Renderer>> renderer = Renderer::create(options.shader_directory, 0.5f);
  if (!renderer) return renderer.error();
  impl.renderer = std::move(*renderer);
  return ok_status();
}

// Dear ImGui on the window and its GL context, at the panels' scale.
void Viewer::start_imgui(Impl& impl, float ui_scale) {
  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGuiIO& io = ImGui::GetIO();
  io.IniFilename = nullptr;  // no imgui.ini left in the working directory
  ImGui::StyleColorsDark();
  // Projectors: every size and the font scaled alike (the docked columns follow in stage_layout).
  if (ui_scale != 1.0f) {
    ImGui::GetStyle().ScaleAllSizes(ui_scale);
    io.FontGlobalScale = ui_scale;
  }
  impl.window->start_imgui();
}

// The session on its worker thread, solving the scene: running from the start unless paused or
// stepped frame by frame.
Status Viewer::start_session(const ViewOptions& options, const std::shared_ptr<const SampledResult>& reference) {
  try {
    session_ =
        std::make_unique<Session>(options.inline_solve ? Session::Threading::Inline : Session::Threading::Worker);
  } catch (const std::system_error& e) {
    return Error{"cannot start the solver's thread: " + e.code().message() + " (see ulimit -u and ulimit -v)"};
  }
  session_->set_path_limit(options.keep_paths);
  session_->set_reference(reference);
  char budget[32];
  std::snprintf(budget, sizeof budget, "%g", static_cast<double>(settings_.photons));
  budget_text_ = budget;
  restart();
  if (options.first_photons) {
    first_photons();  // restarts with walks and steps one photon at a time (the preset's own pace)
    return ok_status();
  }
  if (frame_step_.mode == FrameStep::Mode::Live && !options.paused) session_->set_running(true);
  return ok_status();
}

Viewer::~Viewer() {
  session_.reset();  // stop the worker before the GL context goes
}

void Viewer::restart() { session_->restart(scene_, settings_); }

void Viewer::deliver(const std::string& path) { impl_->window->deliver(path); }

void Viewer::set_message(std::string text) {
  message_ = std::move(text);
  message_time_ = seconds_since_start();
}

Status Viewer::open_scene(const std::string& path) {
  Result<Scene> scene = load_scene(path, options_.cancel);
  if (!scene) {
    set_message(scene.error().message);
    return scene.error();
  }
  const bool same_file = path == scene_path_;
  scene_ = std::make_shared<const Scene>(std::move(*scene));
  scene_path_ = path;
  file_time_ = file_time(path);
  if (!same_file) {
    view_fitted_ = false;
    draw_.selected_curve = -1;
  }
  drop_reference("the scene changed");  // a reference belongs to one scene, as it was
  if (draw_.selected_curve >= static_cast<int>(scene_->curves.size())) draw_.selected_curve = -1;
  impl_->window->set_title("flatland - " + scene_->name);
  // Importance names curves of the scene it was given for: those this one lacks (or that hold no
  // light in it) are dropped, and the message says so.
  std::string dropped;
  std::erase_if(settings_.importance, [&](const std::string& id) {
    SolverSettings one;
    one.importance = {id};
    if (importance_curves(*scene_, one)) return false;
    dropped += (dropped.empty() ? "'" : ", '") + id + "'";
    return true;
  });
  set_message("loaded " + path + (dropped.empty() ? "" : "; importance no longer names " + dropped));
  restart();
  return ok_status();
}

void Viewer::check_file_changed() {
  const double now = seconds_since_start();
  if (now - last_file_check_ < 0.5) return;
  last_file_check_ = now;
  const std::int64_t time = file_time(scene_path_);
  if (time != 0 && time != file_time_) {
    file_time_ = time;
    load_scene_file(scene_path_);
  }
}

std::optional<std::array<float, 4>> Viewer::widget_rect(const std::string& label) const {
  const auto found = widget_rects_.find(label);
  if (found == widget_rects_.end()) return std::nullopt;
  return found->second;
}

void Viewer::queue_click(float x, float y) {
  queued_.push_back({x, y, false, 0});  // move there
  queued_.push_back({x, y, true, 0});   // press
  queued_.push_back({x, y, false, 0});  // release
}

void Viewer::queue_drag(float from_x, float from_y, float to_x, float to_y) {
  queued_.push_back({from_x, from_y, false, 0});
  queued_.push_back({from_x, from_y, true, 0});
  for (int i = 1; i <= 4; ++i) {
    const float f = static_cast<float>(i) / 4.0f;
    queued_.push_back({from_x + f * (to_x - from_x), from_y + f * (to_y - from_y), true, 0});
  }
  queued_.push_back({to_x, to_y, false, 0});
}

void Viewer::resize_window(int width, int height) { impl_->window->set_size(width, height); }

void Viewer::queue_key(int key, bool ctrl) { queued_.push_back({0.0f, 0.0f, false, key, ctrl}); }

void Viewer::handle_key(int key, bool ctrl) {
  overlay_generation_ = ~0ull;  // a display toggle shows at once, also while paused
  switch (key) {
    case ' ':
      if (session_->snapshot()->stop_reason != StopReason::Running)
        set_message("the solve has stopped; Backspace (Reset) starts it again");
      else
        session_->set_running(!session_->running());
      break;
    case '.':
      slow_stepping_ = false;
      session_->step(StepKind::Photon);
      break;
    case 'b': session_->step(StepKind::Batch); break;
    case 'r': session_->step(StepKind::Round); break;
    case keys::kBackspace: restart(); break;
    case 'f': view_fitted_ = false; break;
    case keys::kTab: panels_visible_ = !panels_visible_; break;
    case 'c': draw_.control_points = !draw_.control_points; break;
    case 'n': draw_.storage_nodes = !draw_.storage_nodes; break;
    case 'g': draw_.graph = !draw_.graph; break;
    case 'k': draw_.band = !draw_.band; break;
    case 'p': draw_.paths = !draw_.paths; break;
    case 'm':
      presentation_ = !presentation_;
      if (view_auto_) view_fitted_ = false;
      break;
    case '+':
    case '=': draw_.path_exposure *= 1.5f; break;
    case '-': draw_.path_exposure /= 1.5f; break;
    case keys::kF1:
    case 'h': show_help_ = !show_help_; break;
    case keys::kF5: load_scene_file(scene_path_); break;
    case keys::kEscape:
      if (Window::closable()) quit_ = true;
      break;
    case 's':
      if (ctrl) {
        // The whole window as drawn at the end of this frame: the scene with the panels, so the
        // picture carries its colour key, the bounce colours and the B(s) plot's axes.
        char name[128];
        std::snprintf(name, sizeof name, "flatland-%s-%d.png", scene_->name.c_str(), frames_done_);
        window_picture_ = name;
      }
      break;
    case '1': first_photons(); break;
    case 'e':
      if (ctrl) {
        const std::string name = "flatland-" + scene_->name + "-result.json";
        Result<nlohmann::json> result = session_->result_json(100);
        Status saved =
            result ? write_file_atomically(name, json_text(*result), options_.cancel) : Status(result.error());
        set_message(saved ? "saved " + name : saved.error().message);
        if (saved) deliver(name);
      }
      break;
    default: break;
  }
}

void Viewer::handle_event(const WindowEvent& event) {
  const ImGuiIO& io = ImGui::GetIO();
  switch (event.type) {
    case WindowEvent::Type::Close: quit_ = true; break;
    case WindowEvent::Type::Key:
      if (!io.WantCaptureKeyboard || event.key == keys::kEscape) handle_key(event.key, event.ctrl);
      break;
    case WindowEvent::Type::Wheel:
      if (!io.WantCaptureMouse) {
        view_.zoom_about({event.x, event.y}, std::pow(1.15, event.wheel));
        view_auto_ = false;
      }
      break;
    case WindowEvent::Type::Drop: load_scene_file(event.path); break;
  }
}

void Viewer::apply_edit() {
  if (!edit_pending_) return;
  edit_pending_ = false;
  last_edit_time_ = seconds_since_start();
  Scene edited = edited_;
  if (Status status = finalize_scene(edited); !status) {
    set_message("edit rejected: " + status.error().message);
    return;
  }
  scene_ = std::make_shared<const Scene>(std::move(edited));
  drop_reference("the scene was edited");
  restart();
}

std::size_t Viewer::paths_drawn() const { return path_layer_.drawn(); }

void Viewer::drop_reference(const std::string& why) {
  if (reference_path_.empty()) return;
  session_->set_reference(nullptr);
  set_message("reference " + reference_path_ + " dropped: " + why);
  reference_path_.clear();
}

std::optional<PixelRect> Viewer::panel_rect(const std::string& name) const {
  const auto it = panel_rects_.find(name);
  if (it == panel_rects_.end()) return std::nullopt;
  return it->second;
}

bool Viewer::panel_clips(const std::string& name) const {
  const auto it = panel_clips_.find(name);
  return it != panel_clips_.end() && it->second;
}

bool Viewer::panel_scrolls(const std::string& name) const {
  const auto it = panel_scrolls_.find(name);
  return it != panel_scrolls_.end() && it->second;
}

void Viewer::render_scene(const Snapshot& snapshot, const ViewTransform& view, const PixelRect* stage) {
  if (snapshot.generation != overlay_generation_ || overlay_snapshot_.get() != &snapshot) {
    overlay_ = build_overlay(snapshot, draw_);
    overlay_generation_ = snapshot.generation;
  }
  // Live, a frame draws at most path_budget new paths (the rest of the kept set follows over the
  // next frames); a deterministic step (--step) draws everything it shot before the frame.
  const std::size_t budget =
      frame_step_.mode == FrameStep::Mode::Live ? options_.path_budget : std::numeric_limits<std::size_t>::max();
  const PathDraw paths = path_layer_.update(snapshot, draw_, view, static_cast<std::size_t>(keep_slider_), budget);
  if (Status drawn = impl_->renderer->draw(overlay_, paths, view, draw_.path_exposure, stage); !drawn)
    set_message(drawn.error().message);
}

bool Viewer::frame() {
  // The main loop: events, step, UI, draw, swap.
  const double frame_start = seconds_since_start();
  handle_events();
  step_solve();
  session_->pump(kInlineSolveSeconds);  // an inline session solves between frames (a worker: no-op)
  const std::shared_ptr<const Snapshot> snapshot = session_->snapshot();
  handle_scene_mouse(*snapshot);
  panel_rects_.clear();
  panel_scrolls_.clear();
  panel_clips_.clear();
  if (options_.show_ui) draw_ui(*snapshot);
  ImGui::Render();
  draw(snapshot);
  ++frames_done_;
  if (options_.frames > 0 && frames_done_ >= options_.frames && !options_.screenshot_ui.empty())
    screenshot_ui_saved_ = save_window_picture(options_.screenshot_ui);  // the back buffer, panels included
  if (!window_picture_.empty()) {
    const Status saved = save_window_picture(window_picture_);
    set_message(saved ? "saved " + window_picture_ : saved.error().message);
    if (saved) deliver(window_picture_);
    window_picture_.clear();
  }
  impl_->window->swap();
  frame_seconds_.push_back(seconds_since_start() - frame_start);
  return !quit_;
}

void Viewer::handle_events() {
  for (const WindowEvent& event : impl_->window->poll_events()) handle_event(event);
  check_file_changed();  // a scene file changed on disk is an event too
  const auto [width, height] = impl_->window->drawable_size();
  // The docked layout: panels in the side columns, the scene fitted to the stage between them
  // (again whenever the stage changes, unless the user has zoomed or panned since the last fit).
  // The menu bar's height: ImGui's frame height, which it only knows after its first frame (the
  // default font is 13 pixels before it is loaded).
  const ImGuiIO& imgui_io = ImGui::GetIO();
  const float font =
      (imgui_io.Fonts->Fonts.empty() ? 13.0f : imgui_io.Fonts->Fonts[0]->FontSize) * imgui_io.FontGlobalScale;
  const float menu = options_.show_ui ? font + 2.0f * ImGui::GetStyle().FramePadding.y : 0.0f;
  // The key's strip: its caption, the colour bar with its tick labels, a note of up to two lines,
  // and on scenes with mirrors, glass or detectors their legend.
  const float key_lines = scene_->has_specular() ? 6.0f : 5.0f;
  const float key =
      options_.show_ui && (draw_.band || draw_.graph)
          ? key_lines * (font + ImGui::GetStyle().ItemSpacing.y) + 2.0f * ImGui::GetStyle().WindowPadding.y
          : 0.0f;
  // Presentation mode: the counter's band (its text at 1.5 times the font) and, with a curve
  // inspected, its B(s) in a column of a third of the width, all beside the stage.
  const bool inspected =
      draw_.selected_curve >= 0 && static_cast<std::size_t>(draw_.selected_curve) < scene_->curves.size();
  const StageLayout layout =
      presentation_ && options_.show_ui
          ? presentation_layout(width, height, menu, key,
                                1.5f * font + 2.0f * ImGui::GetStyle().WindowPadding.y + 4.0f * options_.ui_scale,
                                inspected ? 0.32f * static_cast<float>(width) : 0.0f)
          : stage_layout(width, height, options_.ui_scale, options_.show_ui && panels_visible_ && !presentation_, menu,
                         key);
  if (!(layout.stage == layout_.stage) && view_auto_) view_fitted_ = false;
  layout_ = layout;
  if (!view_fitted_) {
    view_ = fit_view(scene_->bounds, width, height, layout_.stage);
    view_fitted_ = true;
    view_auto_ = true;
  }
  view_.width = width;
  view_.height = height;

  impl_->window->new_imgui_frame();
  // Queued input (tests) replaces the device's for this frame.
  if (!queued_.empty()) {
    const QueuedInput input = queued_.front();
    queued_.erase(queued_.begin());
    if (input.key != 0) {
      handle_key(input.key, input.ctrl);
    } else {
      ImGuiIO& io = ImGui::GetIO();
      io.MousePos = ImVec2(input.x, input.y);
      io.MouseDown[0] = input.down;
    }
  }
  ImGui::NewFrame();
}

void Viewer::first_photons() {
  settings_.transport = Transport::Walk;
  settings_.importance.clear();  // walks refuse importance
  draw_.path_colour = PathColour::Bounce;
  draw_.paths = true;
  draw_.journey = true;
  draw_.fade = 0.6f;
  keep_slider_ = 24;
  session_->set_path_limit(24);
  session_->set_running(false);
  restart();
  slow_stepping_ = true;
  last_slow_step_ = -1e9;
  overlay_generation_ = ~0ull;
  set_message("first photons: one random walk every 0.8 s; Space runs, '.' steps");
}

void Viewer::step_solve() {
  if (slow_stepping_ && frame_step_.mode == FrameStep::Mode::Live) {
    if (session_->running()) {
      slow_stepping_ = false;  // Run takes over
    } else if (seconds_since_start() - last_slow_step_ >= kFirstPhotonsSeconds) {
      last_slow_step_ = seconds_since_start();
      session_->step(StepKind::Photon);
    }
  }
  // Deterministic stepping: this frame's steps are finished before it is drawn.
  switch (frame_step_.mode) {
    case FrameStep::Mode::Live: return;
    case FrameStep::Mode::Photons: session_->step(StepKind::Photon, frame_step_.count); break;
    case FrameStep::Mode::Batches: session_->step(StepKind::Batch, frame_step_.count); break;
    case FrameStep::Mode::Rounds: session_->step(StepKind::Round, frame_step_.count); break;
  }
  session_->wait_idle();
}

void Viewer::handle_scene_mouse(const Snapshot& snapshot) {
  const ImGuiIO& io = ImGui::GetIO();
  // Mouse on the scene (not on a panel): hover and drag control points, pick curves, pan.
  if (!io.WantCaptureMouse) {
    const Vec2 mouse{io.MousePos.x, io.MousePos.y};
    const std::vector<ControlPointRef> points = control_point_list(*scene_);
    hovered_point_ = -1;
    if (draw_.control_points && dragging_point_ < 0) {
      double best = 8.0;
      for (std::size_t i = 0; i < points.size(); ++i) {
        const double d = length(view_.to_pixels(points[i].position) - mouse);
        if (d <= best) {
          best = d;
          hovered_point_ = static_cast<int>(i);
        }
      }
    }
    // The curve under the mouse names itself and its material (click to inspect it).
    if (hovered_point_ < 0 && dragging_point_ < 0 && !panning_ && snapshot.traces) {
      if (const auto under = pick_curve(*snapshot.traces, view_, mouse); under && *under < scene_->curves.size()) {
        const Curve& curve = scene_->curves[*under];
        ImGui::SetTooltip("curve %u '%s': %s\n(click to inspect it)", *under, curve.id.c_str(),
                          material_words(*scene_, curve).c_str());
      }
    }
    if (ImGui::IsMouseClicked(ImGuiMouseButton_Left)) {
      if (hovered_point_ >= 0) {
        dragging_point_ = hovered_point_;
        edited_ = *scene_;
      } else if (snapshot.traces) {
        const auto picked = pick_curve(*snapshot.traces, view_, mouse);
        draw_.selected_curve = picked ? static_cast<int>(*picked) : -1;
        overlay_generation_ = ~0ull;
        panning_ = !picked;
      }
    }
    if (ImGui::IsMouseClicked(ImGuiMouseButton_Right) || ImGui::IsMouseClicked(ImGuiMouseButton_Middle))
      panning_ = true;
  }
  if (dragging_point_ >= 0) {
    if (ImGui::IsMouseDown(ImGuiMouseButton_Left)) {
      const std::vector<ControlPointRef> points = control_point_list(edited_);
      if (static_cast<std::size_t>(dragging_point_) < points.size()) {
        const ControlPointRef& ref = points[static_cast<std::size_t>(dragging_point_)];
        const Vec2 moved = view_.to_scene({io.MousePos.x, io.MousePos.y});
        if (!(edited_.curves[ref.curve].points[ref.index] == moved)) {
          edited_.curves[ref.curve].points[ref.index] = moved;
          edit_pending_ = true;
        }
      }
      // The solve restarts as the point moves, about ten times a second.
      if (seconds_since_start() - last_edit_time_ > 0.1) apply_edit();
    } else {
      apply_edit();
      dragging_point_ = -1;
    }
  }
  if (panning_) {
    if (ImGui::IsAnyMouseDown()) {
      const ImVec2 delta = io.MouseDelta;
      view_.center = view_.center - Vec2{delta.x / view_.scale, -delta.y / view_.scale};
      if (delta.x != 0.0f || delta.y != 0.0f) view_auto_ = false;
    } else {
      panning_ = false;
    }
  }
  if (draw_.hovered_control_point != (dragging_point_ >= 0 ? dragging_point_ : hovered_point_)) {
    draw_.hovered_control_point = dragging_point_ >= 0 ? dragging_point_ : hovered_point_;
    overlay_generation_ = ~0ull;
  }
}

void Viewer::draw(const std::shared_ptr<const Snapshot>& snapshot) {
  if (snapshot.get() != overlay_snapshot_.get()) overlay_generation_ = ~0ull;
  overlay_snapshot_ = snapshot;
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  // The window: the scene drawn on the stage only (the docked panels cover the rest).
  if (view_.width > 0 && view_.height > 0) render_scene(*snapshot, view_, &layout_.stage);
  impl_->window->render_imgui();
}

Status Viewer::save_window_picture(const std::string& path) {
  PngImage image{view_.width, view_.height, 4, Renderer::read_pixels(view_.width, view_.height)};
  for (std::size_t i = 3; i < image.pixels.size(); i += 4) image.pixels[i] = 255;
  return write_png(path, image, options_.cancel);
}

Status Viewer::save_screenshot(const std::string& path) {
  const auto [width, height] = impl_->window->drawable_size();
  if (width <= 0 || height <= 0) return Error{path + ": the window has no area to take a picture of"};
  if (Status made =
          Renderer::make_colour_framebuffer(width, height, impl_->screenshot_framebuffer, impl_->screenshot_colour);
      !made) {
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    return Error{path + ": " + made.error().message};
  }
  const std::shared_ptr<const Snapshot> snapshot = session_->snapshot();
  overlay_generation_ = ~0ull;
  // The scene without panels: the fitted view fits the whole picture; a zoomed or panned one is
  // kept as the user set it.
  ViewTransform view = view_auto_ ? fit_view(scene_->bounds, width, height) : view_;
  view.width = width;
  view.height = height;
  render_scene(*snapshot, view);
  PngImage image{width, height, 4, Renderer::read_pixels(width, height)};
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  for (std::size_t i = 3; i < image.pixels.size(); i += 4) image.pixels[i] = 255;
  return write_png(path, image, options_.cancel);
}

Status Viewer::run() {
  const double start = seconds_since_start();
  // Frame pacing: Mesa's software rasteriser draws on the same cores as the solver's threads, so
  // frames beyond what the eye needs are taken from the solve (docs/performance-log.md: unpaced, 44
  // frames/s at 0.49 of the headless photon rate; paced at 40 with late frames made up, 40
  // frames/s at 0.62).
  int max_fps = options_.max_fps;
  if (max_fps == 0) max_fps = software_renderer_ ? 40 : 0;
  const double period = max_fps > 0 ? 1.0 / max_fps : 0.0;
  double next_frame = start;
  while (frame()) {
    if (options_.frames > 0 && frames_done_ >= options_.frames) break;
    // A late frame is made up by the next ones drawn without a pause, so the rate averages
    // max_fps, but at most kPaceCatchUp behind: after a long stall (a window drag, a new scene)
    // at most that many seconds' frames follow without a pause, then the pace resumes.
    next_frame += period;
    const double now = seconds_since_start();
    if (next_frame > now)
      std::this_thread::sleep_for(std::chrono::duration<double>(next_frame - now));
    else
      next_frame = std::max(next_frame, now - kPaceCatchUp);
  }
  const double elapsed = seconds_since_start() - start;
  const std::shared_ptr<const Snapshot> snapshot = session_->snapshot();
  if (!screenshot_ui_saved_) return screenshot_ui_saved_;
  if (!options_.screenshot.empty())
    if (Status saved = save_screenshot(options_.screenshot); !saved) return saved;
  if (options_.report && !frame_seconds_.empty()) {
    std::vector<double> sorted = frame_seconds_;
    std::sort(sorted.begin(), sorted.end());
    const double median = sorted[sorted.size() / 2];
    std::printf("frames    %d in %.2f s: %.1f frames/s (median frame %.1f ms, slowest %.1f ms)\n", frames_done_,
                elapsed, frames_done_ / elapsed, 1e3 * median, 1e3 * sorted.back());
    std::printf("solve     %llu photons, %u rounds, %.3g photons/s while shooting; %zu paths on screen\n",
                static_cast<unsigned long long>(snapshot->progress.photons), snapshot->progress.rounds,
                snapshot->photons_per_second, path_layer_.drawn());
    if (snapshot->reference_error)
      std::printf("error     %.4g relative L2 of B against the reference\n", *snapshot->reference_error);
    const std::string link = link_query();
    std::printf("link      %s\n", link.empty() ? "(every setting at its default)" : link.c_str());
  }
  if (!message_.empty() && options_.frames > 0 && message_.rfind("loaded", 0) != 0)
    std::fprintf(stderr, "flatland view: %s\n", message_.c_str());
  return ok_status();
}

namespace {

// `text` as a URL query value: letters, digits and - _ . ~ , kept, every other byte as %XX (the
// options' names and numbers pass unchanged; importance's curve ids may hold any character).
std::string url_encoded(const std::string& text) {
  static const char kHex[] = "0123456789ABCDEF";
  std::string out;
  for (const char c : text) {
    const auto byte = static_cast<unsigned char>(c);
    if (std::isalnum(byte) != 0 || c == '-' || c == '_' || c == '.' || c == '~' || c == ',') {
      out += c;
    } else {
      out += '%';
      out += kHex[byte >> 4];
      out += kHex[byte & 15];
    }
  }
  return out;
}

}  // namespace

std::string Viewer::link_query() const {
  std::string query;
  const SolverSettings defaults = view_default_settings();
  const SolverSettings& settings = settings_;
  for (const SolveOptionSpec& spec : solve_options()) {
    if (spec.option == SolveOption::Threads) continue;
    const std::string value = solve_option_text(settings, spec.option);
    if (value == solve_option_text(defaults, spec.option)) continue;
    std::string_view flag = spec.flag;
    while (!flag.empty() && flag.front() == '-') flag.remove_prefix(1);
    query += (query.empty() ? "" : "&") + std::string(flag) + "=" + url_encoded(value);
  }
  const int curve = selected_curve();
  if (curve >= 0 && static_cast<std::size_t>(curve) < scene().curves.size())
    query += (query.empty() ? "select=" : "&select=") + std::to_string(curve);
  if (presentation()) query += query.empty() ? "present=1" : "&present=1";
  // A lesson's view: the First photons preset while it steps, and the paths' colouring and count
  // where they differ from the defaults (view::ViewOptions).
  auto add = [&](const std::string& item) { query += (query.empty() ? "" : "&") + item; };
  if (slow_stepping()) add("first-photons=1");
  const ViewOptions view_defaults;
  if (paths_kept() != view_defaults.keep_paths) add("keep-paths=" + std::to_string(paths_kept()));
  if (path_colour() == PathColour::Round) add("colour-by=round");
  if (path_colour() == PathColour::Bounce && !slow_stepping()) add("colour-by=bounce");
  if (light_view() == LightView::Paths) add("light=paths");
  if (light_view() == LightView::Field) add("light=field");
  return query;
}

}  // namespace flatland::viewer
