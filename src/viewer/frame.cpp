#include "viewer/frame.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>

namespace flatland::viewer {

void ViewTransform::zoom_about(Vec2 pixel, double factor) {
  const Vec2 anchor = to_scene(pixel);
  scale *= factor;
  const Vec2 moved = to_scene(pixel);
  center = center + (anchor - moved);
}

ViewTransform fit_view(const Box& bounds, int width, int height, double margin) {
  ViewTransform view;
  view.width = std::max(width, 1);
  view.height = std::max(height, 1);
  view.center = 0.5 * (bounds.lower + bounds.upper);
  const double pad = margin * std::min(view.width, view.height);
  const double w = std::max(bounds.upper.x - bounds.lower.x, 0.0);
  const double h = std::max(bounds.upper.y - bounds.lower.y, 0.0);
  const double sx = w > 0.0 ? (view.width - 2.0 * pad) / w : INFINITY;
  const double sy = h > 0.0 ? (view.height - 2.0 * pad) / h : INFINITY;
  view.scale = std::min(sx, sy);
  if (!std::isfinite(view.scale) || view.scale <= 0.0) view.scale = 1.0;
  return view;
}

StageLayout stage_layout(int width, int height, float ui_scale, bool panels, float menu_height, float key_height) {
  const auto w = static_cast<float>(std::max(width, 1));
  const auto h = static_cast<float>(std::max(height, 1));
  const float top = std::clamp(menu_height, 0.0f, h);
  // The key's strip takes at most a third of the height under the menu.
  const float key = std::clamp(key_height, 0.0f, (h - top) / 3.0f);
  StageLayout layout;
  if (!panels) {
    layout.stage = {0.0f, top, w, h - key};
    layout.key = {0.0f, h - key, w, h};
    layout.left = {0.0f, top, 0.0f, h};
    layout.right = {w, top, w, h};
    return layout;
  }
  float left = 340.0f * ui_scale;
  float right = 370.0f * ui_scale;
  const float room = 0.6f * w;  // what the columns may take together
  if (left + right > room) {
    const float shrink = room / (left + right);
    left *= shrink;
    right *= shrink;
  }
  layout.left = {0.0f, top, std::floor(left), h};
  layout.right = {w - std::floor(right), top, w, h};
  layout.stage = {layout.left.x1, top, layout.right.x0, h - key};
  layout.key = {layout.left.x1, h - key, layout.right.x0, h};
  return layout;
}

StageLayout presentation_layout(int width, int height, float menu_height, float key_height, float counter_height,
                                float plot_width) {
  const auto w = static_cast<float>(std::max(width, 1));
  const auto h = static_cast<float>(std::max(height, 1));
  const float top = std::clamp(menu_height, 0.0f, h);
  const float key = std::clamp(key_height, 0.0f, (h - top) / 3.0f);
  const float counter = std::clamp(counter_height, 0.0f, (h - top) / 4.0f);
  const float plot = std::floor(std::clamp(plot_width, 0.0f, 0.45f * w));
  StageLayout layout;
  layout.left = {0.0f, top, 0.0f, h};
  layout.right = {w - plot, top, w, h};
  layout.counter = {0.0f, top, w - plot, top + counter};
  layout.stage = {0.0f, top + counter, w - plot, h - key};
  layout.key = {0.0f, h - key, w - plot, h};
  return layout;
}

ViewTransform fit_view(const Box& bounds, int width, int height, const PixelRect& stage, double margin) {
  // Fit to the stage as if it were the window, then move the centre so that the stage's centre,
  // not the window's, shows the scene's.
  const int stage_width = std::max(1, static_cast<int>(stage.width()));
  const int stage_height = std::max(1, static_cast<int>(stage.height()));
  ViewTransform view = fit_view(bounds, stage_width, stage_height, margin);
  view.width = std::max(width, 1);
  view.height = std::max(height, 1);
  const double dx = 0.5 * (stage.x0 + stage.x1) - 0.5 * view.width;   // pixels right of the window's centre
  const double dy = 0.5 * (stage.y0 + stage.y1) - 0.5 * view.height;  // pixels below it
  view.center = view.center - Vec2{dx / view.scale, -dy / view.scale};
  return view;
}

std::vector<CurveTrace> trace_curves(const Scene& scene, int samples_per_segment) {
  std::vector<CurveTrace> traces(scene.curves.size());
  const int n = std::max(samples_per_segment, 2);
  for (std::size_t c = 0; c < scene.curves.size(); ++c) {
    const Curve& curve = scene.curves[c];
    CurveTrace& trace = traces[c];
    for (std::uint32_t k = 0; k < curve.segment_count; ++k) {
      const SceneSegment& segment = scene.segments[curve.first_segment + k];
      const double start = curve.segment_start[k];
      // Straight segments need no more samples for their shape, but B varies along them.
      for (int j = 0; j < n; ++j) {
        const double f = static_cast<double>(j) / (n - 1);
        // Stay a hair inside the segment so its own normal is used at corners.
        const double s = start + std::clamp(f, 1e-9, 1.0 - 1e-9) * segment.length;
        const CurvePoint point = point_at_arc_length(scene, curve, s);
        const Cubic& shape = scene.segments[curve.first_segment + point.segment_in_curve].geometry.shape;
        trace.points.push_back(point.position);
        trace.normals.push_back(unit_normal(shape, point.t, scene.scale));
        trace.u.push_back(point.u);
        trace.s.push_back(s);
      }
    }
  }
  return traces;
}

namespace {

// Where a ray from `from` along d leaves the scene's box, padded by 5 % of the scene's size: the
// smallest positive slab distance along d.
Vec2 box_exit(const Scene& scene, Vec2 from, Vec2 d) {
  const Vec2 pad{0.05 * scene.scale, 0.05 * scene.scale};
  const Vec2 lower = scene.bounds.lower - pad;
  const Vec2 upper = scene.bounds.upper + pad;
  double t = INFINITY;
  if (d.x > 0.0) t = std::min(t, (upper.x - from.x) / d.x);
  if (d.x < 0.0) t = std::min(t, (lower.x - from.x) / d.x);
  if (d.y > 0.0) t = std::min(t, (upper.y - from.y) / d.y);
  if (d.y < 0.0) t = std::min(t, (lower.y - from.y) / d.y);
  return from + d * (std::isfinite(t) ? std::max(t, 0.0) : 0.0);
}

}  // namespace

void append_path_records(const PhotonPath& path, const Scene& scene, std::uint64_t& serial, std::uint32_t round,
                         std::vector<PathRecord>& out) {
  Vec2 from = path.origin;
  for (const Vec2& point : path.via) {
    PathRecord leg{serial++, from, point, path.power, round, path.bounce};
    leg.specular = true;
    out.push_back(leg);
    from = point;
  }
  PathRecord last = path_record(path, scene, serial++, round);
  if (!path.via.empty()) {
    last.from = from;
    // An escaped flight's end is its last leg's start plus that leg's direction.
    if (path.escaped) last.to = box_exit(scene, from, path.end - from);
  }
  out.push_back(last);
}

PathRecord path_record(const PhotonPath& path, const Scene& scene, std::uint64_t serial, std::uint32_t round) {
  PathRecord record{serial,       path.origin,   path.end, path.power,     round,         path.bounce,
                    path.escaped, path.absorbed, path.cut, path.hit_curve, path.hit_side, path.hit_s};
  if (path.escaped) record.to = box_exit(scene, path.origin, path.end - path.origin);
  return record;
}

std::array<float, 4> optics_colour(Optics optics) {
  switch (optics) {
    case Optics::Mirror: return {0.6f, 0.75f, 1.0f, 1.0f};
    case Optics::Dielectric: return {0.35f, 0.95f, 1.0f, 1.0f};
    case Optics::Detector: return {0.35f, 1.0f, 0.45f, 1.0f};
    case Optics::Diffuse: break;
  }
  return {0.85f, 0.85f, 0.85f, 1.0f};
}

std::string material_words(const Scene& scene, const Curve& curve) {
  const Material& material = scene.material_of(curve);
  char text[128];
  switch (material.optics) {
    case Optics::Mirror: std::snprintf(text, sizeof text, "mirror"); break;
    case Optics::Dielectric:
      std::snprintf(text, sizeof text, "glass, n %.3g at %.0f nm", material.ior.at(kGreyWavelength),
                    1000.0 * kGreyWavelength);
      break;
    case Optics::Detector: std::snprintf(text, sizeof text, "detector, %u bins", material.detector_bins); break;
    case Optics::Diffuse:
      if (scene.channels == 1)
        std::snprintf(text, sizeof text, "diffuse, rho %.3g", material.reflectivity[0]);
      else
        std::snprintf(text, sizeof text, "diffuse, rho %.3g %.3g %.3g", material.reflectivity[0],
                      material.reflectivity[1], material.reflectivity[2]);
      break;
  }
  return std::string(text) + (scene.is_emitter(curve) ? ", emits" : "");
}

double luminance(const Spectrum& b, int channels) {
  if (channels == 1) return b[0];
  return (b[0] + b[1] + b[2]) / 3.0;
}

namespace {

double channel_value(const Spectrum& b, int channels, ChannelView channel) {
  if (channels == 1 || channel == ChannelView::All) return luminance(b, channels);
  return b[static_cast<std::size_t>(channel) - 1];
}

}  // namespace

double radiosity_range(const Snapshot& snapshot, ChannelView channel) {
  // Reflected light is what the solve finds; emitters are usually far brighter and would darken
  // everything else, so they count only when nothing else is lit.
  std::vector<double> values;
  std::vector<double> emitters;
  if (!snapshot.scene) return 1.0;
  const Scene& scene = *snapshot.scene;
  const int channels = scene.channels;
  for (std::size_t c = 0; c < snapshot.radiosity.size(); ++c) {
    std::vector<double>& into = c < scene.curves.size() && scene.is_emitter(scene.curves[c]) ? emitters : values;
    for (const auto& samples : snapshot.radiosity[c])
      for (const Spectrum& b : samples) {
        if (channels == 3 && channel == ChannelView::All)
          into.push_back(std::max({b[0], b[1], b[2]}));
        else
          into.push_back(channel_value(b, channels, channel));
      }
  }
  if (values.empty() || *std::max_element(values.begin(), values.end()) <= 0.0) values.swap(emitters);
  if (values.empty()) return 1.0;
  const std::size_t k = static_cast<std::size_t>(0.99 * static_cast<double>(values.size() - 1));
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  const double range = values[k];
  return range > 1e-300 ? range : 1.0;
}

std::array<float, 3> colour_map(double t) {
  // Piecewise-linear through a few stops of a dark-to-bright sequential map (after "inferno").
  static constexpr std::array<std::array<float, 3>, 6> stops{{{0.0f, 0.0f, 0.02f},
                                                              {0.17f, 0.04f, 0.38f},
                                                              {0.47f, 0.11f, 0.43f},
                                                              {0.78f, 0.25f, 0.27f},
                                                              {0.97f, 0.56f, 0.04f},
                                                              {0.99f, 1.0f, 0.64f}}};
  t = std::clamp(std::isfinite(t) ? t : 0.0, 0.0, 1.0) * (stops.size() - 1);
  const std::size_t i = std::min(static_cast<std::size_t>(t), stops.size() - 2);
  const auto f = static_cast<float>(t - static_cast<double>(i));
  std::array<float, 3> c{};
  for (std::size_t k = 0; k < 3; ++k) c[k] = stops[i][k] + f * (stops[i + 1][k] - stops[i][k]);
  return c;
}

std::array<float, 3> radiosity_colour(const Spectrum& b, double range, int channels, ChannelView channel) {
  if (channels == 1 || channel != ChannelView::All) return colour_map(channel_value(b, channels, channel) / range);
  // The light's own colour: tone map each channel (1 - exp(-2x) reaches 0.86 at the range),
  // then encode for the display.
  std::array<float, 3> c{};
  for (std::size_t k = 0; k < 3; ++k) {
    const double x = std::max(b[k], 0.0) / range;
    c[k] = static_cast<float>(std::pow(1.0 - std::exp(-2.0 * x), 1.0 / 2.2));
  }
  return c;
}

namespace {

struct OverlayBuilder {
  std::vector<LineVertex>& out;

  void vertex(Vec2 p, Vec2 offset, const std::array<float, 4>& colour) {
    out.push_back({static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(offset.x),
                   static_cast<float>(offset.y), colour[0], colour[1], colour[2], colour[3]});
  }
  // A quad between two scene points with per-end offsets (pixels) of its two long edges.
  void quad(Vec2 a, Vec2 b, Vec2 a_lo, Vec2 a_hi, Vec2 b_lo, Vec2 b_hi, const std::array<float, 4>& ca,
            const std::array<float, 4>& cb) {
    vertex(a, a_lo, ca);
    vertex(b, b_lo, cb);
    vertex(b, b_hi, cb);
    vertex(a, a_lo, ca);
    vertex(b, b_hi, cb);
    vertex(a, a_hi, ca);
  }
  // A stroke of `width` pixels along a polyline of scene points with pixel offsets.
  void stroke(const std::vector<Vec2>& points, const std::vector<Vec2>& offsets, float width,
              const std::array<float, 4>& colour) {
    for (std::size_t i = 0; i + 1 < points.size(); ++i) {
      // Direction of the piece in the scene (the offsets' frame has y up too); the offsets'
      // own slope is ignored, so a steep graph draws a little thinner.
      const Vec2 d = points[i + 1] - points[i];
      const double len = length(d);
      const Vec2 across = len > 0.0 ? Vec2{-d.y / len, d.x / len} : Vec2{0.0, 1.0};
      const Vec2 h = across * (0.5 * width);
      quad(points[i], points[i + 1], offsets[i] - h, offsets[i] + h, offsets[i + 1] - h, offsets[i + 1] + h, colour,
           colour);
    }
  }
  void square(Vec2 p, float half, const std::array<float, 4>& colour) {
    quad(p, p, {-half, -half}, {-half, half}, {half, -half}, {half, half}, colour, colour);
  }
  void diamond(Vec2 p, float half, const std::array<float, 4>& colour) {
    quad(p, p, {-half, 0.0}, {0.0, half}, {0.0, -half}, {half, 0.0}, colour, colour);
  }
};

std::array<float, 4> rgba(const std::array<float, 3>& c, float a) { return {c[0], c[1], c[2], a}; }

}  // namespace

std::pair<std::size_t, std::size_t> newest_journey(const std::vector<PathRecord>& paths) {
  // The run of connected bounces that ends just before `end`.
  auto run_start = [&paths](std::size_t end) {
    std::size_t first = end - 1;
    while (first > 0) {
      const PathRecord& hop = paths[first];
      const PathRecord& before = paths[first - 1];
      // (A hop starts on the curve where the last one landed: the same point to rounding.)
      const double size = length(hop.from) + length(before.from) + length(before.to - before.from);
      const bool next = before.specular ? hop.bounce == before.bounce : hop.bounce == before.bounce + 1;
      if (!next || before.escaped || before.absorbed || before.cut || !(length(hop.from - before.to) <= 1e-9 * size))
        break;
      --first;
    }
    return first;
  };
  std::size_t end = paths.size();
  while (end > 0 && paths[end - 1].cut) end = run_start(end);
  if (end == 0) return {0, 0};
  return {run_start(end), end};
}

namespace {

// The samples per segment that `traces` were made with (trace_curves gives every segment as many).
int traced_samples_per_segment(const Scene& scene, const std::vector<CurveTrace>& traces) {
  for (std::size_t c = 0; c < traces.size() && c < scene.curves.size(); ++c)
    if (scene.curves[c].segment_count > 0 && !traces[c].points.empty())
      return static_cast<int>(traces[c].points.size() / scene.curves[c].segment_count);
  return 48;
}

}  // namespace

std::size_t overlay_vertex_bound(const Scene& scene, int samples_per_segment) {
  const auto per_segment = static_cast<std::size_t>(std::max(samples_per_segment, 2));
  std::size_t vertices = 0;
  for (const Curve& curve : scene.curves) {
    const std::size_t points = per_segment * curve.segment_count;
    if (points < 2) continue;
    constexpr std::size_t kStrips = 2 * 2 + 1;  // band and graph on each side, the stroke
    vertices += (points - 1) * 6 * kStrips;
  }
  return vertices;
}

double render_memory_bound(const Scene& scene, std::size_t paths, int samples_per_segment) {
  double points = 0.0;
  for (const Curve& curve : scene.curves)
    points += static_cast<double>(std::max(samples_per_segment, 2)) * curve.segment_count;
  // A trace point: position, normal, u and s; and B on both sides there.
  const double traces = points * (2.0 * sizeof(Vec2) + 2.0 * sizeof(double) + 2.0 * sizeof(Spectrum));
  // The overlay's vertices, and the piece of them the driver holds at a time (Renderer::draw).
  const double overlay = static_cast<double>(overlay_vertex_bound(scene, samples_per_segment)) * sizeof(LineVertex) +
                         2.0 * (std::size_t{3} << 20) * sizeof(LineVertex);
  // A path: as the solver records it, as the viewer keeps it, and its six vertices, twice.
  const double path_bytes =
      static_cast<double>(paths) * (sizeof(PhotonPath) + sizeof(PathRecord) + 12.0 * sizeof(LineVertex));
  return traces + overlay + path_bytes;
}

std::vector<LineVertex> build_overlay(const Snapshot& snapshot, const DrawOptions& options) {
  std::vector<LineVertex> vertices;
  if (!snapshot.scene || !snapshot.traces) return vertices;
  const Scene& scene = *snapshot.scene;
  const auto& traces = *snapshot.traces;
  // Room for every curve's strips and marks at once: a vector grown by doubling would hold up to
  // three times the vertices while it copies (a scene of 20,000 curves draws 28 million).
  std::size_t marks = 0;
  for (const std::vector<NodeMark>& nodes : snapshot.nodes) marks += nodes.size();
  vertices.reserve(overlay_vertex_bound(scene, snapshot.traces->empty() || (*snapshot.traces)[0].points.empty()
                                                   ? 48
                                                   : traced_samples_per_segment(scene, *snapshot.traces)) +
                   6 * marks + 6 * 256);
  OverlayBuilder out{vertices};
  const double range = radiosity_range(snapshot, options.channel) / std::max(options.band_exposure, 1e-6f);
  const int channels = scene.channels;

  for (std::size_t c = 0; c < traces.size(); ++c) {
    const CurveTrace& trace = traces[c];
    const std::size_t n = trace.points.size();
    if (n < 2) continue;
    const bool selected = static_cast<int>(c) == options.selected_curve;
    for (int side = 0; side < 2; ++side) {
      const double sign = side == 0 ? 1.0 : -1.0;
      const std::vector<Spectrum>* samples =
          c < snapshot.radiosity.size() ? &snapshot.radiosity[c][static_cast<std::size_t>(side)] : nullptr;
      if (samples == nullptr || samples->size() != n) continue;
      // The band: from 2 to 9 pixels off the curve on this side, coloured by B.
      if (options.band) {
        for (std::size_t i = 0; i + 1 < n; ++i) {
          const Vec2 na = trace.normals[i] * sign;
          const Vec2 nb = trace.normals[i + 1] * sign;
          const auto ca = rgba(radiosity_colour((*samples)[i], range, channels, options.channel), 1.0f);
          const auto cb = rgba(radiosity_colour((*samples)[i + 1], range, channels, options.channel), 1.0f);
          out.quad(trace.points[i], trace.points[i + 1], na * 2.0, na * 9.0, nb * 2.0, nb * 9.0, ca, cb);
        }
      }
      // The graph: B(s) as a line offset along the normal by graph_height * B / range.
      if (options.graph) {
        std::vector<Vec2> offsets(n);
        for (std::size_t i = 0; i < n; ++i) {
          double value = 0.0;
          const Spectrum& b = (*samples)[i];
          value = channels == 1 || options.channel == ChannelView::All
                      ? luminance(b, channels)
                      : b[static_cast<std::size_t>(options.channel) - 1];
          const double height = 10.0 + options.graph_height * std::clamp(value / range, 0.0, 1.5);
          offsets[i] = trace.normals[i] * (sign * height);
        }
        const std::array<float, 4> colour =
            selected ? std::array<float, 4>{1.0f, 0.85f, 0.3f, 1.0f} : std::array<float, 4>{0.55f, 0.85f, 1.0f, 0.85f};
        out.stroke(trace.points, offsets, selected ? 2.0f : 1.5f, colour);
      }
    }
    if (options.curves) {
      std::vector<Vec2> zero(n, Vec2{0.0, 0.0});
      // Mirrors steel blue and thicker, glass cyan, detectors green; diffuse curves light grey.
      const Optics optics = c < scene.curves.size() ? scene.material_of(scene.curves[c]).optics : Optics::Diffuse;
      std::array<float, 4> colour = optics_colour(optics);
      const float width = optics == Optics::Mirror ? 3.5f : optics == Optics::Dielectric ? 2.5f : 2.0f;
      if (selected) colour = {1.0f, 0.85f, 0.3f, 1.0f};
      out.stroke(trace.points, zero, selected ? width + 1.0f : width, colour);
    }
    if (c < snapshot.nodes.size()) {
      for (const NodeMark& node : snapshot.nodes[c]) {
        const bool discontinuity = node.continuity != Continuity::C1;
        if (discontinuity && options.discontinuities) {
          const std::array<float, 4> colour = node.continuity == Continuity::Jump
                                                  ? std::array<float, 4>{1.0f, 0.3f, 0.3f, 1.0f}
                                                  : std::array<float, 4>{0.3f, 1.0f, 0.4f, 1.0f};
          out.diamond(node.position, 5.0f, colour);
        } else if (options.storage_nodes) {
          out.square(node.position, 2.0f, {0.6f, 0.6f, 1.0f, 1.0f});
        }
      }
    }
  }
  if (options.paths && options.journey) {
    const auto [first, end] = newest_journey(snapshot.paths);
    for (std::size_t i = first; i < end; ++i) {
      const PathRecord& hop = snapshot.paths[i];
      const std::array<float, 4> colour = rgba(path_palette(hop.bounce), 1.0f);
      const std::array<float, 4> dark{0.0f, 0.0f, 0.0f, 0.9f};
      // A dark casing under the coloured line, so it stands out on bright kept paths.
      out.stroke({hop.from, hop.to}, {Vec2{}, Vec2{}}, 5.0f, dark);
      out.stroke({hop.from, hop.to}, {Vec2{}, Vec2{}}, 2.5f, colour);
      // The direction: an arrowhead 60 % along the hop (its pixel frame has y up, like the scene).
      const Vec2 d = hop.to - hop.from;
      const double len = length(d);
      if (len > 0.0) {
        const Vec2 u = d * (1.0 / len);
        const Vec2 across{-u.y, u.x};
        const Vec2 tip = hop.from + 0.6 * d;
        out.quad(tip, tip, Vec2{}, u * -12.0 + across * 6.0, Vec2{}, u * -12.0 - across * 6.0, colour, colour);
      }
      if (hop.escaped || hop.specular) continue;  // it leaves the scene's box, or flies on: no end mark
      out.square(hop.to, 4.5f, dark);
      out.square(
          hop.to, 3.0f,
          hop.absorbed ? std::array<float, 4>{1.0f, 0.25f, 0.2f, 1.0f} : std::array<float, 4>{1.0f, 1.0f, 1.0f, 1.0f});
      if (hop.absorbed) {  // a cross where the walk ended
        const std::array<float, 4> red{1.0f, 0.25f, 0.2f, 1.0f};
        // Two bars: quad(a, b, a_lo, a_hi, b_lo, b_hi) takes the lo offsets on one long edge.
        out.quad(hop.to, hop.to, {-9.0, -7.0}, {-7.0, -9.0}, {7.0, 9.0}, {9.0, 7.0}, red, red);
        out.quad(hop.to, hop.to, {-9.0, 7.0}, {-7.0, 9.0}, {7.0, -9.0}, {9.0, -7.0}, red, red);
      }
    }
  }
  if (options.control_points) {
    const std::vector<ControlPointRef> points = control_point_list(scene);
    for (std::size_t i = 0; i < points.size(); ++i) {
      const bool hovered = static_cast<int>(i) == options.hovered_control_point;
      out.square(points[i].position, hovered ? 6.0f : 4.0f, {0.1f, 0.1f, 0.1f, 1.0f});
      out.square(points[i].position, hovered ? 4.5f : 3.0f,
                 hovered ? std::array<float, 4>{1.0f, 0.9f, 0.2f, 1.0f} : std::array<float, 4>{1.0f, 1.0f, 1.0f, 1.0f});
    }
  }
  return vertices;
}

namespace {

// Saturated, so that a colour survives the tone mapping where many paths of one round overlap:
// orange, blue, green, magenta, violet, cyan.
constexpr std::array<std::array<float, 3>, 6> kRoundPalette{{{1.0f, 0.45f, 0.05f},
                                                             {0.1f, 0.45f, 1.0f},
                                                             {0.15f, 1.0f, 0.2f},
                                                             {1.0f, 0.15f, 0.6f},
                                                             {0.55f, 0.25f, 1.0f},
                                                             {0.05f, 0.95f, 0.9f}}};

}  // namespace

std::array<float, 3> path_palette(std::uint32_t index) { return kRoundPalette[index % kRoundPalette.size()]; }

namespace {

bool same_view(const ViewTransform& a, const ViewTransform& b) {
  return a.center == b.center && a.scale == b.scale && a.width == b.width && a.height == b.height;
}

}  // namespace

PathInstance PathLayer::instance(const Entry& entry, double factor, int channels, const DrawOptions& options) const {
  const PathRecord& path = entry.path;
  std::array<float, 3> colour{1.0f, 1.0f, 1.0f};
  if (options.path_colour == PathColour::Round) {
    colour = path_palette(path.round);
  } else if (options.path_colour == PathColour::Bounce) {
    colour = path_palette(path.bounce);
  } else if (channels == 3) {
    // The light's colour: channels relative to their mean (the weight carries the power).
    const double mean = luminance(path.power, 3);
    if (mean > 0.0)
      for (std::size_t k = 0; k < 3; ++k) colour[k] = static_cast<float>(path.power[k] / mean);
  }
  const auto w = static_cast<float>(entry.weight * factor);
  return {static_cast<float>(path.from.x),
          static_cast<float>(path.from.y),
          static_cast<float>(path.to.x),
          static_cast<float>(path.to.y),
          colour[0] * w,
          colour[1] * w,
          colour[2] * w,
          1.0f,
          0.0f};
}

std::shared_ptr<const FieldImage> field_image(const LightField& field) {
  auto image = std::make_shared<FieldImage>();
  image->box = field.box();
  image->width = field.width();
  image->height = field.height();
  image->photons = field.photons();
  const double level = field.quantile(kFieldQuantile);
  const double scale = level > 0.0 ? 1.0 / level : 0.0;
  const std::size_t cells = static_cast<std::size_t>(field.width()) * static_cast<std::size_t>(field.height());
  const auto channels = static_cast<std::size_t>(field.channels());
  image->rgba.resize(cells * 4);
  for (std::size_t i = 0; i < cells; ++i) {
    const double* v = field.values().data() + i * channels;
    for (std::size_t k = 0; k < 3; ++k) image->rgba[i * 4 + k] = static_cast<float>(v[channels == 3 ? k : 0] * scale);
    image->rgba[i * 4 + 3] = 1.0f;
  }
  return image;
}

bool shows_field(const Snapshot& snapshot, const DrawOptions& options) {
  if (!snapshot.field || options.light == LightView::Paths) return false;
  return options.light == LightView::Field ||
         (snapshot.paths.size() >= kFieldAutoPaths && options.path_colour == PathColour::Power);
}

PathDraw PathLayer::update(const Snapshot& snapshot, const DrawOptions& options, const ViewTransform& view,
                           std::size_t keep, std::size_t budget) {
  PathDraw draw;
  const int channels = snapshot.scene ? snapshot.scene->channels : 1;
  const float width = static_cast<float>(snapshot.settings.ray_width);
  draw.lines = !(width * view.scale > 1.5);
  if (snapshot.generation != generation_) {
    ring_.clear();
    generation_ = snapshot.generation;
    any_ = false;
    power_unit_ = 0.0;
    valid_ = false;
  }
  if (!options.paths) {
    valid_ = false;
    shown_field_.reset();
    draw.clear = true;
    drawn_ = 0;
    return draw;
  }
  keep = std::max<std::size_t>(keep, 1);
  // The fading per arrival depends on `keep`: the buffer's weights are only known for the old one.
  if (!same_view(view, view_) || options.fade != options_.fade || options.path_colour != options_.path_colour ||
      keep != keep_)
    valid_ = false;
  view_ = view;
  options_ = options;
  keep_ = keep;
  const double rate = 3.0 * options.fade / static_cast<double>(keep);  // fading per arrival
  if (!valid_) {
    draw.clear = true;
    for (Entry& entry : ring_) entry.drawn = false;
    valid_ = true;
  }

  // Arrivals: the snapshot's paths recorded after the last one taken.
  std::size_t arrived = 0;
  for (const PathRecord& path : snapshot.paths) {
    if (any_ && path.serial <= last_serial_) continue;
    const double power = luminance(path.power, channels);
    if (power_unit_ == 0.0 && power > 0.0) power_unit_ = power;
    ring_.push_back({path, arrivals_++, power_unit_ > 0.0 ? power / power_unit_ : 0.0, false});
    last_serial_ = path.serial;
    any_ = true;
    ++arrived;
  }
  if (shows_field(snapshot, options)) {
    // The field replaces the paths: they are drawn again, from the ring, when the paths show.
    for (Entry& entry : ring_) entry.drawn = false;
    while (ring_.size() > keep) ring_.pop_front();
    valid_ = false;
    drawn_ = 0;
    draw.clear = snapshot.field != shown_field_ || !same_view(view, field_view_);
    draw.field = snapshot.field;
    shown_field_ = snapshot.field;
    field_view_ = view;
    return draw;
  }
  shown_field_.reset();
  if (arrived > 0 && rate > 0.0 && !draw.clear)
    draw.decay = static_cast<float>(std::exp(-rate * static_cast<double>(arrived)));
  const std::uint64_t now = arrivals_ == 0 ? 0 : arrivals_ - 1;
  auto factor = [&](const Entry& entry) { return std::exp(-rate * static_cast<double>(now - entry.birth)); };
  // Departures: beyond the last `keep`, subtracted if they were drawn.
  while (ring_.size() > keep) {
    const Entry& old = ring_.front();
    if (old.drawn && !draw.clear) {
      PathInstance removal = instance(old, factor(old), channels, options);
      removal.r = -removal.r;
      removal.g = -removal.g;
      removal.b = -removal.b;
      removal.width = width;
      draw.instances.push_back(removal);
    }
    ring_.pop_front();
  }
  // Draw the newest paths not yet in the buffer, up to the budget.
  std::size_t budget_left = budget;
  for (auto it = ring_.rbegin(); it != ring_.rend() && budget_left > 0; ++it) {
    if (it->drawn) continue;
    PathInstance added = instance(*it, factor(*it), channels, options);
    added.width = width;
    draw.instances.push_back(added);
    it->drawn = true;
    --budget_left;
  }
  // The exposure normalisation: total weight x length (pixels) of what is in the buffer, spread
  // over the viewport, gives the average light per pixel.
  double coverage = 0.0;
  drawn_ = 0;
  double f = 1.0;
  const double step = std::exp(-rate);
  std::uint64_t previous = now;
  for (auto it = ring_.rbegin(); it != ring_.rend(); ++it) {
    for (; previous > it->birth; --previous) f *= step;
    if (!it->drawn) continue;
    ++drawn_;
    coverage += it->weight * f * std::max(length(it->path.to - it->path.from) * view.scale, 1.0);
  }
  const double area = static_cast<double>(view.width) * view.height;
  // About a third of a unit of light on the average lit pixel: dense regions still show structure.
  draw.normalisation = coverage > 0.0 ? static_cast<float>(0.35 * area / coverage) : 1.0f;
  return draw;
}

std::vector<ControlPointRef> control_point_list(const Scene& scene) {
  std::vector<ControlPointRef> points;
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c)
    for (std::uint32_t k = 0; k < scene.curves[c].points.size(); ++k)
      points.push_back({c, k, scene.curves[c].points[k]});
  return points;
}

std::optional<std::uint32_t> pick_curve(const std::vector<CurveTrace>& traces, const ViewTransform& view, Vec2 pixel,
                                        double radius) {
  std::optional<std::uint32_t> best;
  double best_distance = radius;
  for (std::uint32_t c = 0; c < traces.size(); ++c) {
    const auto& points = traces[c].points;
    for (std::size_t i = 0; i + 1 < points.size(); ++i) {
      const Vec2 a = view.to_pixels(points[i]);
      const Vec2 b = view.to_pixels(points[i + 1]);
      const Vec2 ab = b - a;
      const double len2 = dot(ab, ab);
      const double t = len2 > 0.0 ? std::clamp(dot(pixel - a, ab) / len2, 0.0, 1.0) : 0.0;
      const double d = length(pixel - (a + ab * t));
      if (d <= best_distance) {
        best_distance = d;
        best = c;
      }
    }
  }
  return best;
}

}  // namespace flatland::viewer
