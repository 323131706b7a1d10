#include "flatland/scene/discontinuities.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "test_support.hpp"

namespace flatland {
namespace {

std::vector<SegmentGeometry> geometry_of(const Scene& scene) {
  std::vector<SegmentGeometry> geometry;
  for (const SceneSegment& segment : scene.segments) geometry.push_back(segment.geometry);
  return geometry;
}

TEST(Discontinuity, PenumbraEventsSitWhereEmitterAndOccluderEndsLineUp) {
  // Emitter ends (+-0.5, 2), occluder ends (-0.1, 1) and (0.7, 1), floor y = 0 from -3 to 3: the
  // line through E and O meets the floor at x = E.x + 2 (O.x - E.x).
  const Scene scene = testing::scene_from_file("scenes2d/penumbra.json");
  const SegmentAccelerator accelerator(geometry_of(scene));
  const std::vector<DiscontinuityNode> nodes = find_visibility_events(scene, accelerator);
  std::vector<double> floor_x;
  for (const DiscontinuityNode& node : nodes) {
    ASSERT_EQ(scene.curves[node.curve].id, "receiver");
    EXPECT_EQ(node.continuity, Continuity::C0);
    floor_x.push_back(-3.0 + 6.0 * node.u);
  }
  const std::vector<double> expected = {0.5 + 2 * (-0.1 - 0.5), -0.5 + 2 * (-0.1 + 0.5), 0.5 + 2 * (0.7 - 0.5),
                                        -0.5 + 2 * (0.7 + 0.5)};
  ASSERT_EQ(floor_x.size(), 4u);
  std::vector<double> sorted = expected;
  std::sort(sorted.begin(), sorted.end());
  for (std::size_t i = 0; i < 4; ++i) EXPECT_NEAR(floor_x[i], sorted[i], 1e-12);
}

// A lamp (0.3 to 0.8 at height 1, facing down) and a short flat mirror on x = 0 from 0.2 to 0.6:
// the floor (y = 0 from 0.05 to 2) sees the lamp's image (x from -0.8 to -0.3) only through the
// mirror, and the lines from the image's ends through the mirror's ends bound that light where
// they meet the floor: the line from the image end (e, 1) through the mirror end (0, m) meets
// y = 0 at x = -e m / (1 - m).
TEST(Discontinuity, AFlatMirrorsImageMarksTheFloorThroughTheMirrorsEnds) {
  const Scene scene = testing::scene_from_text(R"({"flatland": 2,
      "materials": {"lamp": {"emittance": 1}, "floor": {"reflectivity": 0.5}, "mirror": {"type": "mirror"}},
      "curves": [{"id": "lamp", "material": "lamp", "line": [[0.8, 1], [0.3, 1]]},
                 {"id": "floor", "material": "floor", "line": [[0.05, 0], [2, 0]]},
                 {"id": "mirror", "material": "mirror", "line": [[0, 0.6], [0, 0.2]]}]})");
  const SegmentAccelerator accelerator(geometry_of(scene));
  std::vector<double> floor_x;
  for (const DiscontinuityNode& node : find_visibility_events(scene, accelerator)) {
    ASSERT_EQ(scene.curves[node.curve].id, "floor");
    floor_x.push_back(0.05 + 1.95 * node.u);
  }
  std::vector<double> expected;
  for (double e : {-0.3, -0.8})
    for (double m : {0.2, 0.6}) expected.push_back(-e * m / (1.0 - m));
  std::sort(expected.begin(), expected.end());
  ASSERT_EQ(floor_x.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) EXPECT_NEAR(floor_x[i], expected[i], 1e-12);
  // The mirror's back (its front faces +x: it runs down) does not reflect when only the back is
  // named: no image, no events.
  const Scene back = testing::scene_from_text(R"({"flatland": 2,
      "materials": {"lamp": {"emittance": 1}, "floor": {"reflectivity": 0.5}, "mirror": {"type": "mirror"}},
      "curves": [{"id": "lamp", "material": "lamp", "line": [[0.8, 1], [0.3, 1]]},
                 {"id": "floor", "material": "floor", "line": [[0.05, 0], [2, 0]]},
                 {"id": "mirror", "material": "mirror", "sides": "back", "line": [[0, 0.6], [0, 0.2]]}]})");
  EXPECT_TRUE(find_visibility_events(back, SegmentAccelerator(geometry_of(back))).empty());
}

// Event lines pass through detectors and are reflected by mirrors: the penumbra scene with a
// detector across the light has the same events, and a mirror under the occluder's lines turns
// them up onto a ceiling.
TEST(Discontinuity, EventLinesPassDetectorsAndReflectOffMirrors) {
  const Scene plain = testing::scene_from_file("scenes2d/penumbra.json");
  std::string text = testing::read_text_file(testing::source_path("scenes2d/penumbra.json"));
  const std::string curves = "\"curves\": [";
  const std::string materials = "\"materials\": {";
  text.insert(text.find(materials) + materials.size(), "\"probe\": {\"type\": \"detector\"}, ");
  text.insert(text.find(curves) + curves.size(),
              "{\"id\": \"probe\", \"material\": \"probe\", \"line\": [[-5, 0.5], [5, 0.5]]}, ");
  const Scene with_detector = testing::scene_from_text(text);
  const std::vector<DiscontinuityNode> a = find_visibility_events(plain, SegmentAccelerator(geometry_of(plain)));
  const std::vector<DiscontinuityNode> b =
      find_visibility_events(with_detector, SegmentAccelerator(geometry_of(with_detector)));
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(a[i].u, b[i].u, 1e-12);
  // A mirror below: emitter (+-0.5, 2), occluder ends (-0.1, 1), (0.7, 1), a mirror at y = 0 and a
  // ceiling at y = 3 (facing down, from -20 to 20). A line through E and O meets the mirror at
  // x0 = E.x + 2 (O.x - E.x) and, reflected, the ceiling at x0 + 3 (O.x - E.x).
  const Scene mirrored = testing::scene_from_text(R"({"flatland": 2,
      "materials": {"emitter": {"emittance": 1}, "black": {}, "mirror": {"type": "mirror"},
                    "ceiling": {"reflectivity": 0.5}},
      "curves": [{"id": "emitter", "material": "emitter", "line": [[0.5, 2], [-0.5, 2]]},
                 {"id": "occluder", "material": "black", "sides": "both", "line": [[-0.1, 1], [0.7, 1]]},
                 {"id": "mirror", "material": "mirror", "line": [[-20, 0], [20, 0]]},
                 {"id": "ceiling", "material": "ceiling", "line": [[20, 3], [-20, 3]]}]})");
  std::vector<double> ceiling_x;
  for (const DiscontinuityNode& node : find_visibility_events(mirrored, SegmentAccelerator(geometry_of(mirrored)))) {
    if (mirrored.curves[node.curve].id != "ceiling") continue;
    ceiling_x.push_back(20.0 - 40.0 * node.u);
  }
  std::vector<double> expected;
  for (double e : {-0.5, 0.5})
    for (double o : {-0.1, 0.7}) expected.push_back(e + 5.0 * (o - e));  // two of them 1.5: one node
  // And the lamp's own shadow in the mirrored light: the line from its image (-0.5, -2) straight up
  // past its end (-0.5, 2) (the other image lines through the occluder's ends are blocked by the
  // lamp or the occluder, or are the lines above).
  expected.push_back(-0.5);
  std::sort(expected.begin(), expected.end());
  expected.erase(
      std::unique(expected.begin(), expected.end(), [](double x, double y) { return std::fabs(x - y) < 1e-9; }),
      expected.end());
  std::sort(ceiling_x.begin(), ceiling_x.end());
  ASSERT_EQ(ceiling_x.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) EXPECT_NEAR(ceiling_x[i], expected[i], 1e-9);
}

// The penumbra scene's emitter made a reflector (panel), lit from below by a lamp off to the
// side that emits upward only: with secondary sources the panel's end points past the occluder's
// mark the floor where the emitter's did (x = P.x + 2 (O.x - P.x)); without them nothing marks the
// floor (the lamp's light goes up, and the panel's lines past the lamp's ends pass beyond the floor).
TEST(Discontinuity, ReflectorsAreSecondarySourcesOnRequest) {
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 2,
    "materials": {"lamp": {"emittance": 1}, "black": {}, "grey": {"reflectivity": 0.5}},
    "curves": [
      {"id": "panel", "material": "grey", "line": [[0.5,2],[-0.5,2]]},
      {"id": "lamp", "material": "lamp", "line": [[1.5,1.9],[2.5,1.9]]},
      {"id": "occluder", "material": "black", "line": [[-0.1,1],[0.7,1]]},
      {"id": "floor", "material": "grey", "line": [[-3,0],[3,0]]}]})");
  const SegmentAccelerator accelerator(geometry_of(scene));
  auto floor_events = [&](bool secondary) {
    EventOptions options;
    options.secondary = secondary;
    std::vector<double> x;
    for (const DiscontinuityNode& node : find_visibility_events(scene, accelerator, options)) {
      if (scene.curves[node.curve].id != "floor") continue;
      EXPECT_EQ(node.continuity, Continuity::C0);
      x.push_back(-3.0 + 6.0 * node.u);
    }
    return x;
  };
  EXPECT_TRUE(floor_events(false).empty());
  std::vector<double> expected = {0.5 + 2 * (-0.1 - 0.5), -0.5 + 2 * (-0.1 + 0.5), 0.5 + 2 * (0.7 - 0.5),
                                  -0.5 + 2 * (0.7 + 0.5)};
  std::sort(expected.begin(), expected.end());
  const std::vector<double> found = floor_events(true);
  ASSERT_EQ(found.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) EXPECT_NEAR(found[i], expected[i], 1e-12);
}

TEST(Discontinuity, HiddenVerticesMakeNoEvents) {
  // A wall between the lamp and the occluder's left end hides it from the lamp's right end only.
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 1,
    "materials": {"lamp": {"emittance": 1}, "black": {}, "floor": {"reflectivity": 0.5}},
    "curves": [
      {"id": "lamp", "material": "lamp", "line": [[0.5,2],[-0.5,2]]},
      {"id": "occluder", "material": "black", "line": [[-0.1,1],[0.7,1]]},
      {"id": "wall", "material": "black", "line": [[0.2,1.6],[0.2,1.4]]},
      {"id": "floor", "material": "floor", "line": [[-3,0],[3,0]]}]})");
  const SegmentAccelerator accelerator(geometry_of(scene));
  // The ray from (0.5, 2) to (-0.1, 1) passes x = 0.2 at y = 1.5: blocked.
  for (const DiscontinuityNode& node : find_visibility_events(scene, accelerator)) {
    if (scene.curves[node.curve].id != "floor") continue;
    EXPECT_GT(std::fabs(-3.0 + 6.0 * node.u - (-0.7)), 1e-6) << "event of a hidden vertex";
  }
}

TEST(Discontinuity, ConvexEnclosureHasNoEvents) {
  const Scene scene = testing::scene_from_file("scenes2d/enclosure.json");
  const SegmentAccelerator accelerator(geometry_of(scene));
  EXPECT_TRUE(find_visibility_events(scene, accelerator).empty());
}

// ---------------------------------------------------------------------------------------------
// Independent geometry for the expected answers: long double Bernstein evaluation, tangent points
// by dense sampling of the sign of cross(C(t) - P, C'(t)) and bisection.

using testing::bernstein_point;
using testing::LongVec;

constexpr double kPi = std::numbers::pi;

LongVec bernstein_derivative(const Cubic& c, long double t) {
  const long double s = 1.0L - t;
  const long double w[3] = {s * s, 2.0L * s * t, t * t};
  LongVec r{0.0L, 0.0L};
  for (int i = 0; i < 3; ++i) {
    r.x += 3.0L * w[i] * (static_cast<long double>(c.p[i + 1].x) - c.p[i].x);
    r.y += 3.0L * w[i] * (static_cast<long double>(c.p[i + 1].y) - c.p[i].y);
  }
  return r;
}

long double cross_long(LongVec a, LongVec b) { return a.x * b.y - a.y * b.x; }
LongVec minus(LongVec a, LongVec b) { return {a.x - b.x, a.y - b.y}; }

long double tangent_value(const Cubic& c, LongVec p, long double t) {
  return cross_long(minus(bernstein_point(c, t), p), bernstein_derivative(c, t));
}

// Tangent points of a chain of cubics seen from p, as points.
std::vector<LongVec> brute_tangent_points(const std::vector<Cubic>& chain, LongVec p, int samples = 256) {
  std::vector<LongVec> out;
  for (const Cubic& c : chain) {
    long double previous = tangent_value(c, p, 0.0L);
    for (int k = 1; k <= samples; ++k) {
      const long double t = static_cast<long double>(k) / samples;
      const long double value = tangent_value(c, p, t);
      if ((previous < 0.0L) != (value < 0.0L)) {
        long double lo = static_cast<long double>(k - 1) / samples;
        long double hi = t;
        const bool rising = previous < 0.0L;
        for (int i = 0; i < 80; ++i) {
          const long double middle = 0.5L * (lo + hi);
          if ((tangent_value(c, p, middle) < 0.0L) == rising) {
            lo = middle;
          } else {
            hi = middle;
          }
        }
        out.push_back(bernstein_point(c, 0.5L * (lo + hi)));
      }
      previous = value;
    }
  }
  return out;
}

std::vector<Cubic> chain_of(const Scene& scene, const std::string& id) {
  std::vector<Cubic> chain;
  for (const SceneSegment& segment : scene.segments)
    if (scene.curves[segment.curve].id == id) chain.push_back(segment.geometry.shape);
  return chain;
}

// Where the line from a through b meets y = 0.
double floor_crossing(LongVec a, LongVec b) { return static_cast<double>(a.x + (b.x - a.x) * a.y / (a.y - b.y)); }

// A circle of 8 cubic arcs of 45 degrees (handles (4/3) tan(pi/16) r), from angle 0,
// counter-clockwise (front inward) or clockwise (front outward), as a JSON point list. The last
// point is the first, exactly.
std::string circle_points(double cx, double cy, double r, bool clockwise) {
  const double k = 4.0 / 3.0 * std::tan(kPi / 16.0) * r;
  const double turn = clockwise ? -1.0 : 1.0;
  std::string text;
  auto add = [&](double x, double y) {
    char buffer[96];
    std::snprintf(buffer, sizeof buffer, "%s[%.17g,%.17g]", text.empty() ? "" : ",", x, y);
    text += buffer;
  };
  const double x0 = cx + r;
  const double y0 = cy;
  add(x0, y0);
  for (int i = 0; i < 8; ++i) {
    const double a0 = turn * i * kPi / 4.0;
    const double a1 = turn * (i + 1) * kPi / 4.0;
    const double p0x = i == 0 ? x0 : cx + r * std::cos(a0);
    const double p0y = i == 0 ? y0 : cy + r * std::sin(a0);
    const double p3x = i == 7 ? x0 : cx + r * std::cos(a1);
    const double p3y = i == 7 ? y0 : cy + r * std::sin(a1);
    add(p0x - turn * k * std::sin(a0), p0y + turn * k * std::cos(a0));
    add(p3x + turn * k * std::sin(a1), p3y - turn * k * std::cos(a1));
    add(p3x, p3y);
  }
  return "[" + text + "]";
}

// The x of the C0 nodes on a straight floor from (x0, y) to (x1, y), sorted.
std::vector<double> floor_nodes(const Scene& scene, const std::vector<DiscontinuityNode>& nodes, const std::string& id,
                                double x0, double x1) {
  std::vector<double> xs;
  for (const DiscontinuityNode& node : nodes) {
    if (scene.curves[node.curve].id != id) continue;
    EXPECT_EQ(node.continuity, Continuity::C0);
    xs.push_back(x0 + (x1 - x0) * node.u);
  }
  std::sort(xs.begin(), xs.end());
  return xs;
}

void expect_same_positions(std::vector<double> actual, std::vector<double> expected, double tolerance) {
  std::sort(expected.begin(), expected.end());
  ASSERT_EQ(actual.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) EXPECT_NEAR(actual[i], expected[i], tolerance) << "event " << i;
}

std::vector<std::string> curves_with_nodes(const Scene& scene, const std::vector<DiscontinuityNode>& nodes) {
  std::vector<std::string> ids;
  for (const DiscontinuityNode& node : nodes) ids.push_back(scene.curves[node.curve].id);
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  return ids;
}

TEST(Discontinuity, LinesFromLampEndsTangentToARoundOccluderMarkTheFloor) {
  // A lamp facing down (its front is up, so "back"), a black Bezier circle below it, a floor. Above
  // the lamp a black shade and a reflecting ceiling: lines leaving the lamp's dark top through the
  // shade's ends would mark the ceiling if the back side counted.
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 2,
    "materials": {"lamp": {"emittance": 1}, "black": {}, "grey": {"reflectivity": 0.5}},
    "curves": [
      {"id": "lamp", "material": "lamp", "sides": "back", "line": [[-0.5,2],[0.5,2]]},
      {"id": "ball", "material": "black", "bezier": )" +
                                               circle_points(0.0, 1.0, 0.3, false) + R"(},
      {"id": "shade", "material": "black", "line": [[-0.2,2.5],[0.2,2.5]]},
      {"id": "ceiling", "material": "grey", "line": [[2,3],[-2,3]]},
      {"id": "floor", "material": "grey", "line": [[-2,0],[2,0]]}]})");
  ASSERT_TRUE(scene.curves[1].closed);
  const SegmentAccelerator accelerator(geometry_of(scene));
  const std::vector<DiscontinuityNode> nodes = find_visibility_events(scene, accelerator);
  EXPECT_EQ(curves_with_nodes(scene, nodes), std::vector<std::string>{"floor"});
  std::vector<double> expected;
  for (const LongVec lamp_end : {LongVec{-0.5L, 2.0L}, LongVec{0.5L, 2.0L}}) {
    const std::vector<LongVec> touching = brute_tangent_points(chain_of(scene, "ball"), lamp_end);
    ASSERT_EQ(touching.size(), 2u);
    for (const LongVec& t : touching) expected.push_back(floor_crossing(lamp_end, t));
  }
  expect_same_positions(floor_nodes(scene, nodes, "floor", -2.0, 2.0), expected, 1e-9 * scene.scale);
}

TEST(Discontinuity, SilhouettesOfARoundLampPastAnOccluderEdgeMarkTheFloor) {
  // TV: a clockwise (outward-facing) Bezier circle lamp, a straight black occluder, a floor. The
  // lines from the occluder's ends tangent to the lamp, continued past the ends.
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 2,
    "materials": {"lamp": {"emittance": 1}, "black": {}, "grey": {"reflectivity": 0.5}},
    "curves": [
      {"id": "lamp", "material": "lamp", "bezier": )" +
                                               circle_points(0.0, 2.5, 0.3, true) + R"(},
      {"id": "edge", "material": "black", "line": [[-0.1,1.2],[0.6,1.2]]},
      {"id": "floor", "material": "grey", "line": [[-5,0],[5,0]]}]})");
  const SegmentAccelerator accelerator(geometry_of(scene));
  const std::vector<DiscontinuityNode> nodes = find_visibility_events(scene, accelerator);
  std::vector<double> expected;
  for (const LongVec end : {LongVec{-0.1L, 1.2L}, LongVec{0.6L, 1.2L}}) {
    const std::vector<LongVec> touching = brute_tangent_points(chain_of(scene, "lamp"), end);
    ASSERT_EQ(touching.size(), 2u);
    for (const LongVec& t : touching) expected.push_back(floor_crossing(t, end));
  }
  expect_same_positions(floor_nodes(scene, nodes, "floor", -5.0, 5.0), expected, 1e-9 * scene.scale);

  // The same lamp facing inward (counter-clockwise, front inside) shows no lit silhouette outside.
  const Scene inward = testing::scene_from_text(R"({
    "flatland": 2,
    "materials": {"lamp": {"emittance": 1}, "black": {}, "grey": {"reflectivity": 0.5}},
    "curves": [
      {"id": "lamp", "material": "lamp", "bezier": )" +
                                                circle_points(0.0, 2.5, 0.3, false) + R"(},
      {"id": "edge", "material": "black", "line": [[-0.1,1.2],[0.6,1.2]]},
      {"id": "floor", "material": "grey", "line": [[-5,0],[5,0]]}]})");
  EXPECT_TRUE(find_visibility_events(inward, SegmentAccelerator(geometry_of(inward))).empty());
}

TEST(Discontinuity, BitangentsOfARoundLampAndARoundOccluderMarkTheFloor) {
  // TT: both curves are smooth closed Bezier circles (no vertices anywhere but the floor's ends).
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 2,
    "materials": {"lamp": {"emittance": 1}, "black": {}, "grey": {"reflectivity": 0.5}},
    "curves": [
      {"id": "lamp", "material": "lamp", "bezier": )" +
                                               circle_points(0.0, 2.5, 0.3, true) + R"(},
      {"id": "ball", "material": "black", "bezier": )" +
                                               circle_points(0.3, 1.2, 0.2, false) + R"(},
      {"id": "floor", "material": "grey", "line": [[-6,0],[6,0]]}]})");
  const std::vector<Cubic> lamp = chain_of(scene, "lamp");
  const std::vector<Cubic> ball = chain_of(scene, "ball");
  // Brute force: for P on the lamp, the ball's two tangent points seen from P (left and right of
  // the ball's centre); a bitangent where the lamp's tangent at P passes through one of them.
  const LongVec centre{0.3L, 1.2L};
  auto branch = [&](const Cubic& c, long double t, int side, LongVec* touching) {
    const LongVec p = bernstein_point(c, t);
    for (const LongVec& q : brute_tangent_points(ball, p, 64)) {
      if ((cross_long(minus(q, p), minus(centre, p)) > 0.0L) != (side > 0)) continue;
      *touching = q;
      const LongVec d = bernstein_derivative(c, t);
      const LongVec e = minus(q, p);
      return cross_long(e, d) / std::sqrt((e.x * e.x + e.y * e.y) * (d.x * d.x + d.y * d.y));
    }
    ADD_FAILURE() << "no tangent point";
    return 0.0L;
  };
  std::vector<double> expected;
  for (const Cubic& c : lamp) {
    for (const int side : {1, -1}) {
      constexpr int kSteps = 48;
      LongVec q{};
      long double previous = branch(c, 0.0L, side, &q);
      for (int k = 1; k <= kSteps; ++k) {
        const long double t = static_cast<long double>(k) / kSteps;
        const long double value = branch(c, t, side, &q);
        if ((previous < 0.0L) != (value < 0.0L)) {
          long double lo = static_cast<long double>(k - 1) / kSteps;
          long double hi = t;
          const bool rising = previous < 0.0L;
          for (int i = 0; i < 64; ++i) {
            const long double middle = 0.5L * (lo + hi);
            if ((branch(c, middle, side, &q) < 0.0L) == rising) {
              lo = middle;
            } else {
              hi = middle;
            }
          }
          branch(c, 0.5L * (lo + hi), side, &q);
          expected.push_back(floor_crossing(bernstein_point(c, 0.5L * (lo + hi)), q));
        }
        previous = value;
      }
    }
  }
  ASSERT_EQ(expected.size(), 4u);  // two outer and two inner common tangents
  EXPECT_EQ(bitangents(scene, 0, 1).size(), 4u);
  EXPECT_TRUE(bitangents(scene, 0, 0).empty());  // a convex curve has none with itself
  const std::vector<DiscontinuityNode> nodes = find_visibility_events(scene, SegmentAccelerator(geometry_of(scene)));
  expect_same_positions(floor_nodes(scene, nodes, "floor", -6.0, 6.0), expected, 1e-9 * scene.scale);
}

TEST(Discontinuity, NearlyStraightCubicHasNoTangentPoints) {
  // The penumbra scene with the occluder drawn as a cubic whose inner control points are 1e-13 of
  // its length off the line: its events are those of the straight occluder.
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 2,
    "materials": {"lamp": {"emittance": 1}, "black": {}, "grey": {"reflectivity": 0.5}},
    "curves": [
      {"id": "lamp", "material": "lamp", "line": [[0.5,2],[-0.5,2]]},
      {"id": "occluder", "material": "black",
       "bezier": [[-0.1,1],[0.16666666666666667,1.00000000000008],[0.43333333333333335,0.99999999999992],[0.7,1]]},
      {"id": "floor", "material": "grey", "line": [[-3,0],[3,0]]}]})");
  for (const Vec2 p : {Vec2{-1.0, 1.0}, Vec2{2.0, 1.0}, Vec2{0.3, 0.0}, Vec2{0.5, 2.0}})
    EXPECT_TRUE(tangent_points(scene, 1, p).empty()) << p.x << ", " << p.y;
  const std::vector<DiscontinuityNode> nodes = find_visibility_events(scene, SegmentAccelerator(geometry_of(scene)));
  EXPECT_EQ(curves_with_nodes(scene, nodes), std::vector<std::string>{"floor"});
  expect_same_positions(floor_nodes(scene, nodes, "floor", -3.0, 3.0), {-0.7, 0.3, 0.9, 1.9}, 1e-12);
}

TEST(Discontinuity, TangentPointAtAJointIsFoundOnce) {
  // The upper half of a circle of radius 0.3 in two quarter arcs, joined at the top (0, 0.3).
  const double k = 4.0 / 3.0 * (std::sqrt(2.0) - 1.0) * 0.3;
  char text[512];
  std::snprintf(text, sizeof text, R"({
    "flatland": 2, "materials": {"m": {"reflectivity": 0.5}, "lamp": {"emittance": 1}},
    "curves": [
      {"id": "lamp", "material": "lamp", "line": [[20,20],[21,20]]},{"id": "dome", "material": "m",
      "bezier": [[0.3,0],[0.3,%.17g],[%.17g,0.3],[0,0.3],[%.17g,0.3],[-0.3,%.17g],[-0.3,0]]}]})",
                k, k, -k, k);
  const Scene scene = testing::scene_from_text(text);
  // From either side at the height of the top, the horizontal tangent touches the joint (the other
  // tangent touches the missing lower half).
  for (const double x : {-2.0, 2.0}) {
    const std::vector<double> u = tangent_points(scene, 1, Vec2{x, 0.3});
    ASSERT_EQ(u.size(), 1u) << x;
    EXPECT_NEAR(u[0], 1.0, 1e-9);
  }
  // A point on the tangent at the dome's end (0.3, 0): that end is a vertex, not a tangent point.
  EXPECT_TRUE(tangent_points(scene, 1, Vec2{0.3, -2.0}).empty());
  // From above, two tangent points on the two quarters, symmetric.
  const std::vector<double> u = tangent_points(scene, 1, Vec2{0.0, 1.0});
  ASSERT_EQ(u.size(), 2u);
  EXPECT_NEAR(u[0] + u[1], 2.0, 1e-12);
}

TEST(Discontinuity, MergingJoinsCloseEvents) {
  // Penumbra events at x = -0.7, 0.3, 0.9, 1.9 on a floor 6 long: with 4 elements and a merge
  // fraction of 0.5 (0.75 in arc length), 0.3 and 0.9 become one node at their mean.
  const Scene scene = testing::scene_from_file("scenes2d/penumbra.json");
  const SegmentAccelerator accelerator(geometry_of(scene));
  const std::vector<DiscontinuityNode> nodes = find_visibility_events(scene, accelerator, EventOptions{4, 0.5});
  expect_same_positions(floor_nodes(scene, nodes, "receiver", -3.0, 3.0), {-0.7, 0.6, 1.9}, 1e-12);
}

// ---------------------------------------------------------------------------------------------
// Contacts.

std::vector<double> contact_parameters(const Scene& scene, const std::vector<DiscontinuityNode>& nodes,
                                       const std::string& id) {
  std::vector<double> u;
  for (const DiscontinuityNode& node : nodes) {
    if (scene.curves[node.curve].id != id) continue;
    EXPECT_EQ(node.continuity, Continuity::Jump);
    u.push_back(node.u);
  }
  return u;
}

TEST(Discontinuity, ArchStandingOnAFloorCutsTheFloor) {
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 2, "materials": {"m": {"reflectivity": 0.5}, "lamp": {"emittance": 1}},
    "curves": [
      {"id": "lamp", "material": "lamp", "line": [[20,20],[21,20]]},
      {"id": "arch", "material": "m", "bezier": [[-1,0],[-1,1.5],[1,1.5],[1,0]]},
      {"id": "floor", "material": "m", "line": [[-3,0],[3,0]]}]})");
  const std::vector<DiscontinuityNode> nodes = find_contacts(scene);
  expect_same_positions(contact_parameters(scene, nodes, "floor"), {2.0 / 6.0, 4.0 / 6.0}, 1e-12);
  EXPECT_TRUE(contact_parameters(scene, nodes, "arch").empty());
}

TEST(Discontinuity, CrossingsCutBothCurves) {
  // Two crossing lines; a line crossing the arch twice; a line through two joints of a circle (at
  // its closing point and at joint 4).
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 2, "materials": {"m": {"reflectivity": 0.5}, "lamp": {"emittance": 1}},
    "curves": [
      {"id": "lamp", "material": "lamp", "line": [[20,20],[21,20]]},
      {"id": "a", "material": "m", "line": [[-1,-1],[1,1]]},
      {"id": "b", "material": "m", "line": [[-1,1],[1,-1]]},
      {"id": "arch", "material": "m", "bezier": [[2,0],[2,1.5],[4,1.5],[4,0]]},
      {"id": "bar", "material": "m", "line": [[1.5,0.5],[4.5,0.5]]},
      {"id": "ball", "material": "m", "bezier": )" +
                                               circle_points(0.0, 3.0, 0.3, false) + R"(},
      {"id": "rod", "material": "m", "line": [[-1,3],[1,3]]}]})");
  const std::vector<DiscontinuityNode> nodes = find_contacts(scene);
  expect_same_positions(contact_parameters(scene, nodes, "a"), {0.5}, 1e-12);
  expect_same_positions(contact_parameters(scene, nodes, "b"), {0.5}, 1e-12);
  // The arch's height is y(t) = 4.5 t (1 - t): 0.5 at t = (1 -+ sqrt(5)/3) / 2.
  const double t0 = (1.0 - std::sqrt(5.0) / 3.0) / 2.0;
  const double t1 = (1.0 + std::sqrt(5.0) / 3.0) / 2.0;
  expect_same_positions(contact_parameters(scene, nodes, "arch"), {t0, t1}, 1e-12);
  auto arch_x = [](double t) {
    const double s = 1.0 - t;
    return 2.0 * s * s * s + 3.0 * 2.0 * s * s * t + 3.0 * 4.0 * s * t * t + 4.0 * t * t * t;
  };
  expect_same_positions(contact_parameters(scene, nodes, "bar"), {(arch_x(t0) - 1.5) / 3.0, (arch_x(t1) - 1.5) / 3.0},
                        1e-12);
  expect_same_positions(contact_parameters(scene, nodes, "ball"), {0.0, 4.0}, 1e-12);
  expect_same_positions(contact_parameters(scene, nodes, "rod"), {0.35, 0.65}, 1e-12);
}

TEST(Discontinuity, TJunctionsCutTheReceivingCurveOnly) {
  // A post standing on a beam; an L whose corner touches a wall; a closed square whose closing
  // corner rests on a floor; a circle whose smooth closing point touches a line tangentially.
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 2, "materials": {"m": {"reflectivity": 0.5}, "lamp": {"emittance": 1}},
    "curves": [
      {"id": "lamp", "material": "lamp", "line": [[20,20],[21,20]]},
      {"id": "beam", "material": "m", "line": [[-1,0],[1,0]]},
      {"id": "post", "material": "m", "line": [[0,0],[0,1]]},
      {"id": "wall", "material": "m", "line": [[3,-1],[3,2]]},
      {"id": "ell", "material": "m", "line": [[4,1],[3,0.5],[4,0]]},
      {"id": "floor", "material": "m", "line": [[5,0],[9,0]]},
      {"id": "square", "material": "m", "line": [[7,0],[8,1],[7,2],[6,1],[7,0]]},
      {"id": "ball", "material": "m", "bezier": )" +
                                               circle_points(0.0, 5.0, 0.3, false) + R"(},
      {"id": "tangent", "material": "m", "line": [[0.3,4],[0.3,6]]}]})");
  const std::vector<DiscontinuityNode> nodes = find_contacts(scene);
  expect_same_positions(contact_parameters(scene, nodes, "beam"), {0.5}, 1e-12);
  EXPECT_TRUE(contact_parameters(scene, nodes, "post").empty());
  expect_same_positions(contact_parameters(scene, nodes, "wall"), {0.5}, 1e-12);
  EXPECT_TRUE(contact_parameters(scene, nodes, "ell").empty());
  expect_same_positions(contact_parameters(scene, nodes, "floor"), {0.5}, 1e-12);
  EXPECT_TRUE(contact_parameters(scene, nodes, "square").empty());
  EXPECT_TRUE(contact_parameters(scene, nodes, "ball").empty());
  EXPECT_TRUE(contact_parameters(scene, nodes, "tangent").empty());
}

TEST(Discontinuity, CurveTouchingItselfIsCut) {
  // A polyline whose end comes back onto its first segment, and a closed curve with no contacts.
  const Scene scene = testing::scene_from_text(R"({
    "flatland": 2, "materials": {"m": {"reflectivity": 0.5}, "lamp": {"emittance": 1}},
    "curves": [
      {"id": "lamp", "material": "lamp", "line": [[20,20],[21,20]]},
      {"id": "hook", "material": "m", "line": [[0,0],[4,0],[4,2],[1,2],[1,0]]},
      {"id": "ring", "material": "m", "bezier": )" +
                                               circle_points(0.0, 5.0, 0.3, false) + R"(}]})");
  const std::vector<DiscontinuityNode> nodes = find_contacts(scene);
  expect_same_positions(contact_parameters(scene, nodes, "hook"), {0.25}, 1e-12);
  EXPECT_TRUE(contact_parameters(scene, nodes, "ring").empty());
}

}  // namespace
}  // namespace flatland
