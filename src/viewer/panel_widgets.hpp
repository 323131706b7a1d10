// What the viewer's panels share (panels.cpp, curve_panel.cpp): window flags, docking, widget
// widths, plot ticks and colours. Internal to the viewer.
#pragma once

#include <imgui.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <vector>

#include "flatland/scene/scene.hpp"
#include "viewer/frame.hpp"

namespace flatland::viewer::panels {

inline const char* continuity_name(Continuity c) {
  return c == Continuity::Jump ? "C-1" : c == Continuity::C0 ? "C0" : "C1";
}

// A step of 1, 2 or 5 times a power of ten, near span / 4: the axis ticks of a plot; 0 where there
// is nothing to tick (a span that is not a positive finite number, or too small to divide).
inline double nice_step(double span) {
  if (!(span > 0.0) || !std::isfinite(span)) return 0.0;
  const double raw = span / 4.0;
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  if (!(decade > 0.0) || !std::isfinite(decade)) return 0.0;
  const double f = raw / decade;
  return decade * (f < 1.5 ? 1.0 : f < 3.5 ? 2.0 : f < 7.5 ? 5.0 : 10.0);
}

// The ticks 0, step, 2 step, ... up to `span` (none when nice_step found no step; at most 12).
inline std::vector<double> ticks(double span) {
  std::vector<double> values;
  const double step = nice_step(span);
  if (step > 0.0)
    for (int i = 0; i <= 12 && i * step <= span * (1.0 + 1e-9); ++i) values.push_back(i * step);
  return values;
}

inline ImU32 to_u32(const std::array<float, 3>& c, float alpha = 1.0f) {
  return ImGui::ColorConvertFloat4ToU32(ImVec4(c[0], c[1], c[2], alpha));
}

// Docked panels: placed by the layout every frame, not moved or resized by hand (a title bar
// click still folds one away).
inline constexpr ImGuiWindowFlags kDocked = ImGuiWindowFlags_NoMove | ImGuiWindowFlags_NoResize;
// Overlays on the stage: no title, not moved by hand.
inline constexpr ImGuiWindowFlags kOverlay = ImGuiWindowFlags_NoDecoration | ImGuiWindowFlags_NoMove |
                                             ImGuiWindowFlags_NoSavedSettings | ImGuiWindowFlags_NoFocusOnAppearing;

// Widgets as wide as the panel leaves beside the longest of its labels, so labels are never cut
// off at any size or scale (the widgets narrow instead). Pop with ImGui::PopItemWidth.
inline void push_width_beside(const char* longest_label) {
  ImGui::PushItemWidth(-(ImGui::CalcTextSize(longest_label).x + ImGui::GetStyle().ItemInnerSpacing.x + 2.0f));
}

// The next panel at the top of what is left of `column` below `above` (its y1; the column's top
// for the first panel), as wide as the column; its height follows its content up to what is left.
inline void dock_next(const PixelRect& column, float above) {
  const float top = std::max(column.y0, above);
  ImGui::SetNextWindowPos(ImVec2(column.x0, top), ImGuiCond_Always);
  ImGui::SetNextWindowSizeConstraints(ImVec2(column.width(), 0.0f),
                                      ImVec2(column.width(), std::max(column.y1 - top, 40.0f)));
}

// The key of the band's colours (the colour scale from 0 to the band's range with its values, in
// the units of B: power per unit length, in the scene's emittance units), its scale's note and
// the materials' legend, in the current ImGui window. `after_scale` runs right after the scale's
// item (the viewer's UI tests track its rectangle).
void colour_key(const Snapshot& snapshot, const DrawOptions& options, const std::function<void()>& after_scale = {});
// The materials that hold no light, in the colours the stage draws them in: each mirror, glass
// (with its index) and detector material once, on one line.
void materials_legend(const Scene& scene);

}  // namespace flatland::viewer::panels
