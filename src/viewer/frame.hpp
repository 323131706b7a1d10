// What the viewer draws, computed on the CPU without any GL: the view transform, the curves traced
// for drawing, the solver snapshot a frame is drawn from, and the vertex data built from it. The
// renderer only uploads these; tests check them without a display.
#pragma once

#include <array>
#include <cstdint>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "flatland/results/light_field.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/transport/error_estimate.hpp"
#include "flatland/transport/solver.hpp"

namespace flatland::viewer {

// Scene units to pixels. Pixel coordinates have y down (SDL, ImGui and PNG rows); the scene's y
// is up. `scale` is pixels per scene unit.
struct ViewTransform {
  Vec2 center;
  double scale = 1.0;
  int width = 1;
  int height = 1;

  Vec2 to_pixels(Vec2 p) const {
    return {0.5 * width + (p.x - center.x) * scale, 0.5 * height - (p.y - center.y) * scale};
  }
  Vec2 to_scene(Vec2 pixel) const {
    return {center.x + (pixel.x - 0.5 * width) / scale, center.y - (pixel.y - 0.5 * height) / scale};
  }
  // Zoom by `factor` keeping the scene point under `pixel` in place.
  void zoom_about(Vec2 pixel, double factor);
};

// The whole of `bounds` in a width x height viewport, with a margin of `margin` of the smaller
// side on every edge.
ViewTransform fit_view(const Box& bounds, int width, int height, double margin = 0.06);

// A rectangle in window pixels (y down), x0 <= x1, y0 <= y1.
struct PixelRect {
  float x0 = 0.0f, y0 = 0.0f, x1 = 0.0f, y1 = 0.0f;
  float width() const { return x1 - x0; }
  float height() const { return y1 - y0; }
  // Whether the two share interior points (touching edges do not count).
  bool overlaps(const PixelRect& other) const {
    return x0 < other.x1 && other.x0 < x1 && y0 < other.y1 && other.y0 < y1;
  }
  bool operator==(const PixelRect&) const = default;
};

// The viewer's docked layout: the panels live in two columns at the window's sides (solve and
// display controls on the left, status and the inspected curve on the right), below the menu bar,
// and the scene is fitted to the stage between them, so no panel ever covers it. At `ui_scale` 1
// the columns are 340 and 370 pixels wide; where the window is too narrow for them and a stage of
// 40 % of its width, they shrink alike. Without panels (`panels` false) the stage is the whole
// window below the menu bar.
struct StageLayout {
  PixelRect left;
  PixelRect right;
  PixelRect stage;
  PixelRect key;      // under the stage, as wide: the colour key (empty without one)
  PixelRect counter;  // presentation mode: the photon counter's band over the stage (else empty)
};
// The window below the menu: the panels' columns at the sides (none without `panels`; together at
// most 60 % of the width), the stage between them, and a strip `key_height` high under the stage
// for the colour key, so that the key is always in view.
StageLayout stage_layout(int width, int height, float ui_scale, bool panels, float menu_height,
                         float key_height = 0.0f);
// Presentation mode (M), for a projector: the photon counter in a band `counter_height` high above
// the stage, the inspected curve's B(s) in a column `plot_width` wide at the right (none at 0, and
// at most 45 % of the width) and the key's strip under the stage: the stage takes the rest, so
// nothing is drawn over the scene (`right` is the plot's column).
StageLayout presentation_layout(int width, int height, float menu_height, float key_height, float counter_height,
                                float plot_width);

// The whole of `bounds` inside `stage` of a width x height window, with a margin of `margin` of the
// stage's smaller side.
ViewTransform fit_view(const Box& bounds, int width, int height, const PixelRect& stage, double margin = 0.05);

// A curve sampled for drawing: every segment from end to end (corners stay sharp), positions,
// unit front normals, curve parameter u and arc length s at each sample.
struct CurveTrace {
  std::vector<Vec2> points;
  std::vector<Vec2> normals;
  std::vector<double> u;
  std::vector<double> s;
};
std::vector<CurveTrace> trace_curves(const Scene& scene, int samples_per_segment = 48);

// A photon path as the viewer keeps it.
struct PathRecord {
  std::uint64_t serial = 0;  // order of recording within one solve (Snapshot::generation)
  Vec2 from;
  Vec2 to;
  Spectrum power{};
  std::uint32_t round = 0;
  std::uint32_t bounce = 0;  // reflections before this flight (PhotonPath::bounce)
  bool escaped = false;
  bool absorbed = false;  // a walk ended where this flight landed
  bool cut = false;       // the walk went on, unrecorded (the record was full)
  // Where it landed (not escaped): the curve, the side and the arc length along the curve.
  std::uint32_t hit_curve = 0;
  Side hit_side = Side::Front;
  double hit_s = 0.0;
  // It ended on a mirror, glass or a detector and the photon flew on (the next record, with the
  // same bounce, is that flight).
  bool specular = false;
};

// A photon path for drawing: from its origin to its hit, or, for a photon that escaped (`end` is
// then origin + direction), to where it leaves the scene's box.
// (The box is padded by 5 % of the scene's size, so light escaping a flat scene still shows.)
// The records of one flight: one a leg for a flight through a specular chain (PhotonPath::via),
// their serials consecutive from `serial` (advanced past them). Every front end draws paths
// through this; path_record alone is the last leg's record.
void append_path_records(const PhotonPath& path, const Scene& scene, std::uint64_t& serial, std::uint32_t round,
                         std::vector<PathRecord>& out);
PathRecord path_record(const PhotonPath& path, const Scene& scene, std::uint64_t serial, std::uint32_t round);

// A storage-mesh node of a curve: where, and the continuity of the illumination there.
struct NodeMark {
  Vec2 position;
  double s = 0.0;  // arc length from the curve's start
  Continuity continuity = Continuity::C1;
  bool visibility_event = false;  // added by discontinuity meshing (not a scene joint)
};

// The light field as the renderer draws it: the fluence of LightField divided by the 99th percentile
// of its lit cells' luminance (so the brightest percent of the light saturates and the rest keeps
// its proportions), as RGBA floats (alpha 1), rows from box.lower.y. Remade at most a few times a
// second; a new image is a new object.
struct FieldImage {
  Box box;
  int width = 0;
  int height = 0;
  std::vector<float> rgba;
  double photons = 0.0;  // photons the field stands for
};
inline constexpr double kFieldQuantile = 0.99;
std::shared_ptr<const FieldImage> field_image(const LightField& field);

// Everything a frame is drawn from, published by the solving thread; immutable once published.
struct Snapshot {
  std::uint64_t generation = 0;  // changes whenever the solve restarts (new scene or settings)
  std::shared_ptr<const Scene> scene;
  std::shared_ptr<const std::vector<CurveTrace>> traces;
  SolverSettings settings;
  std::string error;  // why there is no solve (bad settings, scene error), empty when fine
  // B at every trace sample, per curve and side (empty for a side that neither emits nor reflects).
  std::vector<std::array<std::vector<Spectrum>, 2>> radiosity;
  std::vector<std::vector<NodeMark>> nodes;  // per curve: interior storage nodes
  std::vector<double> received_share;        // per curve: its share of all reflected power
  std::vector<PathRecord> paths;             // oldest first
  // The light of every recorded flight of the solve, each standing for its share of the photons
  // shot (LightField::add_record); null before anything is recorded.
  std::shared_ptr<const FieldImage> field;
  SolverProgress progress;
  EnergyBooks books;
  StopReason stop_reason = StopReason::Running;
  std::uint64_t round_photons = 0;  // photons of the open round, and how many are shot
  std::uint64_t round_done = 0;
  double photons_per_second = 0.0;
  bool running = false;
  // Against a loaded reference: the error so far (relative L2 of B over the scene), its history
  // against elapsed solve time, and the reference's B samples per curve (luminance, main side).
  std::optional<double> reference_error;
  std::vector<std::array<double, 2>> error_history;                  // {seconds, rel_l2}
  std::vector<std::vector<std::array<double, 2>>> reference_curves;  // per curve {s, B}
  // The solve's own estimated error (the scene's and each curve's bound) and, per curve and side,
  // the bound's half-width at every trace sample (the channels' mean, as the plot shows B); remade
  // about twice a second of solving and when the solve stops.
  std::optional<ErrorEstimate> estimated_error;
  // The estimate is of the final gather's B (once the solve has stopped, with a gather); empty, or
  // why --gather auto gathers nothing on this scene.
  bool estimate_gathered = false;
  std::string gather_skipped;
  // Why --control-variate auto runs without the variate on this scene (empty where it runs it).
  std::string variate_skipped;
  std::shared_ptr<const std::vector<std::array<std::vector<double>, 2>>> error_band;
  // Detector curves: per curve and side (the side the light arrives on), the power per unit
  // length that crossed each bin (empty for other curves).
  std::vector<std::array<std::vector<Spectrum>, 2>> detected;
};

// Radiosity of a sample for display: one number (the channels' mean).
double luminance(const Spectrum& b, int channels);

// A vertex of the overlay (curves, bands, graphs, markers): a scene point, an offset in pixels
// (y up), and a display-encoded RGBA colour.
struct LineVertex {
  float x, y;
  float offset_x, offset_y;
  float r, g, b, a;
};
// One photon path for the path shader.
struct PathInstance {
  float from_x, from_y, to_x, to_y;
  float r, g, b, a;
  float width;
};

// Paths coloured by their light (power and colour), by the round that shot them, or by the
// number of reflections their light has had (a walk's hops; shooting's round number).
enum class PathColour { Power, Round, Bounce };
enum class ChannelView { All, Red, Green, Blue };
// What the light layer shows: the kept paths, each a line; the light field of the whole solve; or,
// automatically, the paths while few are kept (stepping a photon at a time) and the field once
// kFieldAutoPaths are.
enum class LightView { Auto, Paths, Field };
inline constexpr std::size_t kFieldAutoPaths = 4096;
// The colour of round or bounce `index` (six saturated colours, repeating).
std::array<float, 3> path_palette(std::uint32_t index);

// The colour a curve of these optics is drawn in on the stage (mirrors steel blue, glass cyan,
// detectors green, diffuse light grey), shared by the stage and the materials' legend.
std::array<float, 4> optics_colour(Optics optics);
// A curve's material in a few words for a legend or a tooltip: "mirror", "glass, n 1.62 at 588 nm",
// "detector, 60 bins", "diffuse, rho 0.7", with ", emits" for an emitter.
std::string material_words(const Scene& scene, const Curve& curve);

struct DrawOptions {
  bool curves = true;
  bool band = true;  // colour-mapped band of B along each lit side
  // B(s) as a graph offset along the normal: off by default (drawn beside the curves it reads as
  // more geometry); the curve panel plots B(s) with axes instead.
  bool graph = false;
  bool control_points = false;
  bool storage_nodes = false;
  bool discontinuities = true;  // mark nodes below C1
  bool paths = true;
  // The newest photon's journey drawn on top of the kept paths: every hop thick in its bounce's
  // colour with an arrowhead, a square where it landed, a cross where it was absorbed.
  bool journey = true;
  float path_exposure = 1.0f;  // multiplies the automatic path normalisation
  float band_exposure = 1.0f;  // multiplies the automatic radiosity normalisation
  float graph_height = 60.0f;  // pixels for the largest B
  float fade = 1.0f;           // 0: every kept path equally bright; 1: the oldest fade to ~5 %
  PathColour path_colour = PathColour::Power;
  LightView light = LightView::Auto;
  ChannelView channel = ChannelView::All;
  int selected_curve = -1;
  int hovered_control_point = -1;  // index into control_point_list()
};

// The largest B to map to full brightness: the 99th percentile of the samples on curves that do not
// emit (so neither the lights nor one hot spot darken the rest; the emitters' own samples when
// nothing else is lit yet), at least a tiny positive value.
double radiosity_range(const Snapshot& snapshot, ChannelView channel);

// Colour of a radiosity value: grey scenes through a perceptual colour map, colour scenes as the
// light's own colour, tone mapped; `value` is B / radiosity_range.
std::array<float, 3> radiosity_colour(const Spectrum& b, double range, int channels, ChannelView channel);
// The colour map for grey values (t in [0, 1]): dark blue through orange to pale yellow.
std::array<float, 3> colour_map(double t);

// The overlay's triangles for the given snapshot and options; sizes in pixels (independent of
// zoom, so this is rebuilt only when the snapshot or the options change).
std::vector<LineVertex> build_overlay(const Snapshot& snapshot, const DrawOptions& options);

// The most vertices build_overlay makes for the curves of `scene` traced with `samples_per_segment`
// (trace_curves): on each of the two sides a band and a graph, and the curve's stroke, six vertices
// a piece between trace points; the few marks of storage nodes and the newest journey are left out.
std::size_t overlay_vertex_bound(const Scene& scene, int samples_per_segment = 48);
// An upper bound of the memory drawing `scene` once takes, before any of it is allocated: the
// traces and the radiosity sampled on them, the overlay's vertices (and the piece of them the
// driver copies at a time), and `paths` photon paths.
double render_memory_bound(const Scene& scene, std::size_t paths, int samples_per_segment = 48);

// The newest photon's journey among `paths` (oldest first): the indices [first, paths.size()) of
// the run of paths that ends with the last one, each a bounce after the one before and starting
// where it landed (a walk's hops); a walk whose record was cut short is passed over for the one
// before. With shooting, the last path alone. Empty for no paths.
std::pair<std::size_t, std::size_t> newest_journey(const std::vector<PathRecord>& paths);

// What the path buffer does this frame (see PathLayer).
struct PathDraw {
  bool clear = false;                   // start from an empty buffer
  float decay = 1.0f;                   // multiply the accumulated light by this first (fading by age)
  std::vector<PathInstance> instances;  // then add these; a negative colour removes a path
  bool lines = true;                    // point rays: 1-pixel lines; extended rays: quads as wide as the ray
  float normalisation = 1.0f;           // exposure factor that makes the average lit pixel about 1
  // The light field instead of paths (already normalised): drawn into the cleared buffer when
  // `clear` is set, else the buffer holds it from an earlier frame.
  std::shared_ptr<const FieldImage> field;
};

// Whether the light layer shows the field (LightView; Auto: a field exists, at least
// kFieldAutoPaths paths are kept and they are coloured by power: the field has no rounds).
bool shows_field(const Snapshot& snapshot, const DrawOptions& options);

// The photon paths on screen, kept in a floating-point buffer that is updated incrementally: a
// software rasteriser cannot redraw 20,000 long paths every frame, so each frame draws only the
// paths that arrived (at most `budget`, newest first), fades the buffer by their number, and
// subtracts the paths that fell out of the last `keep`. A path's weight at age a (in paths) is
// power x exp(-3 fade a / keep). After a change of view, colouring or fade, the buffer is rebuilt
// from the kept paths over the next frames, newest first.
class PathLayer {
 public:
  PathDraw update(const Snapshot& snapshot, const DrawOptions& options, const ViewTransform& view, std::size_t keep,
                  std::size_t budget);
  void invalidate() { valid_ = false; }
  std::size_t drawn() const { return drawn_; }  // paths in the buffer now

 private:
  struct Entry {
    PathRecord path;
    std::uint64_t birth = 0;  // arrival number
    double weight = 0.0;      // power at age 0 (normalised)
    bool drawn = false;
  };
  PathInstance instance(const Entry& entry, double factor, int channels, const DrawOptions& options) const;

  std::deque<Entry> ring_;
  std::uint64_t generation_ = ~0ull;
  std::uint64_t last_serial_ = 0;
  bool any_ = false;
  std::uint64_t arrivals_ = 0;
  double power_unit_ = 0.0;  // the first path's power: weights are relative to it
  bool valid_ = false;
  ViewTransform view_;
  DrawOptions options_;
  std::size_t keep_ = 0;
  std::size_t drawn_ = 0;
  // The field in the buffer (null: paths are) and the view it was drawn for.
  std::shared_ptr<const FieldImage> shown_field_;
  ViewTransform field_view_;
};

// Every control point of the scene, in order (curve by curve), for picking and dragging.
struct ControlPointRef {
  std::uint32_t curve = 0;
  std::uint32_t index = 0;  // into Curve::points
  Vec2 position;
};
std::vector<ControlPointRef> control_point_list(const Scene& scene);

// The curve nearest to `pixel` within `radius` pixels, if any.
std::optional<std::uint32_t> pick_curve(const std::vector<CurveTrace>& traces, const ViewTransform& view, Vec2 pixel,
                                        double radius = 6.0);

}  // namespace flatland::viewer
