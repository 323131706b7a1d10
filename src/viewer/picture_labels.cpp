#include "viewer/picture_labels.hpp"

#include <imgui.h>
#include <imgui_impl_opengl3.h>

#include <algorithm>

#include "viewer/panel_widgets.hpp"

namespace flatland::viewer {

namespace {

constexpr float kFontPixels = 13.0f;  // ImGui's built-in font
constexpr float kPad = 6.0f;

float line_height(float scale) { return (kFontPixels + 4.0f) * scale; }

}  // namespace

PictureLayout picture_layout(int width, int height, bool labels) {
  PictureLayout layout;
  const auto w = static_cast<float>(width);
  const auto h = static_cast<float>(height);
  layout.stage = {0.0f, 0.0f, w, h};
  if (!labels || width < 320 || height < 240) return layout;
  layout.scale = std::clamp(h / 700.0f, 1.0f, 3.0f);
  const float line = line_height(layout.scale);
  // Title: three lines (its two lines wrap in a narrow picture). Key: caption, scale, values, note and legend (five
  // lines and the padding).
  const float title = 3.0f * line + 2.0f * kPad * layout.scale;
  const float key = 5.0f * line + 3.0f * kPad * layout.scale;
  layout.title = {0.0f, 0.0f, w, title};
  layout.key = {0.0f, h - key, w, h};
  layout.stage = {0.0f, title, w, h - key};
  return layout;
}

Status draw_picture_labels(const Snapshot& snapshot, const DrawOptions& options, const PictureLayout& layout, int width,
                           int height, const std::vector<std::string>& title_lines) {
  if (layout.title.height() <= 0.0f && layout.key.height() <= 0.0f) return ok_status();
  // A context of its own, made and destroyed here: render draws one picture per process.
  ImGuiContext* previous = ImGui::GetCurrentContext();
  ImGuiContext* context = ImGui::CreateContext();
  ImGui::SetCurrentContext(context);
  ImGuiIO& io = ImGui::GetIO();
  io.IniFilename = nullptr;
  io.DisplaySize = ImVec2(static_cast<float>(width), static_cast<float>(height));
  io.DeltaTime = 1.0f / 60.0f;
  ImGui::StyleColorsDark();
  ImGui::GetStyle().ScaleAllSizes(layout.scale);
  io.FontGlobalScale = layout.scale;
  if (!ImGui_ImplOpenGL3_Init("#version 330 core")) {
    ImGui::DestroyContext(context);
    ImGui::SetCurrentContext(previous);
    return Error{"cannot draw the picture's labels: Dear ImGui's OpenGL 3 renderer did not start"};
  }
  constexpr ImGuiWindowFlags kText = panels::kOverlay | ImGuiWindowFlags_NoBackground | ImGuiWindowFlags_NoInputs;
  // Two frames: a window lays its contents out in its first.
  for (int frame = 0; frame < 2; ++frame) {
    ImGui_ImplOpenGL3_NewFrame();
    ImGui::NewFrame();
    const float pad = kPad * layout.scale;
    ImGui::SetNextWindowPos(ImVec2(layout.title.x0 + pad, layout.title.y0 + pad), ImGuiCond_Always);
    ImGui::SetNextWindowSize(ImVec2(layout.title.width() - 2.0f * pad, layout.title.height() - pad), ImGuiCond_Always);
    ImGui::Begin("##title", nullptr, kText);
    for (std::size_t i = 0; i < title_lines.size(); ++i) {
      if (i > 0) ImGui::PushStyleColor(ImGuiCol_Text, ImGui::GetStyle().Colors[ImGuiCol_TextDisabled]);
      ImGui::TextWrapped("%s", title_lines[i].c_str());
      if (i > 0) ImGui::PopStyleColor();
    }
    ImGui::End();
    ImGui::SetNextWindowPos(ImVec2(layout.key.x0 + pad, layout.key.y0), ImGuiCond_Always);
    ImGui::SetNextWindowSize(
        ImVec2(std::min(layout.key.width() - 2.0f * pad, 900.0f * layout.scale), layout.key.height()),
        ImGuiCond_Always);
    ImGui::Begin("##key", nullptr, kText | ImGuiWindowFlags_NoScrollbar);
    panels::colour_key(snapshot, options);
    ImGui::End();
    ImGui::Render();
  }
  ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
  ImGui_ImplOpenGL3_Shutdown();
  ImGui::DestroyContext(context);
  ImGui::SetCurrentContext(previous);
  return ok_status();
}

}  // namespace flatland::viewer
