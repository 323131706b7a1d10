// The viewer's panels (Dear ImGui): menu, solve controls, display options, status, the key and
// presentation mode's overlays, help (the inspected curve's panel is in curve_panel.cpp). They read the snapshot and
// change the viewer's settings; the main loop is in viewer_app.cpp.
#include <imgui.h>
#include <imgui_internal.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <vector>

#include "flatland/base/text.hpp"
#include "viewer/panel_widgets.hpp"
#include "viewer/viewer_app.hpp"
#include "viewer/window.hpp"

namespace flatland::viewer {

using namespace panels;

namespace {

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

bool Viewer::option_combo(SolveOption option, const char* tooltip) {
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
  const bool chosen = combo(label.c_str(), &index, pointers.data(), static_cast<int>(pointers.size()));
  if (tooltip != nullptr && ImGui::IsItemHovered()) ImGui::SetTooltip("%s", tooltip);
  return chosen && set_solve_option(settings_, option, names[static_cast<std::size_t>(index)]).ok();
}

bool Viewer::importance_checkbox(std::size_t c) {
  const Curve& curve = scene_->curves[c];
  std::vector<std::string>& ids = settings_.importance;
  const auto named = std::find(ids.begin(), ids.end(), curve.id);
  bool in_region = named != ids.end();
  if (!ImGui::Checkbox("importance", &in_region)) return false;
  if (in_region)
    ids.push_back(curve.id);
  else
    ids.erase(named);
  return true;
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
  // The coarse control variate (--control-variate auto when ticked, as solve's default; none when
  // not), on the same line: the panel's height is the classroom's 720 pixels' budget. Where auto
  // does without it, the estimated error's tooltip says why.
  ImGui::SameLine();
  bool variate = settings_.control_variate != ControlVariate::None;
  if (ImGui::Checkbox("coarse variate", &variate)) {
    settings_.control_variate = variate ? ControlVariate::Auto : ControlVariate::None;
    changed = true;
  }
  if (ImGui::IsItemHovered())
    ImGui::SetTooltip(
        "A control variate: a reference solve on coarse elements carries most of the light exactly,\n"
        "and the photons (of either sign) shoot only what it misses: far less noise for the same\n"
        "photons, where it applies (diffuse scenes, transport shooting, reconstructed origins,\n"
        "B-spline storage; the estimated error's tooltip says where it does not)");
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
  changed = option_combo(SolveOption::Transport,
                         "shooting: rounds of one hop each (the paper's method)\n"
                         "walk: each photon a whole random walk, ended by Russian roulette\n"
                         "jacobi: shooting to the tolerance, then iterations that each shoot all the\n"
                         "reflected light again, averaged (the estimate moves per iteration)") ||
            changed;
  // A score is a walk's: back to shooting, the score goes back to collision (shooting refuses others).
  if (settings_.transport != Transport::Walk) settings_.walk_score = WalkScore::Collision;
  if (settings_.transport == Transport::Walk)
    changed = option_combo(SolveOption::WalkScore,
                           "What a walk tallies where it lands (the same answer, different noise):\n"
                           "collision: the power that arrived, at every landing\n"
                           "absorption: power / (1 - q) where the walk ends (q: its chance of going on)\n"
                           "survival: power / q where it goes on") ||
              changed;
  // Importance belongs to shooting: with walks or Jacobi iterations it is cleared (the pairs are refused).
  if (settings_.transport != Transport::Shooting) settings_.importance.clear();
  changed = option_combo(SolveOption::Gather,
                         "The answer's B once the solve stops (the saved result, the estimate, the error\n"
                         "against a reference; the plots stay the storage's B):\n"
                         "none: the storage's own\n"
                         "samples: a final gather, one deterministic bounce of the solution over what each\n"
                         "sample sees (diffuse surfaces and flat mirrors only)\n"
                         "auto: samples where the scene allows it at a bounded cost, none elsewhere") ||
            changed;
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

void Viewer::draw_colour_key(const Snapshot& snapshot) {
  panels::colour_key(snapshot, draw_, [this] { track("colour key"); });
}

namespace panels {

void colour_key(const Snapshot& snapshot, const DrawOptions& options, const std::function<void()>& after_scale) {
  if (!snapshot.scene) return;
  const int channels = snapshot.scene->channels;
  const double range = radiosity_range(snapshot, options.channel) / std::max(options.band_exposure, 1e-6f);
  ImGui::TextUnformatted("band colour = B, power per unit length");
  ImDrawList* draw = ImGui::GetWindowDrawList();
  const ImVec2 origin = ImGui::GetCursorScreenPos();
  const float width = ImGui::GetContentRegionAvail().x;
  const float height = ImGui::GetTextLineHeight();
  ImGui::InvisibleButton("##colour key", ImVec2(width, height));
  if (after_scale) after_scale();
  const int steps = 48;
  for (int i = 0; i < steps; ++i) {
    // The band's own mapping at B = (i + 0.5) / steps x range (grey level for colour scenes).
    const double b = (i + 0.5) / steps * range;
    const std::array<float, 3> colour = radiosity_colour({b, b, b}, range, channels, options.channel);
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
  ImGui::TextWrapped(channels == 3 && options.channel == ChannelView::All
                         ? "each channel 1 - exp(-2 B / %.3g); emitters saturate"
                         : "scale: the 99th percentile of B off the emitters, %.3g",
                     range);
  ImGui::PopStyleColor();
  materials_legend(*snapshot.scene);
}

void materials_legend(const Scene& scene) {
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

}  // namespace panels

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
    int light = static_cast<int>(draw_.light);
    const char* const light_names[] = {"auto", "paths", "field"};
    combo("light as", &light, light_names, 3);
    draw_.light = static_cast<LightView>(light);
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip(
          "paths: each kept flight a line. field: the light of the whole solve, every\n"
          "recorded flight standing for its share of the photons, so more photons\n"
          "give a smoother, truer picture. auto: the field once 4096 paths are kept\n"
          "and paths are coloured by power");
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
  if (!settings_.importance.empty())
    ImGui::TextWrapped("importance %s", solve_option_text(settings_, SolveOption::Importance).c_str());
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
      ImGui::Text("error    <= %.2g %% (estimated, %g %%%s)", 100.0 * estimate.bound.l1, 100.0 * estimate.confidence,
                  snapshot.estimate_gathered ? ", gathered" : "");
    else
      ImGui::Text("error    not bounded yet");
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip(
          "Upper bound of the relative L1 error of B - E over the scene at %g %% confidence\n"
          "noise %.2g %%, storage %s, unshot %.2g %%%s%s%s%s%s",
          100.0 * estimate.confidence, 100.0 * estimate.noise.l1,
          estimate.storage_estimated ? (format_number(100.0 * estimate.storage.l1, 2) + " %").c_str() : "not estimated",
          100.0 * estimate.unshot.l1,
          snapshot.estimate_gathered
              ? (", gather " + format_number(100.0 * estimate.gather.l1, 2) +
                 " %\nof the final gather's B, which a saved result holds; the plots show the storage's B")
                    .c_str()
              : "",
          snapshot.gather_skipped.empty() ? "" : ("\nno final gather: " + snapshot.gather_skipped).c_str(),
          snapshot.variate_skipped.empty() ? "" : ("\nno control variate: " + snapshot.variate_skipped).c_str(),
          estimate.caveat.empty() ? "" : "\n", estimate.caveat.c_str());
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
