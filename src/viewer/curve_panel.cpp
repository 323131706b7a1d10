// The curve panel: the inspected curve's facts, its storage nodes and the plot of B(s) (or a
// detector's bins), also drawn beside the stage in presentation mode.
#include <imgui.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "viewer/panel_widgets.hpp"
#include "viewer/viewer_app.hpp"

namespace flatland::viewer {

using namespace panels;

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
  // Importance (shooting only, curves whose light the solve estimates): a checkbox at the right
  // end of the facts' first row, so the panel keeps its height.
  const Curve& curve = scene_->curves[c];
  if (settings_.transport == Transport::Shooting && scene_->reflects_light(curve)) {
    const ImVec2 start = ImGui::GetCursorPos();
    const float width =
        ImGui::GetFrameHeight() + ImGui::GetStyle().ItemInnerSpacing.x + ImGui::CalcTextSize("importance").x;
    ImGui::SetCursorPosX(std::max(start.x, ImGui::GetWindowContentRegionMax().x - width));
    if (importance_checkbox(c)) restart();
    track("importance");
    if (ImGui::IsItemHovered())
      ImGui::SetTooltip(
          "Favour this curve: photons leave the sources by power times the square root\n"
          "of their importance for the ticked curves (from a short solve of the adjoint\n"
          "scene). The same expected answer, less noise on the ticked curves and more\n"
          "elsewhere (shooting only)");
    ImGui::SetCursorPos(start);
  }
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

}  // namespace flatland::viewer
