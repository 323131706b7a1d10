// The viewer's panels (Dear ImGui): menu, solve controls, display options, status, the inspected
// curve, help. They read the snapshot and change the viewer's settings; the main loop is in
// viewer_app.cpp.
#include <imgui.h>
#include <imgui_internal.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "flatland/base/text.hpp"
#include "viewer/viewer_app.hpp"
#include "viewer/window.hpp"

namespace flatland::viewer {

namespace {

const char* continuity_name(Continuity c) { return c == Continuity::Jump ? "C-1" : c == Continuity::C0 ? "C0" : "C1"; }

const char* const kHelp[][2] = {
    {"Space", "run / pause"},
    {".", "step one photon"},
    {"B", "step one batch (4096 photons)"},
    {"R", "step one round"},
    {"Backspace", "reset (restart the solve)"},
    {"F", "fit the scene to the stage (the space between the panels)"},
    {"Tab", "hide or show the panels (the scene takes the whole window)"},
    {"M", "presentation mode: the stage takes the window, with the counter above, B(s) beside, the key under it"},
    {"C", "show control points (drag them to edit)"},
    {"N", "show storage nodes"},
    {"G", "graph of B along the normals"},
    {"K", "colour band of B"},
    {"P", "photon paths"},
    {"+ / -", "path exposure"},
    {"Ctrl+S", "save a screenshot (PNG, the whole window with its legends)"},
    {"1", "first photons: random walks stepped slowly, coloured by bounce"},
    {"Ctrl+E", "save the result (JSON, as solve --out)"},
    {"F5", "reload the scene file"},
    {"F1 / H", "this help"},
    {"Esc", "quit"},
    {"Mouse",
     "wheel: zoom; right or middle drag, or left drag on empty space: pan; click a "
     "curve: inspect it"},
};

}  // namespace

namespace {

// A step of 1, 2 or 5 times a power of ten, near span / 4: the axis ticks of a plot; 0 where there
// is nothing to tick (a span that is not a positive finite number, or too small to divide).
double nice_step(double span) {
  if (!(span > 0.0) || !std::isfinite(span)) return 0.0;
  const double raw = span / 4.0;
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  if (!(decade > 0.0) || !std::isfinite(decade)) return 0.0;
  const double f = raw / decade;
  return decade * (f < 1.5 ? 1.0 : f < 3.5 ? 2.0 : f < 7.5 ? 5.0 : 10.0);
}

// The ticks 0, step, 2 step, ... up to `span` (none when nice_step found no step; at most 12).
std::vector<double> ticks(double span) {
  std::vector<double> values;
  const double step = nice_step(span);
  if (step > 0.0)
    for (int i = 0; i <= 12 && i * step <= span * (1.0 + 1e-9); ++i) values.push_back(i * step);
  return values;
}

ImU32 to_u32(const std::array<float, 3>& c, float alpha = 1.0f) {
  return ImGui::ColorConvertFloat4ToU32(ImVec4(c[0], c[1], c[2], alpha));
}

}  // namespace

bool Viewer::option_combo(SolveOption option) {
  // The option's names as the command line and Python take them (options.hpp).
  const SolveOptionSpec& spec = spec_of(option);
  std::vector<std::string> names(spec.choices.begin(), spec.choices.end());
  std::vector<const char*> pointers;
  int index = 0;
  const std::string current = solve_option_text(settings_, option);
  for (std::size_t i = 0; i < names.size(); ++i) {
    pointers.push_back(names[i].c_str());
    if (names[i] == current) index = static_cast<int>(i);
  }
  const std::string label(spec.name);
  if (!combo(label.c_str(), &index, pointers.data(), static_cast<int>(pointers.size()))) return false;
  return set_solve_option(settings_, option, names[static_cast<std::size_t>(index)]).ok();
}

bool Viewer::combo(const char* label, int* index, const char* const* names, int count) {
  bool changed = false;
  const bool open = ImGui::BeginCombo(label, names[std::clamp(*index, 0, count - 1)]);
  track(label);
  if (open) {
    for (int i = 0; i < count; ++i) {
      if (ImGui::Selectable(names[i], i == *index) && i != *index) {
        *index = i;
        changed = true;
      }
      track((std::string(label) + ":" + names[i]).c_str());
    }
    ImGui::EndCombo();
  }
  return changed;
}

void Viewer::track(const char* label) {
  const ImVec2 lo = ImGui::GetItemRectMin();
  const ImVec2 hi = ImGui::GetItemRectMax();
  widget_rects_[label] = {lo.x, lo.y, hi.x, hi.y};
}

void Viewer::record_panel(const char* name) {
  const ImVec2 position = ImGui::GetWindowPos();
  const ImVec2 size = ImGui::GetWindowSize();
  panel_rects_[name] = {position.x, position.y, position.x + size.x, position.y + size.y};
  panel_scrolls_[name] = ImGui::GetScrollMaxY() > 0.0f;
  // Content wider than the panel (as of the last frame) is cut off at its right edge.
  const ImGuiWindow* window = ImGui::GetCurrentWindow();
  panel_clips_[name] = window->ContentSize.x > window->ContentRegionRect.GetWidth() + 1.0f;
}

namespace {

// Docked panels: placed by the layout every frame, not moved or resized by hand (a title bar
// click still folds one away).
constexpr ImGuiWindowFlags kDocked = ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize;
// Overlays on the stage: no title, not moved by hand.
constexpr ImGuiWindowFlags kOverlay = ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_NoMove |
                                      ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoFocusOnAppearing;

// Widgets as wide as the panel leaves beside the longest of its labels, so labels are never cut
// off at any size or scale (the widgets narrow instead). Pop with ImGui::PopItemWidth.
void push_width_beside(const char* longest_label) {
  ImGui::PushItemWidth(-(ImGui::CalcTextSize(longest_label).x + ImGui::GetStyle().ItemInnerSpacing.x + 2.0f));
}

// The next panel at the top of what is left of `column` below `above` (its y1; the column's top
// for the first panel), as wide as the column; its height follows its content up to what is left.
void dock_next(const PixelRect& column, float above) {
  const float top = std::max(column.y0, above);
  ImGui::SetNextWindowPos(ImVec2(column.x0, top), ImGuiCond_Always);
  ImGui::SetNextWindowSizeConstraints(ImVec2(column.width(), 0.0f),
                                      ImVec2(column.width(), std::max(column.y1 - top, 40.0f)));
}

}  // namespace

void Viewer::draw_ui(const Snapshot& snapshot) {
  draw_menu(snapshot);
  const bool selected =
      draw_.selected_curve >= 0 && static_cast<std::size_t>(draw_.selected_curve) < scene_->curves.size();
  if (panels_visible_ && !presentation_) {
    draw_solve_panel(snapshot);
    draw_status_panel(snapshot);
    draw_display_panel();  // under Solve, or under Status when only that has room
    if (selected) draw_curve_panel(snapshot);
  }
  if (presentation_) {
    draw_counter_overlay(snapshot);
    if (selected) draw_curve_overlay(snapshot);
  }
  if (layout_.key.height() > 0.0f) draw_key_strip(snapshot);
  if (show_help_) draw_help_panel();
  // The newest journey's hops, numbered at their middles (the overlay draws the hops themselves).
  if (draw_.paths && draw_.journey) {
    const auto [first, end] = newest_journey(snapshot.paths);
    ImDrawList* draw = ImGui::GetBackgroundDrawList();
    for (std::size_t i = first; i < end && end - first > 1; ++i) {
      const PathRecord& hop = snapshot.paths[i];
      const Vec2 mid = view_.to_pixels(hop.from + 0.4 * (hop.to - hop.from));
      char label[16];
      std::snprintf(label, sizeof label, "%zu", i - first + 1);
      const ImVec2 size = ImGui::CalcTextSize(label);
      const ImVec2 at(static_cast<float>(mid.x) - 0.5f * size.x, static_cast<float>(mid.y) - 0.5f * size.y);
      draw->AddRectFilled(ImVec2(at.x - 3.0f, at.y - 1.0f), ImVec2(at.x + size.x + 3.0f, at.y + size.y + 1.0f),
                          IM_COL32(0, 0, 0, 200), 3.0f);
      const std::array<float, 3> c = path_palette(hop.bounce);
      draw->AddText(at, to_u32(c), label);
    }
  }
  if (!message_.empty() && seconds_since_start() - message_time_ < 8.0) {
    ImGui::SetNextWindowPos(ImVec2(0.5f * (layout_.stage.x0 + layout_.stage.x1), layout_.stage.y1 - 10.0f),
                            ImGuiCond_Always, ImVec2(0.5f, 1.0f));
    ImGui::SetNextWindowBgAlpha(0.8f);
    ImGui::Begin("##message", nullptr,
                 ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_AlwaysAutoResize | ImGuiWindowFlags_NoInputs);
    ImGui::TextUnformatted(message_.c_str());
    ImGui::End();
  }
}

void Viewer::draw_menu(const Snapshot& snapshot) {
  (void)snapshot;
  if (!ImGui::BeginMainMenuBar()) return;
  if (ImGui::BeginMenu("File")) {
    track("File");
    if (ImGui::BeginMenu("Open scene")) {
      std::vector<std::string> files;
      const std::filesystem::path directory = std::filesystem::path(default_scene_path()).parent_path();
      std::error_code error;
      for (const auto& entry : std::filesystem::directory_iterator(directory, error))
        if (entry.path().extension() == ".json") files.push_back(entry.path().string());
      std::sort(files.begin(), files.end());
      for (const std::string& file : files)
        if (ImGui::MenuItem(std::filesystem::path(file).filename().string().c_str(), nullptr, file == scene_path_))
          load_scene_file(file);
      ImGui::EndMenu();
    }
    if (ImGui::MenuItem("Reload scene", "F5")) load_scene_file(scene_path_);
    if (ImGui::MenuItem("Save screenshot", "Ctrl+S")) handle_key('s', true);
    if (ImGui::MenuItem("Save scene picture (no panels)")) {
      const std::string name = "flatland-" + scene_->name + "-scene.png";
      const Status saved = save_screenshot(name);
      set_message(saved ? "saved " + name : saved.error().message);
      if (saved) deliver(name);
    }
    if (ImGui::MenuItem("Save result", "Ctrl+E")) handle_key('e', true);
    if (Window::closable() && ImGui::MenuItem("Quit", "Esc")) quit_ = true;
    ImGui::EndMenu();
  }
  if (ImGui::BeginMenu("View")) {
    if (ImGui::MenuItem("Fit scene", "F")) view_fitted_ = false;
    if (ImGui::MenuItem("Presentation mode", "M", presentation_)) handle_key('m', false);
    if (ImGui::MenuItem("Panels", "Tab", panels_visible_)) panels_visible_ = !panels_visible_;
    if (ImGui::MenuItem("First photons (lecture preset)", "1")) first_photons();
    ImGui::EndMenu();
  }
  if (ImGui::MenuItem("Help")) show_help_ = !show_help_;
  ImGui::EndMainMenuBar();
}

void Viewer::draw_solve_panel(const Snapshot& snapshot) {
  dock_next(layout_.left, layout_.left.y0);
  ImGui::Begin("Solve", nullptr, kDocked | ImGuiWindowFlags_AlwaysAutoResize);
  record_panel("Solve");
  push_width_beside("discontinuities");
  const bool running = session_->running();
  // A stopped solve (converged, budget spent) cannot run on: Reset or a new setting starts over.
  const bool stopped = snapshot.stop_reason != StopReason::Running;
  ImGui::BeginDisabled(stopped);
  if (ImGui::Button(running ? "Pause" : "Run", ImVec2(60, 0))) session_->set_running(!running);
  ImGui::EndDisabled();
  track("Run");
  ImGui::SameLine();
  if (ImGui::Button("Reset")) restart();
  track("Reset");
  if (ImGui::Button("Photon")) {
    slow_stepping_ = false;
    session_->step(StepKind::Photon);
  }
  track("Photon");
  ImGui::SameLine();
  if (ImGui::Button("Batch")) {
    slow_stepping_ = false;
    session_->step(StepKind::Batch);
  }
  track("Batch");
  ImGui::SameLine();
  if (ImGui::Button("Round")) {
    slow_stepping_ = false;
    session_->step(StepKind::Round);
  }
  track("Round");
  ImGui::SameLine();
  if (ImGui::Button("First photons")) first_photons();
  track("First photons");
  if (ImGui::IsItemHovered())
    ImGui::SetTooltip(
        "A lecture preset: random walks, one every %.1f s, coloured by bounce,\n"
        "the newest journey on top (Space runs on, '.' steps by hand)",
        kFirstPhotonsSeconds);
  ImGui::Separator();

  bool changed = false;
  char budget[32];
  std::snprintf(budget, sizeof budget, "%s", budget_text_.c_str());
  if (ImGui::InputText("photons", budget, sizeof budget, ImGuiInputTextFlags_EnterReturnsTrue)) {
    budget_text_ = budget;
    Result<std::uint64_t> photons = parse_whole_number(budget_text_, "photons");
    if (photons) {
      settings_.photons = *photons;
      changed = true;
    } else {
      set_message(photons.error().message);
    }
  }
  int seed = static_cast<int>(settings_.seed);
  if (ImGui::InputInt("seed", &seed) && seed >= 0) {
    settings_.seed = static_cast<std::uint64_t>(seed);
    changed = true;
  }
  int threads = static_cast<int>(settings_.threads);
  if (ImGui::SliderInt("threads", &threads, 0, 16, threads == 0 ? "all" : "%d")) {
    settings_.threads = static_cast<unsigned>(threads);
    changed = true;
  }
  changed = option_combo(SolveOption::Basis) || changed;
  bool auto_elements = settings_.elements == kAutoElements;
  if (ImGui::Checkbox("auto elements", &auto_elements)) {
    settings_.elements = auto_elements ? kAutoElements : 16;
    changed = true;
  }
  if (!auto_elements) {
    int elements = settings_.elements;
    if (ImGui::SliderInt("elements", &elements, 1, 256, "%d", ImGuiSliderFlags_Logarithmic)) {
      settings_.elements = elements;
      changed = true;
    }
  }
  changed = option_combo(SolveOption::Sampling) || changed;
  changed = option_combo(SolveOption::Discontinuities) || changed;
  changed = option_combo(SolveOption::Estimator) || changed;
  changed = option_combo(SolveOption::Transport) || changed;
  if (ImGui::IsItemHovered())
    ImGui::SetTooltip(
        "shooting: rounds of one hop each (the paper's method)\n"
        "walk: each photon a whole random walk, ended by Russian roulette");
  // Ray width as a fraction of the scene's size; profile and mode only matter for wide rays.
  float width = static_cast<float>(settings_.ray_width / scene_->scale);
  if (ImGui::SliderFloat("ray width", &width, 0.0f, 0.2f, width == 0.0f ? "point rays" : "%.4f x scale",
                         ImGuiSliderFlags_Logarithmic)) {
    settings_.ray_width = static_cast<double>(width) * scene_->scale;
    changed = true;
  }
  if (settings_.ray_width > 0.0) {
    changed = option_combo(SolveOption::RayProfile) || changed;
    changed = option_combo(SolveOption::RayMode) || changed;
    if (settings_.ray_mode == RayMode::Band && ImGui::SliderInt("band rays", &settings_.band_rays, 1, 64))
      changed = true;
  }
  // Solve to an accuracy: 0 (off) or a relative L1 error of B - E; the photon budget is the cap.
  float target = static_cast<float>(settings_.target_error);
  if (ImGui::SliderFloat("target error", &target, 0.0f, 0.1f, target == 0.0f ? "off" : "%.0e",
                         ImGuiSliderFlags_Logarithmic)) {
    settings_.target_error = static_cast<double>(target);
    changed = true;
  }
  if (ImGui::IsItemHovered())
    ImGui::SetTooltip(
        "Keep shooting until the estimated relative L1 error of B - E is at most this\n"
        "(the photon budget is the cap); off: the budget and tolerance decide");
  float tolerance = static_cast<float>(settings_.tolerance);
  if (ImGui::SliderFloat("tolerance", &tolerance, 1e-6f, 0.1f, "%.0e", ImGuiSliderFlags_Logarithmic)) {
    settings_.tolerance = static_cast<double>(tolerance);
    changed = true;
  }
  if (changed) {
    if (Status valid = validate(settings_); valid)
      restart();
    else
      set_message(valid.error().message);
  }
  if (!snapshot.error.empty()) ImGui::TextColored(ImVec4(1, 0.4f, 0.4f, 1), "%s", snapshot.error.c_str());
  ImGui::PopItemWidth();
  ImGui::End();
}

// The key of the band's colours: the colour scale from 0 to the band's range with its values,
// in the units of B (power per unit length, in the scene's emittance units).
void Viewer::draw_colour_key(const Snapshot& snapshot) {
  if (!snapshot.scene) return;
  const int channels = snapshot.scene->channels;
  const double range = radiosity_range(snapshot, draw_.channel) / std::max(draw_.band_exposure, 1e-6f);
  ImGui::TextUnformatted("band colour = B, power per unit length");
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const ImVec2 origin = ImGui::GetCursorScreenPos();
  const float width = ImGui::GetContentRegionAvail().x;
  const float height = ImGui::GetTextLineHeight();
  ImGui::InvisibleButton("##colour key", ImVec2(width, height));
  track("colour key");
  const int steps = 48;
  for (int i = 0; i < steps; ++i) {
    // The band's own mapping at B = (i + 0.5) / steps x range (grey level for colour scenes).
    const double b = (i + 0.5) / steps * range;
    const std::array<float, 3> colour = radiosity_colour({b, b, b}, range, channels, draw_.channel);
    const float x0 = origin.x + width * static_cast<float>(i) / steps;
    draw->AddRectFilled(ImVec2(x0, origin.y), ImVec2(x0 + width / steps + 0.5f, origin.y + height), to_u32(colour));
  }
  for (const double v : ticks(range)) {
    const float x = origin.x + width * static_cast<float>(v / range);
    draw->AddLine(ImVec2(x, origin.y + height), ImVec2(x, origin.y + height + 4.0f), IM_COL32(220, 220, 220, 255));
    char label[32];
    std::snprintf(label, sizeof label, "%.3g", v);
    const float text_width = ImGui::CalcTextSize(label).x;
    draw->AddText(
        ImVec2(std::clamp(x - 0.5f * text_width, origin.x, origin.x + width - text_width), origin.y + height + 4.0f),
        IM_COL32(220, 220, 220, 255), label);
  }
  ImGui::Dummy(ImVec2(width, ImGui::GetTextLineHeight() + 6.0f));
  ImGui::PushStyleColor(ImGuiCol_Text, ImGui::GetStyle().Colors[ImGuiCol_TextDisabled]);
  ImGui::TextWrapped(channels == 3 && draw_.channel == ChannelView::All
                         ? "each channel 1 - exp(-2 B / %.3g); emitters saturate"
                         : "scale: the 99th percentile of B off the emitters, %.3g",
                     range);
  ImGui::PopStyleColor();
  draw_materials_legend(*snapshot.scene);
}

// The materials that hold no light, in the colours the stage draws them in: each mirror, glass
// (with its index) and detector material once, on one line (the key strip keeps a line for it).
void Viewer::draw_materials_legend(const Scene& scene) {
  if (!scene.has_specular()) return;
  std::vector<std::uint32_t> shown;  // material indices
  bool first = true;
  for (const Curve& curve : scene.curves) {
    const Material& material = scene.material_of(curve);
    if (material.optics == Optics::Diffuse) continue;
    if (std::find(shown.begin(), shown.end(), curve.material) != shown.end()) continue;
    shown.push_back(curve.material);
    const std::array<float, 4> c = optics_colour(material.optics);
    const std::string words = "-- " + material.name + ": " + material_words(scene, curve);
    if (!first) {
      ImGui::SameLine();
      if (ImGui::GetContentRegionAvail().x < ImGui::CalcTextSize(words.c_str()).x) break;  // one line only
    }
    ImGui::TextColored(ImVec4(c[0], c[1], c[2], c[3]), "%s", words.c_str());
    first = false;
  }
}

void Viewer::draw_display_panel() {
  // Under Solve in the left column; where that leaves too little height for it (large type on a
  // projector) and the right column has it under Status, there, with the inspected curve below.
  const auto solve = panel_rects_.find("Solve");
  const auto status = panel_rects_.find("Status");
  const float left_top = solve != panel_rects_.end() ? solve->second.y1 : layout_.left.y0;
  const float right_top = status != panel_rects_.end() ? status->second.y1 : layout_.right.y0;
  display_on_right_ = display_height_ > 0.0f && left_top + display_height_ > layout_.left.y1 &&
                      right_top + display_height_ <= layout_.right.y1;
  if (display_on_right_)
    dock_next(layout_.right, right_top);
  else
    dock_next(layout_.left, left_top);
  ImGui::Begin("Display", nullptr, kDocked | ImGuiWindowFlags_AlwaysAutoResize);
  record_panel("Display");
  {
    // Its whole height as of the last frame, for the choice above.
    const ImGuiWindow* window = ImGui::GetCurrentWindow();
    display_height_ = window->ContentSize.y + window->TitleBarHeight() + 2.0f * ImGui::GetStyle().WindowPadding.y;
  }
  push_width_beside("path exposure");
  bool changed = false;
  changed |= ImGui::Checkbox("band", &draw_.band);
  ImGui::SameLine();
  changed |= ImGui::Checkbox("graph", &draw_.graph);
  if (ImGui::IsItemHovered())
    ImGui::SetTooltip(
        "B drawn as a graph along each lit side's normal: a side's curve is its\n"
        "baseline, the graph's height is proportional to B (graph height = the key's end)");
  ImGui::SameLine();
  changed |= ImGui::Checkbox("paths", &draw_.paths);
  changed |= ImGui::Checkbox("control points", &draw_.control_points);
  ImGui::SameLine();
  changed |= ImGui::Checkbox("nodes", &draw_.storage_nodes);
  changed |= ImGui::Checkbox("discontinuities", &draw_.discontinuities);
  changed |= ImGui::SliderFloat("B exposure", &draw_.band_exposure, 0.1f, 10.0f, "%.2f", ImGuiSliderFlags_Logarithmic);
  changed |= ImGui::SliderFloat("graph height", &draw_.graph_height, 10.0f, 200.0f, "%.0f px");
  if (scene_->channels == 3) {
    int channel = static_cast<int>(draw_.channel);
    const char* const names[] = {"all (colour)", "red", "green", "blue"};
    changed |= combo("channel", &channel, names, 4);
    draw_.channel = static_cast<ChannelView>(channel);
  }
  if (draw_.paths) {
    changed |= ImGui::Checkbox("newest journey", &draw_.journey);
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip(
          "The newest photon on top of the kept paths: hops numbered and coloured by\n"
          "bounce, an arrow for the direction, a white square where it landed, a red\n"
          "cross where a walk was absorbed (--transport walk shows whole journeys)");
    ImGui::SliderFloat("path exposure", &draw_.path_exposure, 0.05f, 50.0f, "%.2f", ImGuiSliderFlags_Logarithmic);
    float keep = static_cast<float>(keep_slider_);
    if (ImGui::SliderFloat("paths kept", &keep, 0.0f, 200000.0f, "%.0f", ImGuiSliderFlags_Logarithmic)) {
      keep_slider_ = std::round(keep);
      session_->set_path_limit(static_cast<std::size_t>(keep_slider_));
    }
    ImGui::SliderFloat("fade by age", &draw_.fade, 0.0f, 3.0f, "%.2f");
    int colour = static_cast<int>(draw_.path_colour);
    const char* const names[] = {"power", "round", "bounce"};
    combo("colour by", &colour, names, 3);
    if (draw_.path_colour != PathColour::Power) {
      // The palette's key: which colour is which round or bounce (it repeats after six).
      const char* const what = draw_.path_colour == PathColour::Round ? "round" : "bounce";
      for (std::uint32_t i = 0; i < 6; ++i) {
        const std::array<float, 3> c = path_palette(i);
        if (i > 0) ImGui::SameLine();
        ImGui::TextColored(ImVec4(c[0], c[1], c[2], 1.0f), "%s%u", i == 0 ? what : "", i);
      }
      ImGui::TextDisabled("(the colours repeat after 6)");
    }
    draw_.path_colour = static_cast<PathColour>(colour);
  }
  if (changed) overlay_generation_ = ~0ull;
  ImGui::PopItemWidth();
  ImGui::End();
}

// The colour key in its strip under the stage (StageLayout::key), in view whatever the panels do.
void Viewer::draw_key_strip(const Snapshot& snapshot) {
  ImGui::SetNextWindowPos(ImVec2(layout_.key.x0, layout_.key.y0), ImGuiCond_Always);
  ImGui::SetNextWindowSize(ImVec2(layout_.key.width(), layout_.key.height()), ImGuiCond_Always);
  ImGui::Begin("##key", nullptr, kOverlay | ImGuiWindowFlags_NoScrollbar);
  record_panel("Key");
  draw_colour_key(snapshot);
  ImGui::End();
}

// Presentation mode: the photon counter, large, in its band above the stage.
void Viewer::draw_counter_overlay(const Snapshot& snapshot) {
  ImGui::SetNextWindowPos(ImVec2(layout_.counter.x0, layout_.counter.y0), ImGuiCond_Always);
  ImGui::SetNextWindowSize(ImVec2(layout_.counter.width(), layout_.counter.height()), ImGuiCond_Always);
  ImGui::Begin("##counter", nullptr, kOverlay | ImGuiWindowFlags_NoInputs | ImGuiWindowFlags_NoScrollbar);
  record_panel("Counter");
  ImGui::SetWindowFontScale(1.5f);
  const char* state = snapshot.stop_reason != StopReason::Running ? "finished"
                      : session_->running()                       ? "running"
                                                                  : "paused";
  ImGui::Text("%s   %.3g photons   round %u   %s", scene_->name.c_str(), static_cast<double>(snapshot.progress.photons),
              snapshot.progress.rounds + (snapshot.round_photons > 0 ? 1 : 0), state);
  ImGui::End();
}

// Presentation mode: the inspected curve's B(s) in its column beside the stage.
void Viewer::draw_curve_overlay(const Snapshot& snapshot) {
  const auto c = static_cast<std::size_t>(draw_.selected_curve);
  ImGui::SetNextWindowPos(ImVec2(layout_.right.x0, layout_.right.y0), ImGuiCond_Always);
  ImGui::SetNextWindowSize(ImVec2(layout_.right.width(), layout_.right.height()), ImGuiCond_Always);
  ImGui::Begin("##curve plot", nullptr, kOverlay);
  record_panel("Curve plot");
  ImGui::Text("curve %zu '%s': B against arc length", c, scene_->curves[c].id.c_str());
  draw_curve_plot(snapshot, c, false);
  ImGui::End();
}

void Viewer::draw_status_panel(const Snapshot& snapshot) {
  dock_next(layout_.right, layout_.right.y0);
  ImGui::Begin("Status", nullptr, kDocked | ImGuiWindowFlags_AlwaysAutoResize);
  record_panel("Status");
  ImGui::Text("scene    %s (%s)", scene_->name.c_str(), scene_->channels == 1 ? "grey" : "colour");
  ImGui::Text("photons  %llu of %llu", static_cast<unsigned long long>(snapshot.progress.photons),
              static_cast<unsigned long long>(settings_.photons));
  ImGui::Text("rounds   %u%s", snapshot.progress.rounds, snapshot.round_photons > 0 ? " (+ one open)" : "");
  if (snapshot.round_photons > 0)
    ImGui::ProgressBar(static_cast<float>(snapshot.round_done) / static_cast<float>(snapshot.round_photons),
                       ImVec2(-1, 0), "open round");
  ImGui::Text("rate     %.3g photons/s", snapshot.photons_per_second);
  ImGui::Text("state    %s", snapshot.stop_reason != StopReason::Running ? to_string(snapshot.stop_reason)
                             : session_->running()                       ? "running"
                                                                         : "paused");
  const EnergyBooks& books = snapshot.books;
  if (books.emitted > 0.0) {
    ImGui::Text("emitted  %.6g", books.emitted);
    ImGui::Text("absorbed %.6g  escaped %.6g", books.absorbed, books.escaped);
    ImGui::Text("unshot   %.6g (%.3g%%)", books.unshot, 100.0 * books.unshot / books.emitted);
    if (scene_->has_specular())
      ImGui::Text("mirrors  %.6g  glass %.6g  cut %.6g", books.absorbed_mirrors, books.absorbed_glass, books.cut);
    ImGui::Text("balance  %.2g", books.imbalance());
  }
  if (snapshot.estimated_error && snapshot.estimated_error->available) {
    const ErrorEstimate& estimate = *snapshot.estimated_error;
    if (estimate.bounded)
      ImGui::Text("error    <= %.2g %% (estimated, %g %%)", 100.0 * estimate.bound.l1, 100.0 * estimate.confidence);
    else
      ImGui::Text("error    not bounded yet");
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip(
          "Upper bound of the relative L1 error of B - E over the scene at %g %% confidence\n"
          "noise %.2g %%, storage %s, unshot %.2g %%%s%s",
          100.0 * estimate.confidence, 100.0 * estimate.noise.l1,
          estimate.storage_estimated ? (format_number(100.0 * estimate.storage.l1, 2) + " %").c_str() : "not estimated",
          100.0 * estimate.unshot.l1, estimate.caveat.empty() ? "" : "\n", estimate.caveat.c_str());
    if (settings_.target_error > 0.0)
      ImGui::Text("target   %.2g %%%s", 100.0 * settings_.target_error,
                  snapshot.stop_reason == StopReason::TargetReached ? " (reached)" : "");
  }
  if (snapshot.reference_error) {
    ImGui::Separator();
    ImGui::Text("error    %.4f (relative L2 of B vs reference)", *snapshot.reference_error);
    if (snapshot.error_history.size() >= 2) {
      // log10 error against elapsed time, drawn with ImGui's own primitives.
      ImDrawList* draw = ImGui::GetWindowDrawList();
      const ImVec2 origin = ImGui::GetCursorScreenPos();
      const ImVec2 size(ImGui::GetContentRegionAvail().x, 90.0f);
      ImGui::InvisibleButton("##errorplot", size);
      draw->AddRectFilled(origin, ImVec2(origin.x + size.x, origin.y + size.y), IM_COL32(30, 30, 40, 255));
      double lo = INFINITY;
      double hi = -INFINITY;
      for (const auto& point : snapshot.error_history) {
        const double e = std::log10(std::max(point[1], 1e-12));
        lo = std::min(lo, e);
        hi = std::max(hi, e);
      }
      if (hi - lo < 0.5) {
        lo -= 0.25;
        hi += 0.25;
      }
      const double t_end = std::max(snapshot.error_history.back()[0], 1e-9);
      ImVec2 previous{};
      for (std::size_t i = 0; i < snapshot.error_history.size(); ++i) {
        const auto& point = snapshot.error_history[i];
        const double e = std::log10(std::max(point[1], 1e-12));
        const ImVec2 p(origin.x + static_cast<float>(point[0] / t_end) * size.x,
                       origin.y + static_cast<float>((hi - e) / (hi - lo)) * size.y);
        if (i > 0) draw->AddLine(previous, p, IM_COL32(255, 200, 80, 255), 1.5f);
        previous = p;
      }
      ImGui::Text("log10 error %.2f .. %.2f over %.2f s of solving", lo, hi, t_end);
    }
  }
  ImGui::End();
}

namespace {

// The inspected curve's facts: material, emission, geometry and its share of the reflected power.
void draw_curve_facts(const Scene& scene, const Snapshot& snapshot, std::size_t c) {
  const Curve& curve = scene.curves[c];
  const Material& material = scene.material_of(curve);
  ImGui::TextWrapped("curve    %zu '%s'", c, curve.id.c_str());
  switch (material.optics) {
    case Optics::Diffuse:
      ImGui::TextWrapped("material %s: rho %.3g %.3g %.3g", material.name.c_str(), material.reflectivity[0],
                         material.reflectivity[1], material.reflectivity[2]);
      if (material.spectrum) {
        const EmitterSpectrum& sp = *material.spectrum;
        if (sp.kind == EmitterSpectrum::Kind::Blackbody)
          ImGui::TextWrapped("spectrum black body at %.0f K", sp.kelvin);
        else if (sp.kind == EmitterSpectrum::Kind::Line)
          ImGui::TextWrapped("spectrum a line at %.1f nm", sp.line);
        else
          ImGui::TextWrapped("spectrum a table of %zu points", sp.points.size());
      }
      break;
    case Optics::Mirror:
      ImGui::TextWrapped("material %s: mirror, reflectance %.3g %.3g %.3g", material.name.c_str(),
                         material.reflectance[0], material.reflectance[1], material.reflectance[2]);
      break;
    case Optics::Dielectric: {
      // The index at 450 and 650 nm (equal without dispersion) and the critical angle at the d line.
      const double front = material.ior.at(kGreyWavelength);
      const double high = std::max(front, material.ior_back), low = std::min(front, material.ior_back);
      ImGui::TextWrapped("material %s: dielectric, n %.4g (450 nm) .. %.4g (650 nm) in front, %.4g behind",
                         material.name.c_str(), material.ior.at(0.45), material.ior.at(0.65), material.ior_back);
      if (high > low)
        ImGui::TextWrapped("critical angle %.2f degrees (total internal reflection beyond it, from the n = %.4g side)",
                           std::asin(low / high) * 180.0 / 3.14159265358979323846, high);
      break;
    }
    case Optics::Detector:
      ImGui::TextWrapped("material %s: detector, %u bins", material.name.c_str(), material.detector_bins);
      break;
  }
  if (scene.is_emitter(curve))
    ImGui::TextWrapped("emits    %.3g %.3g %.3g per unit length", curve.emittance[0], curve.emittance[1],
                       curve.emittance[2]);
  ImGui::TextWrapped("length   %.6g, %u %s segment%s, sides %s", curve.length, curve.segment_count,
                     curve.kind == SegmentKind::Line ? "straight" : "cubic", curve.segment_count == 1 ? "" : "s",
                     curve.sides == Sides::Both    ? "both"
                     : curve.sides == Sides::Front ? "front"
                                                   : "back");
  if (c < snapshot.received_share.size())
    ImGui::TextWrapped("share    %.2f%% of all reflected power", 100.0 * snapshot.received_share[c]);
}

// The storage nodes of curve `c` under a folding header (nothing while it has none).
void draw_node_list(const Snapshot& snapshot, std::size_t c) {
  if (c >= snapshot.nodes.size() || snapshot.nodes[c].empty()) return;
  const std::vector<NodeMark>& nodes = snapshot.nodes[c];
  std::size_t below_c1 = 0;
  for (const NodeMark& node : nodes) below_c1 += node.continuity == Continuity::C1 ? 0 : 1;
  char header[96];
  std::snprintf(header, sizeof header, "%zu storage nodes, %zu below C1###nodes", nodes.size(), below_c1);
  if (ImGui::CollapsingHeader(header)) {
    // Every node with its continuity: C1 (smooth), C0 (a kink may form), C-1 (a jump may form);
    // * marks the C0 nodes that discontinuity meshing placed at visibility events.
    ImGui::BeginChild("##node list", ImVec2(0, 96), true);
    for (std::size_t k = 0; k < nodes.size(); ++k)
      ImGui::TextWrapped("%3zu  (%.4g, %.4g)  %s%s", k, nodes[k].position.x, nodes[k].position.y,
                         continuity_name(nodes[k].continuity), nodes[k].visibility_event ? "  * visibility event" : "");
    ImGui::EndChild();
  }
}

// One side's B in the plot of B(s): a sample at each arc length of the curve's trace.
struct PlotLine {
  const std::vector<Spectrum>* samples;
  ImU32 colour;
  const char* name;
  const std::vector<double>* band = nullptr;  // the estimated error's half-width at each sample
};

// The newest journey's hops that landed on a curve: hop number (as on the stage) and record.
using Landings = std::vector<std::pair<std::size_t, const PathRecord*>>;

// The sides of curve `c` with B at every sample of its trace (none without a trace).
std::vector<PlotLine> plot_lines(const Snapshot& snapshot, std::size_t c, const CurveTrace* trace) {
  std::vector<PlotLine> lines;
  for (int side = 0; side < 2; ++side) {
    const std::vector<Spectrum>* samples =
        c < snapshot.radiosity.size() ? &snapshot.radiosity[c][static_cast<std::size_t>(side)] : nullptr;
    if (trace == nullptr || samples == nullptr || samples->size() != trace->s.size() || samples->empty()) continue;
    const std::vector<double>* band = snapshot.error_band && c < snapshot.error_band->size()
                                          ? &(*snapshot.error_band)[c][static_cast<std::size_t>(side)]
                                          : nullptr;
    if (band != nullptr && band->size() != samples->size()) band = nullptr;
    lines.push_back({samples, side == 0 ? IM_COL32(255, 190, 70, 255) : IM_COL32(110, 170, 255, 255),
                     side == 0 ? "front" : "back", band});
  }
  return lines;
}

// On colour scenes the plots draw r, g and b, each in its colour (a spectrum is invisible in
// their mean); on grey scenes the one channel.
constexpr ImU32 kChannelColours[3] = {IM_COL32(240, 85, 75, 255), IM_COL32(95, 205, 95, 255),
                                      IM_COL32(100, 150, 255, 255)};

// The largest value a plot draws of a sample: the largest channel on colour scenes.
double plotted_top(const Spectrum& b, int channels) { return channels == 3 ? std::max({b[0], b[1], b[2]}) : b[0]; }

// The B at the top of the plot: a tenth above the highest B of the lines and the reference, 1 when
// none is above zero.
double plot_top(const std::vector<PlotLine>& lines, const std::vector<std::array<double, 2>>* reference, int channels) {
  double hi = 0.0;
  for (const PlotLine& line : lines)
    for (const Spectrum& b : *line.samples) hi = std::max(hi, plotted_top(b, channels));
  if (reference != nullptr)
    for (const auto& point : *reference) hi = std::max(hi, point[1]);
  hi = hi > 0.0 ? 1.1 * hi : 1.0;
  if (!std::isfinite(hi)) hi = 1.0;  // (a sample that is not finite: keep the plot usable)
  return hi;
}

// Legend: each line's side, the reference's side and the marks of the nodes below C1.
// One entry of a legend: on the line of the previous one when it fits, else on the next line (a
// legend on one line ran past narrow panels at large ui scales).
void legend_entry(const ImVec4& colour, const std::string& text, bool first, float spacing = -1.0f) {
  if (!first) {
    ImGui::SameLine(0.0f, spacing);
    if (ImGui::GetContentRegionAvail().x < ImGui::CalcTextSize(text.c_str()).x) ImGui::NewLine();
  }
  ImGui::TextColored(colour, "%s", text.c_str());
}

void draw_plot_legend(const std::vector<PlotLine>& lines, bool reference, int main_side, int channels) {
  bool first = true;
  if (channels == 3) {
    // Colour: a line per channel in its colour; the second side's lines dashed.
    for (std::size_t ch = 0; ch < 3; ++ch) {
      legend_entry(ImGui::ColorConvertU32ToFloat4(kChannelColours[ch]),
                   ch == 0   ? "-- r"
                   : ch == 1 ? "g"
                             : "b",
                   first, 5.0f);
      first = false;
    }
    for (std::size_t i = 0; i < lines.size(); ++i)
      legend_entry(ImGui::ColorConvertU32ToFloat4(lines[i].colour),
                   std::string(lines.size() == 1 ? ""
                               : i == 0          ? "solid: "
                                                 : "dashed: ") +
                       lines[i].name + (lines.size() == 1 ? " side" : ""),
                   false);
  } else {
    for (const PlotLine& line : lines) {
      legend_entry(ImGui::ColorConvertU32ToFloat4(line.colour),
                   std::string("-- ") + line.name + (lines.size() == 1 ? " side" : ""), first);
      first = false;
    }
  }
  if (reference)
    legend_entry(ImVec4(0.47f, 0.86f, 0.47f, 1.0f),
                 std::string("-- reference (") + (main_side == 0 ? "front" : "back") + ")", first);
  if (!lines.empty() && lines[0].band != nullptr)
    legend_entry(ImVec4(0.75f, 0.75f, 0.75f, 1.0f), "band: +- estimated error", false);
  legend_entry(ImVec4(0.8f, 0.35f, 0.35f, 1.0f), "| C-1", false);
  legend_entry(ImVec4(0.6f, 0.6f, 0.6f, 1.0f), "| C0", false);
}

// Where the newest journey's hops landed on curve `c` (its deposits).
Landings journey_landings(const Snapshot& snapshot, std::size_t c) {
  Landings landings;
  const auto [first, end] = newest_journey(snapshot.paths);
  for (std::size_t i = first; i < end; ++i)
    if (!snapshot.paths[i].escaped && snapshot.paths[i].hit_curve == c)
      landings.emplace_back(i - first + 1, &snapshot.paths[i]);
  return landings;
}

// The plot on the window's draw list: s from 0 (left) to the curve's length (right), B from 0
// (bottom) to `hi` (top), inside the rectangle from `lo` (top left) to `hi_corner` (bottom right).
struct PlotArea {
  ImDrawList* draw;
  ImVec2 lo;
  ImVec2 hi_corner;
  double length;
  double hi;
  float text;  // the height of a line of text

  ImVec2 point(double s, double b) const {
    return ImVec2(lo.x + static_cast<float>(s / length) * (hi_corner.x - lo.x),
                  hi_corner.y - static_cast<float>(b / hi) * (hi_corner.y - lo.y));
  }
};

// The plot area in the widget at `corner` of `size`, leaving room for the value labels on the left
// and the arc lengths below.
PlotArea plot_area(ImDrawList* draw, ImVec2 corner, ImVec2 size, float text, double length, double hi) {
  const float left = ImGui::CalcTextSize("0.000e+00").x * 0.8f;
  const ImVec2 lo(corner.x + left, corner.y + 4.0f);
  const ImVec2 hi_corner(corner.x + size.x - 4.0f, corner.y + size.y - text - 6.0f);
  return {draw, lo, hi_corner, length, hi, text};
}

// The background, the grid with the values of B on the left, the arc lengths below, and the axes.
void draw_plot_axes(const PlotArea& plot) {
  ImDrawList* draw = plot.draw;
  const ImVec2 lo = plot.lo;
  const ImVec2 hi_corner = plot.hi_corner;
  draw->AddRectFilled(lo, hi_corner, IM_COL32(30, 30, 40, 255));
  const ImU32 axis = IM_COL32(200, 200, 200, 255);
  const ImU32 grid = IM_COL32(70, 70, 85, 255);
  for (const double v : ticks(plot.hi)) {
    const ImVec2 p = plot.point(0.0, v);
    draw->AddLine(ImVec2(lo.x, p.y), ImVec2(hi_corner.x, p.y), grid);
    char label[32];
    std::snprintf(label, sizeof label, "%.3g", v);
    draw->AddText(ImVec2(lo.x - ImGui::CalcTextSize(label).x - 4.0f, p.y - 0.5f * plot.text), axis, label);
  }
  for (const double v : ticks(plot.length)) {
    const ImVec2 p = plot.point(v, 0.0);
    draw->AddLine(ImVec2(p.x, hi_corner.y), ImVec2(p.x, hi_corner.y + 4.0f), axis);
    char label[32];
    std::snprintf(label, sizeof label, "%.3g", v);
    const float w = ImGui::CalcTextSize(label).x;
    draw->AddText(ImVec2(std::min(p.x - 0.5f * w, hi_corner.x - w), hi_corner.y + 5.0f), axis, label);
  }
  draw->AddLine(ImVec2(lo.x, lo.y), ImVec2(lo.x, hi_corner.y), axis);
  draw->AddLine(ImVec2(lo.x, hi_corner.y), ImVec2(hi_corner.x, hi_corner.y), axis);
}

// The storage nodes below C1 (C0 grey, C-1 red), where the illumination may kink or jump.
void draw_plot_nodes(const PlotArea& plot, const std::vector<NodeMark>& nodes) {
  for (const NodeMark& node : nodes) {
    if (node.continuity == Continuity::C1) continue;
    const float x = plot.point(node.s, 0.0).x;
    plot.draw->AddLine(ImVec2(x, plot.lo.y), ImVec2(x, plot.hi_corner.y),
                       node.continuity == Continuity::Jump ? IM_COL32(200, 90, 90, 200) : IM_COL32(150, 150, 150, 160));
  }
}

void draw_plot_reference(const PlotArea& plot, const std::vector<std::array<double, 2>>& reference) {
  for (std::size_t i = 1; i < reference.size(); ++i)
    plot.draw->AddLine(plot.point(reference[i - 1][0], reference[i - 1][1]),
                       plot.point(reference[i][0], reference[i][1]), IM_COL32(120, 220, 120, 255), 1.5f);
}

void draw_plot_lines(const PlotArea& plot, const std::vector<PlotLine>& lines, const CurveTrace& trace, int channels) {
  // Under each line, the band of +- its estimated error: a translucent quad per trace interval.
  for (const PlotLine& line : lines) {
    if (line.band == nullptr) continue;
    const ImU32 fill = (line.colour & 0x00ffffffu) | (static_cast<ImU32>(70) << IM_COL32_A_SHIFT);
    for (std::size_t i = 1; i < line.samples->size(); ++i) {
      const double b0 = luminance((*line.samples)[i - 1], channels);
      const double b1 = luminance((*line.samples)[i], channels);
      const double w0 = (*line.band)[i - 1];
      const double w1 = (*line.band)[i];
      plot.draw->AddQuadFilled(plot.point(trace.s[i - 1], b0 + w0), plot.point(trace.s[i], b1 + w1),
                               plot.point(trace.s[i], b1 - w1), plot.point(trace.s[i - 1], b0 - w0), fill);
    }
  }
  for (std::size_t l = 0; l < lines.size(); ++l) {
    const PlotLine& line = lines[l];
    if (channels != 3) {
      for (std::size_t i = 1; i < line.samples->size(); ++i)
        plot.draw->AddLine(plot.point(trace.s[i - 1], luminance((*line.samples)[i - 1], channels)),
                           plot.point(trace.s[i], luminance((*line.samples)[i], channels)), line.colour, 1.5f);
      continue;
    }
    // Colour: r, g and b; the second side's lines dashed (every other pair of samples).
    for (std::size_t ch = 0; ch < 3; ++ch)
      for (std::size_t i = 1; i < line.samples->size(); ++i) {
        if (l > 0 && (i / 2) % 2 == 1) continue;
        plot.draw->AddLine(plot.point(trace.s[i - 1], (*line.samples)[i - 1][ch]),
                           plot.point(trace.s[i], (*line.samples)[i][ch]), kChannelColours[ch], 1.5f);
      }
  }
}

// The newest journey's deposits: numbered as on the stage and coloured by bounce, a triangle on the
// axis and a dotted line up the plot.
void draw_plot_landings(const PlotArea& plot, const Landings& landings) {
  ImDrawList* draw = plot.draw;
  const ImVec2 lo = plot.lo;
  const ImVec2 hi_corner = plot.hi_corner;
  for (const auto& [number, hop] : landings) {
    const ImU32 colour = to_u32(path_palette(hop->bounce));
    const float x = plot.point(hop->hit_s, 0.0).x;
    for (float y = hi_corner.y - 10.0f; y > lo.y; y -= 6.0f) draw->AddLine(ImVec2(x, y), ImVec2(x, y - 3.0f), colour);
    draw->AddTriangleFilled(ImVec2(x, hi_corner.y - 10.0f), ImVec2(x - 5.0f, hi_corner.y),
                            ImVec2(x + 5.0f, hi_corner.y), colour);
    char label[16];
    std::snprintf(label, sizeof label, "%zu", number);
    draw->AddText(ImVec2(x + 4.0f, hi_corner.y - 10.0f - plot.text), colour, label);
  }
}

}  // namespace

void Viewer::draw_curve_panel(const Snapshot& snapshot) {
  const auto c = static_cast<std::size_t>(draw_.selected_curve);
  // The rest of the right column, below the status panel; when Display has taken that place, the
  // rest of the left column, below Solve.
  const auto above = panel_rects_.find(display_on_right_ ? "Solve" : "Status");
  const PixelRect& column = display_on_right_ ? layout_.left : layout_.right;
  const float top = above != panel_rects_.end() ? above->second.y1 : column.y0;
  ImGui::SetNextWindowPos(ImVec2(column.x0, top), ImGuiCond_Always);
  ImGui::SetNextWindowSize(ImVec2(column.width(), std::max(column.y1 - top, 120.0f)), ImGuiCond_Always);
  ImGui::Begin("Curve", nullptr, kDocked);
  record_panel("Curve");
  draw_curve_facts(*scene_, snapshot, c);
  // (Mirrors, glass and detectors store no light: no nodes to list.)
  if (scene_->material_of(scene_->curves[c]).optics == Optics::Diffuse) draw_node_list(snapshot, c);
  draw_curve_plot(snapshot, c);
  ImGui::End();
}

// B(s) along the curve with axes in the units of the scene: the sides that emit or reflect
// (front orange, back blue, each labelled), the reference's B (green, main side), and the storage
// nodes below C1 (C0 grey, C-1 red), where the illumination may kink or jump.
void Viewer::draw_curve_plot(const Snapshot& snapshot, std::size_t c, bool captions) {
  const Curve& curve = scene_->curves[c];
  if (c < snapshot.detected.size() && !snapshot.detected[c][0].empty()) {
    draw_detector_plot(snapshot, c, captions);
    return;
  }
  const CurveTrace* trace = snapshot.traces && c < snapshot.traces->size() ? &(*snapshot.traces)[c] : nullptr;
  const int main_side = curve.sides == Sides::Back ? 1 : 0;
  const std::vector<PlotLine> lines = plot_lines(snapshot, c, trace);
  if (lines.empty()) return;
  const std::vector<std::array<double, 2>>* reference =
      c < snapshot.reference_curves.size() && !snapshot.reference_curves[c].empty() ? &snapshot.reference_curves[c]
                                                                                    : nullptr;
  const double hi = plot_top(lines, reference, scene_->channels);
  draw_plot_legend(lines, reference != nullptr, main_side, scene_->channels);
  // Where the newest journey's hops landed on this curve (its deposits): hop number and record.
  Landings landings;
  if (draw_.paths && draw_.journey) landings = journey_landings(snapshot, c);
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const float text = ImGui::GetTextLineHeight();
  const ImVec2 corner = ImGui::GetCursorScreenPos();
  const ImVec2 avail = ImGui::GetContentRegionAvail();
  const float caption_lines = !captions ? 0.0f : landings.empty() ? 2.5f : 5.5f;  // text under the plot
  const ImVec2 size(avail.x, std::max(avail.y - caption_lines * text - 8.0f, 80.0f));
  ImGui::InvisibleButton("##bplot", size);
  track("B plot");
  const PlotArea plot = plot_area(draw, corner, size, text, curve.length, hi);
  draw_plot_axes(plot);
  if (c < snapshot.nodes.size()) draw_plot_nodes(plot, snapshot.nodes[c]);
  if (reference != nullptr) draw_plot_reference(plot, *reference);
  draw->PushClipRect(plot.lo, plot.hi_corner, true);
  draw_plot_lines(plot, lines, *trace, scene_->channels);
  draw_plot_landings(plot, landings);
  draw->PopClipRect();
  if (!captions) return;
  if (!landings.empty())
    ImGui::TextWrapped(
        "Triangles: where the newest journey's hops (numbered as on the stage) landed on this "
        "curve and left their deposits.");
  ImGui::TextWrapped("B (power per unit length) against s (arc length from the first point)%s",
                     scene_->channels == 3 ? "; r, g and b in their colours" : "");
}

// A detector's tallies as steps, one per bin: the power per unit length that crossed it arriving on
// its front (orange) and on its back (blue), against s.
void Viewer::draw_detector_plot(const Snapshot& snapshot, std::size_t c, bool captions) {
  const Curve& curve = scene_->curves[c];
  const int channels = scene_->channels;
  const auto& sides = snapshot.detected[c];
  double hi = 0.0;
  for (const auto& side : sides)
    for (const Spectrum& value : side) hi = std::max(hi, plotted_top(value, channels));
  hi = hi > 0.0 && std::isfinite(hi) ? 1.1 * hi : 1.0;
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const float text = ImGui::GetTextLineHeight();
  const ImVec2 corner = ImGui::GetCursorScreenPos();
  const ImVec2 avail = ImGui::GetContentRegionAvail();
  const ImVec2 size(avail.x, std::max(avail.y - (captions ? 2.5f : 0.0f) * text - 8.0f, 80.0f));
  ImGui::InvisibleButton("##detector plot", size);
  track("detector plot");
  const PlotArea plot = plot_area(draw, corner, size, text, curve.length, hi);
  draw_plot_axes(plot);
  draw->PushClipRect(plot.lo, plot.hi_corner, true);
  const ImU32 colours[2] = {IM_COL32(255, 190, 70, 255), IM_COL32(110, 170, 255, 255)};
  // Grey: one step line a side; colour: r, g and b in their colours, the back's thinner.
  for (std::size_t side = 0; side < 2; ++side) {
    const std::vector<Spectrum>& bins = sides[side];
    const double width = curve.length / static_cast<double>(bins.size());
    for (std::size_t ch = 0; ch < (channels == 3 ? 3u : 1u); ++ch) {
      const ImU32 colour = channels == 3 ? kChannelColours[ch] : colours[side];
      const float thickness = channels == 3 && side == 1 ? 0.8f : 1.5f;
      auto value_of = [&](const Spectrum& bin) { return channels == 3 ? bin[ch] : luminance(bin, channels); };
      for (std::size_t b = 0; b < bins.size(); ++b) {
        const double value = value_of(bins[b]);
        const double s0 = width * static_cast<double>(b), s1 = s0 + width;
        draw->AddLine(plot.point(s0, value), plot.point(s1, value), colour, thickness);
        if (b + 1 < bins.size())
          draw->AddLine(plot.point(s1, value), plot.point(s1, value_of(bins[b + 1])), colour, 0.7f * thickness);
      }
    }
  }
  draw->PopClipRect();
  if (!captions) return;
  ImGui::TextWrapped(
      "Power per unit length that crossed each of the detector's bins, arriving on its front (%s) and on its "
      "back (%s), against s%s",
      channels == 3 ? "thick lines" : "orange", channels == 3 ? "thin lines" : "blue",
      channels == 3 ? "; r, g and b in their colours: the detector's spectrum" : "");
}

void Viewer::draw_help_panel() {
  // Over the stage, as long as it is asked for (Help, F1 or H closes it again).
  ImGui::SetNextWindowPos(ImVec2(0.5f * (layout_.stage.x0 + layout_.stage.x1), layout_.stage.y0 + 20.0f),
                          ImGuiCond_Appearing, ImVec2(0.5f, 0.0f));
  ImGui::Begin("Help", &show_help_, ImGuiWindowFlags_AlwaysAutoResize);
  ImGui::TextUnformatted("Keyboard shortcuts (when no panel has the keyboard)");
  ImGui::Separator();
  for (const auto& entry : kHelp) {
    ImGui::Text("%-10s", entry[0]);
    ImGui::SameLine();
    ImGui::TextUnformatted(entry[1]);
  }
  ImGui::End();
}

}  // namespace flatland::viewer
