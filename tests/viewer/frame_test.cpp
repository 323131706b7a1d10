// The viewer's CPU side (src/viewer/frame): view transform, curve traces, the path layer's
// incremental bookkeeping, the overlay and picking. No GL, no display.
#include "viewer/frame.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "test_support.hpp"

namespace flatland::viewer {
namespace {

TEST(Frame, FitViewShowsTheWholeSceneWithItsMargin) {
  Box bounds;
  bounds.extend(Vec2{-3.0, -1.0});
  bounds.extend(Vec2{5.0, 2.0});
  const ViewTransform view = fit_view(bounds, 800, 600, 0.05);
  const double margin = 0.05 * 600;
  for (Vec2 corner : {bounds.lower, bounds.upper, Vec2{bounds.lower.x, bounds.upper.y}}) {
    const Vec2 p = view.to_pixels(corner);
    EXPECT_GE(p.x, margin - 1e-9);
    EXPECT_LE(p.x, 800 - margin + 1e-9);
    EXPECT_GE(p.y, margin - 1e-9);
    EXPECT_LE(p.y, 600 - margin + 1e-9);
    const Vec2 back = view.to_scene(p);
    EXPECT_NEAR(back.x, corner.x, 1e-12);
    EXPECT_NEAR(back.y, corner.y, 1e-12);
  }
  // The wide scene fills the width exactly; y is up in the scene and down in pixels.
  EXPECT_NEAR(view.to_pixels(bounds.upper).x - view.to_pixels(bounds.lower).x, 800 - 2 * margin, 1e-9);
  EXPECT_LT(view.to_pixels(bounds.upper).y, view.to_pixels(bounds.lower).y);
}

TEST(Frame, DockedLayoutKeepsTheStageClearOfThePanelColumns) {
  for (const auto& [width, height] : {std::pair{1280, 800}, {1024, 768}, {800, 600}, {1920, 1080}, {640, 900}}) {
    for (float scale : {1.0f, 1.5f, 2.0f}) {
      const StageLayout layout = stage_layout(width, height, scale, true, 20.0f);
      EXPECT_FALSE(layout.left.overlaps(layout.stage)) << width << "x" << height << " scale " << scale;
      EXPECT_FALSE(layout.right.overlaps(layout.stage)) << width << "x" << height << " scale " << scale;
      // The three share the window below the menu exactly, and the stage keeps at least 40 %.
      EXPECT_FLOAT_EQ(layout.left.width() + layout.stage.width() + layout.right.width(), static_cast<float>(width));
      EXPECT_GE(layout.stage.width(), 0.4f * static_cast<float>(width) - 1.0f);
      EXPECT_EQ(layout.stage.y0, 20.0f);
      EXPECT_EQ(layout.stage.y1, static_cast<float>(height));
      // Any scene fitted to the stage stays inside it: wide, tall, and a single point.
      for (const auto& [lower, upper] :
           {std::pair{Vec2{-3, -1}, Vec2{5, 2}}, {Vec2{0, 0}, Vec2{0.1, 7}}, {Vec2{1, 1}, Vec2{1, 1}}}) {
        Box bounds;
        bounds.extend(lower);
        bounds.extend(upper);
        const ViewTransform view = fit_view(bounds, width, height, layout.stage);
        for (Vec2 corner : {bounds.lower, bounds.upper}) {
          const Vec2 p = view.to_pixels(corner);
          EXPECT_GE(p.x, layout.stage.x0 - 1e-6);
          EXPECT_LE(p.x, layout.stage.x1 + 1e-6);
          EXPECT_GE(p.y, layout.stage.y0 - 1e-6);
          EXPECT_LE(p.y, layout.stage.y1 + 1e-6);
        }
        // Centred in the stage.
        const Vec2 centre = view.to_pixels(0.5 * (bounds.lower + bounds.upper));
        EXPECT_NEAR(centre.x, 0.5 * (layout.stage.x0 + layout.stage.x1), 1e-6);
        EXPECT_NEAR(centre.y, 0.5 * (layout.stage.y0 + layout.stage.y1), 1e-6);
      }
    }
  }
  // Without panels the stage is the whole window below the menu.
  const StageLayout bare = stage_layout(1280, 800, 1.0f, false, 20.0f);
  EXPECT_EQ(bare.stage, (PixelRect{0.0f, 20.0f, 1280.0f, 800.0f}));
}

TEST(Frame, NewestJourneyIsTheLastRunOfConnectedBounces) {
  auto hop = [](Vec2 from, Vec2 to, std::uint32_t bounce, bool escaped = false, bool absorbed = false) {
    PathRecord record;
    record.from = from;
    record.to = to;
    record.bounce = bounce;
    record.escaped = escaped;
    record.absorbed = absorbed;
    return record;
  };
  EXPECT_EQ(newest_journey({}), (std::pair<std::size_t, std::size_t>{0, 0}));
  // An earlier walk that escaped, then a walk of three hops (the last absorbed).
  std::vector<PathRecord> paths{hop({0, 0}, {1, 0}, 0), hop({1, 0}, {5, 5}, 1, true), hop({0, 1}, {2, 2}, 0),
                                hop({2, 2}, {3, 0}, 1), hop({3, 0}, {0, 0}, 2, false, true)};
  EXPECT_EQ(newest_journey(paths), (std::pair<std::size_t, std::size_t>{2, 5}));
  // A hop that does not start where the last one landed begins a new journey.
  paths[4].from = {3.5, 0};
  EXPECT_EQ(newest_journey(paths), (std::pair<std::size_t, std::size_t>{4, 5}));
  // Shooting: every path of a round has the same bounce, so the newest is the last path alone.
  std::vector<PathRecord> round{hop({0, 0}, {1, 0}, 2), hop({1, 0}, {2, 0}, 2)};
  EXPECT_EQ(newest_journey(round), (std::pair<std::size_t, std::size_t>{1, 2}));
}

TEST(Frame, AChainIsDrawnLegByLegAndIsOneJourney) {
  // A flight from (0, 0) that met a mirror at (1, 0) and glass at (1, 1), then landed at (0, 2).
  const Scene scene = testing::scene_from_file("scenes2d/lens.json");
  PhotonPath path;
  path.origin = {0, 0};
  path.via = {{1, 0}, {1, 1}};
  path.end = {0, 2};
  path.hit_curve = 2;
  path.bounce = 3;
  std::vector<PathRecord> records;
  std::uint64_t serial = 7;
  append_path_records(path, scene, serial, 4, records);
  ASSERT_EQ(records.size(), 3u);
  EXPECT_EQ(serial, 10u);
  const Vec2 points[] = {{0, 0}, {1, 0}, {1, 1}, {0, 2}};
  for (std::size_t i = 0; i < 3; ++i) {
    EXPECT_EQ(records[i].from, points[i]);
    EXPECT_EQ(records[i].to, points[i + 1]);
    EXPECT_EQ(records[i].serial, 7 + i);
    EXPECT_EQ(records[i].bounce, 3u);
    EXPECT_EQ(records[i].round, 4u);
    EXPECT_EQ(records[i].specular, i < 2);
  }
  EXPECT_EQ(records[2].hit_curve, 2u);
  // The newest journey runs through the legs.
  EXPECT_EQ(newest_journey(records), (std::pair<std::size_t, std::size_t>{0, 3}));
  // An escaped flight leaves along its last leg: towards +y from (1, 1), to the box's edge.
  path.escaped = true;
  path.end = Vec2{1, 1} + Vec2{0, 1};
  records.clear();
  append_path_records(path, scene, serial, 4, records);
  ASSERT_EQ(records.size(), 3u);
  EXPECT_EQ(records[2].from, (Vec2{1, 1}));
  EXPECT_EQ(records[2].to.x, 1.0);
  EXPECT_GT(records[2].to.y, scene.bounds.upper.y);
}

TEST(Frame, ZoomKeepsThePointUnderTheCursor) {
  Box bounds;
  bounds.extend(Vec2{0.0, 0.0});
  bounds.extend(Vec2{1.0, 1.0});
  ViewTransform view = fit_view(bounds, 640, 480);
  const Vec2 cursor{100.0, 50.0};
  const Vec2 before = view.to_scene(cursor);
  view.zoom_about(cursor, 3.0);
  const Vec2 after = view.to_scene(cursor);
  EXPECT_NEAR(before.x, after.x, 1e-12);
  EXPECT_NEAR(before.y, after.y, 1e-12);
}

TEST(Frame, TracesFollowEveryCurveFromEndToEnd) {
  const Scene scene = testing::scene_from_file("scenes2d/mixed.json");
  const std::vector<CurveTrace> traces = trace_curves(scene, 16);
  ASSERT_EQ(traces.size(), scene.curves.size());
  for (std::size_t c = 0; c < scene.curves.size(); ++c) {
    const Curve& curve = scene.curves[c];
    const CurveTrace& trace = traces[c];
    ASSERT_EQ(trace.points.size(), 16u * curve.segment_count);
    EXPECT_NEAR(trace.s.front(), 0.0, 1e-6 * curve.length);
    EXPECT_NEAR(trace.s.back(), curve.length, 1e-6 * curve.length);
    const Vec2 first = curve.points.front();
    const Vec2 last = curve.points.back();
    EXPECT_LT(length(trace.points.front() - first), 1e-6 * scene.scale);
    EXPECT_LT(length(trace.points.back() - last), 1e-6 * scene.scale);
    for (std::size_t i = 0; i < trace.points.size(); ++i) {
      EXPECT_NEAR(length(trace.normals[i]), 1.0, 1e-9);
      if (i > 0) {
        EXPECT_GE(trace.s[i], trace.s[i - 1]);
        // Each sample is where its arc length says (chord <= arc).
        EXPECT_LE(length(trace.points[i] - trace.points[i - 1]), trace.s[i] - trace.s[i - 1] + 1e-9 * scene.scale);
      }
    }
  }
}

// A snapshot with `count` paths of unit power along the x axis, serials from `first`.
Snapshot path_snapshot(std::shared_ptr<const Scene> scene, std::uint64_t first, std::uint64_t count) {
  Snapshot snapshot;
  snapshot.scene = std::move(scene);
  for (std::uint64_t i = 0; i < count; ++i) {
    PathRecord path;
    path.serial = first + i;
    path.from = {0.0, 0.0};
    path.to = {1.0, 0.0};
    path.power = {1.0, 1.0, 1.0};
    snapshot.paths.push_back(path);
  }
  return snapshot;
}

double light_sum(const PathDraw& draw) {
  double sum = 0.0;
  for (const PathInstance& instance : draw.instances) sum += instance.r;
  return sum;
}

TEST(Frame, PathLayerAddsArrivalsAndSubtractsDeparturesExactly) {
  // Without fading, the buffer must hold exactly the last `keep` paths: the light added minus the
  // light removed, summed over frames, equals keep unit paths.
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/penumbra.json"));
  DrawOptions options;
  options.fade = 0.0f;
  const ViewTransform view = fit_view(scene->bounds, 400, 300);
  PathLayer layer;
  double buffer = 0.0;
  std::uint64_t serial = 0;
  for (std::uint64_t arrivals : {7u, 3u, 12u, 1u, 9u}) {
    Snapshot snapshot = path_snapshot(scene, serial, arrivals);
    serial += arrivals;
    const PathDraw draw = layer.update(snapshot, options, view, 10, 1000);
    if (draw.clear) buffer = 0.0;
    EXPECT_EQ(draw.decay, 1.0f);
    buffer += light_sum(draw);
    EXPECT_NEAR(buffer, std::min<double>(static_cast<double>(serial), 10.0), 1e-6);
    EXPECT_EQ(layer.drawn(), std::min<std::size_t>(serial, 10));
  }
  // The same snapshot again brings nothing new.
  const PathDraw again = layer.update(path_snapshot(scene, serial - 9, 9), options, view, 10, 1000);
  EXPECT_TRUE(again.instances.empty());
}

TEST(Frame, PathLayerFadesByAgeAndRemovesWhatRemains) {
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/penumbra.json"));
  DrawOptions options;
  options.fade = 1.0f;
  const ViewTransform view = fit_view(scene->bounds, 400, 300);
  PathLayer layer;
  const std::size_t keep = 20;
  const double r = std::exp(-3.0 / keep);  // fading per arrival
  double buffer = 0.0;
  std::uint64_t serial = 0;
  for (std::uint64_t arrivals : {5u, 5u, 5u, 5u, 5u, 5u, 5u}) {
    const PathDraw draw = layer.update(path_snapshot(scene, serial, arrivals), options, view, keep, 1000);
    serial += arrivals;
    if (draw.clear) buffer = 0.0;
    buffer = buffer * draw.decay + light_sum(draw);
    // Independent sum: the kept paths at ages 0 .. n-1 weigh r^age.
    const std::size_t n = std::min<std::size_t>(serial, keep);
    double expected = 0.0;
    for (std::size_t age = 0; age < n; ++age) expected += std::pow(r, static_cast<double>(age));
    EXPECT_NEAR(buffer, expected, 1e-5) << serial;
  }
}

TEST(Frame, PathLayerStartsOverWhenTheKeptNumberChanges) {
  // The fading per arrival depends on how many paths are kept; after a change the buffer must hold
  // the new set with the new weights, never ghosts of the old ones.
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/penumbra.json"));
  DrawOptions options;
  options.fade = 1.0f;
  const ViewTransform view = fit_view(scene->bounds, 400, 300);
  PathLayer layer;
  double buffer = 0.0;
  std::uint64_t serial = 0;
  const std::pair<std::uint64_t, std::size_t> frames[] = {{30, 40}, {10, 40}, {5, 8}, {5, 8}, {20, 60}, {7, 60}};
  for (const auto& [arrivals, keep] : frames) {
    const PathDraw draw = layer.update(path_snapshot(scene, serial, arrivals), options, view, keep, 1000);
    serial += arrivals;
    if (draw.clear) buffer = 0.0;
    buffer = buffer * draw.decay + light_sum(draw);
    // The buffer holds the last min(serial, keep) paths weighted r^age with r for this keep, except
    // after growing `keep`: paths dropped earlier do not come back.
    const double r = std::exp(-3.0 / static_cast<double>(keep));
    double expected = 0.0;
    for (std::size_t age = 0; age < std::min<std::size_t>(layer.drawn(), keep); ++age)
      expected += std::pow(r, static_cast<double>(age));
    EXPECT_NEAR(buffer, expected, 1e-5) << "after " << serial << " paths, keep " << keep;
    EXPECT_GE(buffer, 0.0);
  }
}

TEST(Frame, PathLayerDrawsTheNewestFirstWithinItsBudget) {
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/penumbra.json"));
  DrawOptions options;
  const ViewTransform view = fit_view(scene->bounds, 400, 300);
  PathLayer layer;
  Snapshot snapshot = path_snapshot(scene, 0, 100);
  for (std::size_t i = 0; i < 100; ++i) snapshot.paths[i].from.y = static_cast<double>(i);  // tag
  const PathDraw first = layer.update(snapshot, options, view, 1000, 30);
  ASSERT_EQ(first.instances.size(), 30u);
  EXPECT_EQ(first.instances.front().from_y, 99.0f);
  EXPECT_EQ(first.instances.back().from_y, 70.0f);
  // The rest follow in later frames, still newest first; a view change starts over.
  const PathDraw second = layer.update(snapshot, options, view, 1000, 30);
  EXPECT_FALSE(second.clear);
  EXPECT_EQ(second.instances.front().from_y, 69.0f);
  ViewTransform moved = view;
  moved.center.x += 1.0;
  const PathDraw third = layer.update(snapshot, options, moved, 1000, 30);
  EXPECT_TRUE(third.clear);
  EXPECT_EQ(third.instances.front().from_y, 99.0f);
  // Another solve (generation) forgets the old paths.
  Snapshot next = path_snapshot(scene, 0, 3);
  next.generation = snapshot.generation + 1;
  const PathDraw fourth = layer.update(next, options, moved, 1000, 30);
  EXPECT_TRUE(fourth.clear);
  EXPECT_EQ(fourth.instances.size(), 3u);
}

// The field's image is the fluence divided by the 99th percentile of its lit cells (so that
// percentile shows at 1 and the rest keeps its proportions), grey fields copied to r, g and b.
TEST(Frame, FieldImageIsTheFluenceOverItsHighPercentile) {
  Box box;
  box.lower = {0.0, 0.0};
  box.upper = {100.0, 1.0};
  Result<LightField> field = LightField::create(box, 100, 1);
  ASSERT_TRUE(field.ok());
  // Cell k crossed by a leg of power k + 1: luminance k + 1 (cells 0..99); the 99th percentile
  // of the 100 lit cells is the 99th smallest, 99.
  for (int k = 0; k < 100; ++k) field->add_leg({k + 0.0, 0.5}, {k + 1.0, 0.5}, {k + 1.0, 0.0, 0.0}, 1.0);
  const std::shared_ptr<const FieldImage> image = field_image(*field);
  ASSERT_EQ(image->width, 100);
  ASSERT_EQ(image->height, 1);
  for (int k = 0; k < 100; ++k) {
    EXPECT_FLOAT_EQ(image->rgba[static_cast<std::size_t>(k) * 4], static_cast<float>((k + 1.0) / 99.0));
    EXPECT_EQ(image->rgba[static_cast<std::size_t>(k) * 4 + 2], image->rgba[static_cast<std::size_t>(k) * 4]);
    EXPECT_EQ(image->rgba[static_cast<std::size_t>(k) * 4 + 3], 1.0f);
  }
}

// Auto shows the paths while few are kept (stepping) or while they are coloured by round or
// bounce, the field otherwise; the field is drawn again only when it or the view changed, and the
// paths come back whole when they show again.
TEST(Frame, PathLayerShowsTheFieldInPlaceOfManyPaths) {
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/penumbra.json"));
  Result<LightField> made = LightField::for_scene(*scene, 16);
  ASSERT_TRUE(made.ok());
  DrawOptions options;
  options.fade = 0.0f;
  const ViewTransform view = fit_view(scene->bounds, 400, 300);
  PathLayer layer;
  Snapshot few = path_snapshot(scene, 0, 10);
  few.field = field_image(*made);
  EXPECT_FALSE(shows_field(few, options));
  const PathDraw paths = layer.update(few, options, view, kFieldAutoPaths * 2, kFieldAutoPaths * 2);
  EXPECT_EQ(paths.field, nullptr);
  EXPECT_EQ(paths.instances.size(), 10u);

  Snapshot many = path_snapshot(scene, 10, kFieldAutoPaths);
  many.field = few.field;
  EXPECT_TRUE(shows_field(many, options));
  const PathDraw field = layer.update(many, options, view, kFieldAutoPaths * 2, kFieldAutoPaths * 2);
  EXPECT_EQ(field.field, many.field);
  EXPECT_TRUE(field.clear);
  EXPECT_TRUE(field.instances.empty());
  EXPECT_FALSE(layer.update(many, options, view, kFieldAutoPaths * 2, kFieldAutoPaths * 2).clear);
  ViewTransform moved = view;
  moved.scale *= 2.0;
  EXPECT_TRUE(layer.update(many, options, moved, kFieldAutoPaths * 2, kFieldAutoPaths * 2).clear);
  many.field = field_image(*made);  // a new image
  EXPECT_TRUE(layer.update(many, options, moved, kFieldAutoPaths * 2, kFieldAutoPaths * 2).clear);

  // Coloured by bounce: the paths again, every kept one redrawn from a cleared buffer.
  options.path_colour = PathColour::Bounce;
  EXPECT_FALSE(shows_field(many, options));
  const PathDraw back = layer.update(many, options, moved, kFieldAutoPaths * 2, kFieldAutoPaths * 2);
  EXPECT_TRUE(back.clear);
  EXPECT_EQ(back.field, nullptr);
  EXPECT_EQ(back.instances.size(), kFieldAutoPaths + 10);
  // Forced either way.
  options.light = LightView::Field;
  EXPECT_TRUE(shows_field(few, options));
  options.light = LightView::Paths;
  options.path_colour = PathColour::Power;
  EXPECT_FALSE(shows_field(many, options));
  Snapshot none = many;
  none.field.reset();
  options.light = LightView::Field;
  EXPECT_FALSE(shows_field(none, options));
}

TEST(Frame, OverlayStaysOnTheCurvesWithinItsPixelOffsets) {
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/default.json"));
  Snapshot snapshot;
  snapshot.scene = scene;
  auto traces = std::make_shared<const std::vector<CurveTrace>>(trace_curves(*scene));
  snapshot.traces = traces;
  snapshot.radiosity.resize(scene->curves.size());
  for (std::size_t c = 0; c < scene->curves.size(); ++c)
    snapshot.radiosity[c][0].assign((*traces)[c].points.size(), Spectrum{1.0, 2.0, 3.0});
  DrawOptions options;
  options.control_points = true;
  options.graph_height = 60.0f;
  const std::vector<LineVertex> vertices = build_overlay(snapshot, options);
  ASSERT_FALSE(vertices.empty());
  EXPECT_EQ(vertices.size() % 3, 0u);  // triangles
  const double slack = 1e-6 * scene->scale;
  for (const LineVertex& v : vertices) {
    EXPECT_GE(v.x, scene->bounds.lower.x - slack);
    EXPECT_LE(v.x, scene->bounds.upper.x + slack);
    EXPECT_GE(v.y, scene->bounds.lower.y - slack);
    EXPECT_LE(v.y, scene->bounds.upper.y + slack);
    EXPECT_LE(std::hypot(v.offset_x, v.offset_y), 10.0 + 1.5 * 60.0 + 2.0);
    for (float channel : {v.r, v.g, v.b, v.a}) {
      EXPECT_GE(channel, 0.0f);
      EXPECT_LE(channel, 1.0f);
    }
  }
}

// The bound that render checks memory with, before anything is drawn: the overlay of every curve
// with B on both sides, band, graph and stroke, is never larger, and the bound is tight.
TEST(Frame, OverlayVertexBoundHoldsAndIsTight) {
  auto scene = std::make_shared<const Scene>(testing::scene_from_file("scenes2d/default.json"));
  Snapshot snapshot;
  snapshot.scene = scene;
  auto traces = std::make_shared<const std::vector<CurveTrace>>(trace_curves(*scene));
  snapshot.traces = traces;
  snapshot.radiosity.resize(scene->curves.size());
  for (std::size_t c = 0; c < scene->curves.size(); ++c)
    for (int side = 0; side < 2; ++side)
      snapshot.radiosity[c][static_cast<std::size_t>(side)].assign((*traces)[c].points.size(), Spectrum{1.0, 2.0, 3.0});
  DrawOptions options;
  options.band = options.graph = options.curves = true;
  options.discontinuities = options.storage_nodes = false;
  const std::size_t drawn = build_overlay(snapshot, options).size();
  const std::size_t bound = overlay_vertex_bound(*scene);
  EXPECT_LE(drawn, bound);
  EXPECT_GE(static_cast<double>(drawn), 0.95 * static_cast<double>(bound));
  EXPECT_GT(render_memory_bound(*scene, 0), static_cast<double>(bound * sizeof(LineVertex)));
}

TEST(Frame, ColourMapBrightensWithRadiosity) {
  double previous = -1.0;
  for (int i = 0; i <= 20; ++i) {
    const auto c = colour_map(i / 20.0);
    const double brightness = 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
    EXPECT_GT(brightness, previous);
    previous = brightness;
  }
  EXPECT_EQ(colour_map(-1.0), colour_map(0.0));
  EXPECT_EQ(colour_map(std::nan("")), colour_map(0.0));
}

TEST(Frame, PickingFindsTheNearestCurveWithinTheRadius) {
  const Scene scene = testing::scene_from_file("scenes2d/penumbra.json");
  const std::vector<CurveTrace> traces = trace_curves(scene);
  const ViewTransform view = fit_view(scene.bounds, 600, 400);
  // Curves: 0 emitter (y = 2), 1 occluder (y = 1), 2 receiver (y = 0).
  EXPECT_EQ(pick_curve(traces, view, view.to_pixels({0.2, 1.0}) + Vec2{0.0, 3.0}), 1u);
  EXPECT_EQ(pick_curve(traces, view, view.to_pixels({-2.0, 0.0})), 2u);
  EXPECT_FALSE(pick_curve(traces, view, view.to_pixels({-2.0, 1.5})).has_value());
}

}  // namespace
}  // namespace flatland::viewer
