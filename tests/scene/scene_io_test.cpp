// Scene files and derived scene data: every default, every error path (with its location in the
// text), the example scenes, and a fuzz run that must never crash or throw.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "flatland/scene/scene.hpp"

namespace flatland {
namespace {

using Json = nlohmann::ordered_json;

const std::string kSourceDir = FLATLAND_SOURCE_DIR;

// A valid grey scene: a lamp above a floor.
constexpr const char* kMinimal = R"({
  "flatland": 1,
  "materials": {"lamp": {"emittance": 1}, "wall": {"reflectivity": 0.5}},
  "curves": [
    {"id": "lamp", "material": "lamp", "line": [[1, 1], [0, 1]]},
    {"id": "floor", "material": "wall", "line": [[0, 0], [1, 0]]}
  ]
})";

Result<Scene> parse(std::string_view text) { return parse_scene(text, "test.json"); }

// The minimal scene after an edit of its JSON value.
std::string edited(const std::function<void(Json&)>& edit) {
  Json j = Json::parse(kMinimal);
  edit(j);
  return j.dump();
}

// The error message of a text that must fail, checked for the one-line "test.json..." shape.
std::string error_of(std::string_view text) {
  const Result<Scene> r = parse(text);
  if (r.ok()) {
    ADD_FAILURE() << "expected an error for: " << text;
    return "";
  }
  const std::string& message = r.error().message;
  EXPECT_EQ(message.rfind("test.json", 0), 0u) << message;
  EXPECT_EQ(message.find('\n'), std::string::npos) << message;
  return message;
}

#define EXPECT_CONTAINS(haystack, needle)                                     \
  do {                                                                        \
    const std::string haystack_ = (haystack);                                 \
    EXPECT_NE(haystack_.find(needle), std::string::npos)                      \
        << "message: " << haystack_ << "\nexpected to contain: " << (needle); \
  } while (false)

// Lengths by brute force: the sum of many chords converges to the arc length as O(h^2).
double chord_length(const Cubic& c, int chords) {
  double total = 0.0;
  Vec2 previous = evaluate(c, 0.0);
  for (int k = 1; k <= chords; ++k) {
    const Vec2 next = evaluate(c, k / double(chords));
    total += length(next - previous);
    previous = next;
  }
  return total;
}

// ------------------------------------------------------------------------------------------------
// Defaults

TEST(SceneIo, MinimalSceneAndDefaults) {
  const Result<Scene> r = parse_scene(kMinimal, "some/dir/my_room.json");
  ASSERT_TRUE(r.ok()) << r.error().message;
  const Scene& s = *r;
  EXPECT_EQ(s.name, "my_room");  // file stem when "name" is absent
  EXPECT_EQ(s.source, "some/dir/my_room.json");
  EXPECT_EQ(s.description, "");
  EXPECT_EQ(s.channels, 1);
  ASSERT_EQ(s.materials.size(), 2u);
  EXPECT_EQ(s.materials[0].name, "lamp");  // file order
  EXPECT_EQ(s.materials[1].name, "wall");
  // Defaults: reflectivity 0 and emittance 0, broadcast to all three channels.
  EXPECT_EQ(s.materials[0].reflectivity, (Spectrum{0, 0, 0}));
  EXPECT_EQ(s.materials[0].emittance, (Spectrum{1, 1, 1}));
  EXPECT_EQ(s.materials[1].reflectivity, (Spectrum{0.5, 0.5, 0.5}));
  EXPECT_EQ(s.materials[1].emittance, (Spectrum{0, 0, 0}));
  ASSERT_EQ(s.curves.size(), 2u);
  EXPECT_EQ(s.curves[0].id, "lamp");
  EXPECT_EQ(s.curves[0].material, 0u);
  EXPECT_EQ(s.curves[1].material, 1u);
  EXPECT_EQ(s.curves[0].sides, Sides::Front);
  EXPECT_EQ(s.curves[0].kind, SegmentKind::Line);
  EXPECT_EQ(s.curves[0].emittance, (Spectrum{1, 1, 1}));  // the material's
  EXPECT_EQ(s.curves[1].emittance, (Spectrum{0, 0, 0}));
  EXPECT_TRUE(s.curves[0].joints.empty());
  EXPECT_FALSE(s.has_cubics());
}

TEST(SceneIo, NameAndDescription) {
  const Result<Scene> r = parse(edited([](Json& j) {
    j["name"] = "Lamp over floor";
    j["description"] = "two lines";
  }));
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->name, "Lamp over floor");
  EXPECT_EQ(r->description, "two lines");
  // No file stem at all: a generic name.
  const Result<Scene> unnamed = parse_scene(kMinimal, "");
  ASSERT_TRUE(unnamed.ok());
  EXPECT_EQ(unnamed->name, "scene");
}

TEST(SceneIo, ColourWhenAnyValueIsAnArray) {
  // One [r,g,b] anywhere (here a curve override) makes the scene colour; greys are broadcast.
  const Result<Scene> r = parse(edited([](Json& j) { j["curves"][1]["emittance"] = {0.0, 0.25, 0.0}; }));
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->channels, 3);
  EXPECT_EQ(r->materials[1].reflectivity, (Spectrum{0.5, 0.5, 0.5}));
  EXPECT_EQ(r->curves[1].emittance, (Spectrum{0.0, 0.25, 0.0}));
  const Result<Scene> reflect = parse(edited([](Json& j) {
    j["materials"]["wall"]["reflectivity"] = {0.1, 0.2, 0.3};
  }));
  ASSERT_TRUE(reflect.ok());
  EXPECT_EQ(reflect->channels, 3);
  EXPECT_EQ(reflect->materials[1].reflectivity, (Spectrum{0.1, 0.2, 0.3}));
  EXPECT_EQ(reflect->materials[0].emittance, (Spectrum{1, 1, 1}));
}

TEST(SceneIo, CurveEmittanceOverridesTheMaterial) {
  const Result<Scene> r = parse(edited([](Json& j) { j["curves"][0]["emittance"] = 3.5; }));
  ASSERT_TRUE(r.ok());
  EXPECT_EQ(r->curves[0].emittance, (Spectrum{3.5, 3.5, 3.5}));
  EXPECT_EQ(r->materials[0].emittance, (Spectrum{1, 1, 1}));
}

TEST(SceneIo, Sides) {
  for (const auto& [text, sides] : std::vector<std::pair<std::string, Sides>>{
           {"front", Sides::Front}, {"back", Sides::Back}, {"both", Sides::Both}}) {
    const Result<Scene> r = parse(edited([&](Json& j) { j["curves"][1]["sides"] = text; }));
    ASSERT_TRUE(r.ok());
    EXPECT_EQ(r->curves[1].sides, sides);
  }
  Curve c;
  c.sides = Sides::Back;
  EXPECT_FALSE(c.has_side(Side::Front));
  EXPECT_TRUE(c.has_side(Side::Back));
}

TEST(SceneIo, DefaultJointsFollowTangentContinuity) {
  // A polyline: collinear vertices join with C1, corners (right and acute) with a jump. (A
  // reversal would fold the line back over itself, an overlap the reader refuses.)
  const Result<Scene> r =
      parse(edited([](Json& j) { j["curves"][1]["line"] = Json::parse("[[0,0],[1,0],[2,0],[2,1],[1.5,0.5]]"); }));
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->curves[1].joints, (std::vector<Continuity>{Continuity::C1, Continuity::Jump, Continuity::Jump}));
  // A Bezier chain: the joint is C1 where the handles are collinear, a jump at a corner.
  const Result<Scene> b = parse(edited([](Json& j) {
    j["curves"][1].erase("line");
    j["curves"][1]["bezier"] = Json::parse("[[0,0],[1,0],[2,1],[3,1], [4,1],[5,0],[6,0], [6,1],[7,1],[8,1]]");
  }));
  ASSERT_TRUE(b.ok()) << b.error().message;
  EXPECT_EQ(b->curves[1].joints, (std::vector<Continuity>{Continuity::C1, Continuity::Jump}));
  // Tangent continuity is tested on directions, so unequal handle lengths still give C1, and a
  // coincident handle (P2 == P3) uses the limiting tangent from inside the segment.
  const Result<Scene> h = parse(edited([](Json& j) {
    j["curves"][1].erase("line");
    j["curves"][1]["bezier"] = Json::parse("[[0,0],[1,1],[2,0],[2,0], [2,0],[3,-1],[4,-1]]");
  }));
  ASSERT_TRUE(h.ok()) << h.error().message;
  EXPECT_EQ(h->curves[1].joints, (std::vector<Continuity>{Continuity::C1}));
}

TEST(SceneIo, ExplicitJoints) {
  const Result<Scene> all = parse(edited([](Json& j) {
    j["curves"][1]["line"] = Json::parse("[[0,0],[1,0],[2,0]]");
    j["curves"][1]["joints"] = "C-1";
  }));
  ASSERT_TRUE(all.ok());
  EXPECT_EQ(all->curves[1].joints, (std::vector<Continuity>{Continuity::Jump}));
  const Result<Scene> each = parse(edited([](Json& j) {
    j["curves"][1]["line"] = Json::parse("[[0,0],[1,0],[1,0.5],[0,0.5]]");
    j["curves"][1]["joints"] = {"C0", "C1"};
  }));
  ASSERT_TRUE(each.ok());
  EXPECT_EQ(each->curves[1].joints, (std::vector<Continuity>{Continuity::C0, Continuity::C1}));
  // A one-segment curve has no joints: a string applies to none, an empty array is exact.
  EXPECT_TRUE(parse(edited([](Json& j) { j["curves"][1]["joints"] = "C0"; })).ok());
  EXPECT_TRUE(parse(edited([](Json& j) { j["curves"][1]["joints"] = Json::array(); })).ok());
}

// ------------------------------------------------------------------------------------------------
// Derived data (finalize_scene), checked against independent answers

TEST(Scene, PolylineSegmentsLengthsAndBounds) {
  const Result<Scene> r = parse(edited([](Json& j) { j["curves"][1]["line"] = Json::parse("[[0,0],[3,0],[3,4]]"); }));
  ASSERT_TRUE(r.ok());
  const Scene& s = *r;
  ASSERT_EQ(s.segments.size(), 3u);
  const Curve& c = s.curves[1];
  EXPECT_EQ(c.first_segment, 1u);
  EXPECT_EQ(c.segment_count, 2u);
  EXPECT_DOUBLE_EQ(c.length, 7.0);
  ASSERT_EQ(c.segment_start.size(), 3u);
  EXPECT_DOUBLE_EQ(c.segment_start[0], 0.0);
  EXPECT_DOUBLE_EQ(c.segment_start[1], 3.0);
  EXPECT_DOUBLE_EQ(c.segment_start[2], 7.0);
  const SceneSegment& second = s.segments[2];
  EXPECT_EQ(second.curve, 1u);
  EXPECT_EQ(second.index_in_curve, 1u);
  EXPECT_EQ(second.geometry.kind, SegmentKind::Line);
  EXPECT_EQ(second.geometry.shape.p[0], (Vec2{3, 0}));
  EXPECT_EQ(second.geometry.shape.p[3], (Vec2{3, 4}));
  EXPECT_DOUBLE_EQ(second.length, 4.0);
  EXPECT_NEAR(second.arc_length.total(), 4.0, 1e-12);
  EXPECT_GE(second.speed_bound, 4.0 * (1 - 1e-15));  // |C'| of a constant-speed line is its length
  EXPECT_DOUBLE_EQ(s.segments[0].length, 1.0);
  // Bounds: union of the segments' boxes, from (0,0) to (3,4); scale = diagonal = 5.
  EXPECT_EQ(s.bounds.lower, (Vec2{0, 0}));
  EXPECT_EQ(s.bounds.upper, (Vec2{3, 4}));
  EXPECT_DOUBLE_EQ(s.scale, 5.0);
}

TEST(Scene, BezierLengthsMatchChordSums) {
  // A quarter of the unit circle (the usual 4-point approximation) followed by a straight piece
  // whose control points are unevenly spaced (length 2 regardless of the spacing).
  const double k = 0.5522847498307936;
  const Result<Scene> r = parse(edited([&](Json& j) {
    j["curves"][1].erase("line");
    j["curves"][1]["bezier"] = {{1, 0}, {1, k}, {k, 1}, {0, 1}, {-0.1, 1}, {-1.9, 1}, {-2, 1}};
  }));
  ASSERT_TRUE(r.ok()) << r.error().message;
  const Scene& s = *r;
  EXPECT_TRUE(s.has_cubics());
  const Curve& c = s.curves[1];
  ASSERT_EQ(c.segment_count, 2u);
  const SceneSegment& arc = s.segments[c.first_segment];
  const SceneSegment& straight = s.segments[c.first_segment + 1];
  EXPECT_EQ(arc.geometry.kind, SegmentKind::Cubic);
  EXPECT_NEAR(arc.length, chord_length(arc.geometry.shape, 20000), 1e-8);
  EXPECT_NEAR(arc.length, std::numbers::pi / 2, 1e-3);  // the approximation is within 3e-4
  EXPECT_NEAR(straight.length, 2.0, 1e-12);
  EXPECT_NEAR(c.length, arc.length + 2.0, 1e-12);
  EXPECT_NEAR(c.segment_start[1], arc.length, 1e-15);
  EXPECT_EQ(c.joints, (std::vector<Continuity>{Continuity::C1}));
  // speed_bound bounds |C'| (sampled densely).
  for (const SceneSegment* seg : {&arc, &straight}) {
    double fastest = 0.0;
    for (int i = 0; i <= 1000; ++i) fastest = std::max(fastest, length(derivative(seg->geometry.shape, i / 1000.0)));
    EXPECT_GE(seg->speed_bound, fastest);
    EXPECT_LE(seg->speed_bound, 1.1 * fastest);
  }
  // Bounds include the control points' boxes.
  EXPECT_LE(s.bounds.lower.x, -2.0);
  EXPECT_GE(s.bounds.upper.x, 1.0);
}

TEST(Scene, EmittedPowerCountsLengthSidesAndChannels) {
  // Grey: lamp of length 2 with E = 1.5 emitting from both sides: 2 * 2 * 1.5 = 6.
  const Result<Scene> grey = parse(edited([](Json& j) {
    j["curves"][0]["line"] = Json::parse("[[2,1],[0,1]]");
    j["curves"][0]["emittance"] = 1.5;
    j["curves"][0]["sides"] = "both";
  }));
  ASSERT_TRUE(grey.ok());
  EXPECT_TRUE(grey->is_emitter(grey->curves[0]));
  EXPECT_FALSE(grey->is_emitter(grey->curves[1]));
  EXPECT_DOUBLE_EQ(grey->emitted_power(), 6.0);
  // Colour: E = [1, 2, 3] on a unit line, one side: 1 + 2 + 3 = 6.
  const Result<Scene> colour = parse(edited([](Json& j) { j["materials"]["lamp"]["emittance"] = {1, 2, 3}; }));
  ASSERT_TRUE(colour.ok());
  EXPECT_EQ(colour->channels, 3);
  EXPECT_DOUBLE_EQ(colour->emitted_power(), 6.0);
  // A grey scene counts channel 0 only, though all three hold the value.
  const Result<Scene> one = parse(kMinimal);
  ASSERT_TRUE(one.ok());
  EXPECT_DOUBLE_EQ(one->emitted_power(), 1.0);
  // An emitter is a curve with positive emittance in a used channel.
  Scene s = *colour;
  s.curves[0].emittance = {0.0, 0.0, 0.5};
  EXPECT_TRUE(s.is_emitter(s.curves[0]));
  s.channels = 1;
  EXPECT_FALSE(s.is_emitter(s.curves[0]));
}

TEST(Scene, FinalizeAHandBuiltScene) {
  Scene s;
  Material m;
  m.name = "m";
  m.reflectivity = {0.5, 0.5, 0.5};
  m.emittance = {1, 1, 1};
  s.materials.push_back(m);
  Curve c;
  c.id = "c";
  c.kind = SegmentKind::Cubic;
  c.points = {{0, 0}, {1, 0}, {2, 0}, {3, 0}, {3, 1}, {3, 2}, {3, 3}};
  s.curves.push_back(c);
  ASSERT_TRUE(finalize_scene(s).ok());
  EXPECT_EQ(s.curves[0].joints, (std::vector<Continuity>{Continuity::Jump}));  // filled in
  EXPECT_DOUBLE_EQ(s.curves[0].length, 6.0);
  // Finalizing twice gives the same segments (the viewer re-finalizes after edits).
  ASSERT_TRUE(finalize_scene(s).ok());
  EXPECT_EQ(s.segments.size(), 2u);
  // Wrong joint count, bad material index, malformed chain: errors that name the field.
  Scene bad = s;
  bad.curves[0].joints = {Continuity::C0, Continuity::C0};
  EXPECT_CONTAINS(finalize_scene(bad).error().message, "curves[0].joints: expected 1 entries");
  bad = s;
  bad.curves[0].material = 7;
  EXPECT_CONTAINS(finalize_scene(bad).error().message, "curves[0].material:");
  bad = s;
  bad.curves[0].points.pop_back();
  EXPECT_CONTAINS(finalize_scene(bad).error().message, "curves[0].bezier: expected 3k+1 points");
  bad = s;
  bad.curves[0].points[1] = {NAN, 0};
  EXPECT_CONTAINS(finalize_scene(bad).error().message, "curves[0].bezier[1]: coordinates must be finite");
  bad = s;
  bad.curves.clear();
  EXPECT_FALSE(finalize_scene(bad).ok());
  // Coordinates far from double's limits only.
  bad = s;
  bad.curves[0].points[6] = {1.7e308, 0};
  EXPECT_CONTAINS(finalize_scene(bad).error().message,
                  "curves[0].bezier[6]: coordinate too large: (1.7e+308, 0); coordinates must lie within +-1e100");
  bad = s;
  for (Vec2& p : bad.curves[0].points) p = 1e-102 * p;
  EXPECT_CONTAINS(finalize_scene(bad).error().message, "curves: the scene is only 4.24264e-102 across");
  bad = s;
  for (Vec2& p : bad.curves[0].points) p = 1e99 * p;  // large but valid
  EXPECT_TRUE(finalize_scene(bad).ok());
  EXPECT_NEAR(bad.curves[0].length, 6e99, 1e87);
}

// ------------------------------------------------------------------------------------------------
// Errors: syntax and structure

TEST(SceneIoErrors, SyntaxErrorHasLineAndColumn) {
  // The stray comma makes the closing brace on line 3, column 1 unexpected.
  EXPECT_CONTAINS(error_of("{\n  \"flatland\": 1,\n}"), "test.json:3:1: parse error: ");
  EXPECT_CONTAINS(error_of(""), "test.json:1:1: parse error: ");
  EXPECT_CONTAINS(error_of("{\"flatland\": 1} x"), "test.json:1:17: parse error: ");
  // Columns count characters, not bytes (the e-acute is two bytes in UTF-8).
  EXPECT_CONTAINS(error_of("{\"\xC3\xA9\": 1 ,,}"), "test.json:1:10: parse error: ");
  // Nothing of the library's internal prefix leaks into the message.
  EXPECT_EQ(error_of("[").find("json.exception"), std::string::npos);
}

TEST(SceneIoErrors, RootMustBeAnObject) {
  EXPECT_CONTAINS(error_of("[1, 2]"), "test.json:1:1: a scene file must be a JSON object");
  EXPECT_CONTAINS(error_of("42"), "got a number");
}

TEST(SceneIoErrors, Version) {
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j.erase("flatland"); })),
                  "missing \"flatland\": 2, the format version; this program reads versions 1 and 2");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["flatland"] = 3; })),
                  "flatland: unsupported format version 3; this program reads versions 1 and 2");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["flatland"] = 1.5; })), "unsupported format version 1.5");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["flatland"] = "1"; })),
                  "flatland: expected the format version as a number (1), got a string");
  // A newer file reports its version before complaining about keys it does not know.
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["flatland"] = 3;
                    j["lights"] = Json::array();
                  })),
                  "unsupported format version 3");
  EXPECT_TRUE(parse(edited([](Json& j) { j["flatland"] = 2; })).ok());
  // 1.0 is the number 1.
  EXPECT_TRUE(parse(edited([](Json& j) { j["flatland"] = 1.0; })).ok());
}

TEST(SceneIoErrors, UnknownKeysGetAHint) {
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["curves"][0]["matrial"] = "lamp";
                    j["curves"][0].erase("material");
                  })),
                  "curves[0]: unknown key \"matrial\"; did you mean \"material\"?");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curve"] = Json::array(); })),
                  "unknown key \"curve\"; did you mean \"curves\"?");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["materials"]["wall"]["reflectivty"] = 0.2; })),
                  "materials.wall: unknown key \"reflectivty\"; did you mean \"reflectivity\"?");
  // Nothing close: list what is accepted.
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["materials"]["wall"]["zzzzzzzz"] = 0.2; })),
                  "unknown key \"zzzzzzzz\"; the keys here are \"type\", \"reflectivity\", \"emittance\"");
}

TEST(SceneIoErrors, DuplicateKeys) {
  EXPECT_CONTAINS(error_of("{\"flatland\": 1,\n \"flatland\": 1}"),
                  "test.json:2:2: duplicate key \"flatland\" (first at line 1, column 2)");
  const std::string nested = R"({"flatland": 1, "materials": {"lamp": {"emittance": 1, "emittance": 2}},
    "curves": [{"id": "a", "material": "lamp", "line": [[0,0],[1,0]]}]})";
  EXPECT_CONTAINS(error_of(nested), "test.json:1:56: materials.lamp: duplicate key \"emittance\"");
  // Duplicate material names are duplicate keys too.
  const std::string names = R"({"flatland": 1, "materials": {"lamp": {"emittance": 1}, "lamp": {}},
    "curves": [{"id": "a", "material": "lamp", "line": [[0,0],[1,0]]}]})";
  EXPECT_CONTAINS(error_of(names), "materials: duplicate key \"lamp\"");
}

TEST(SceneIoErrors, WrongTypes) {
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["name"] = 3; })),
                  "name: expected the scene's name (a string), got a number");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["description"] = Json::array(); })),
                  "description: expected a description (a string), got an array");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["materials"] = Json::array(); })),
                  "materials: expected an object of named materials");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["materials"]["wall"] = 0.5; })),
                  "materials.wall: expected a material object");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["materials"]["wall"]["reflectivity"] = "0.5"; })),
                  "materials.wall.reflectivity: expected a number (grey) or [r, g, b] (colour), got a string");
  EXPECT_CONTAINS(
      error_of(edited([](Json& j) {
        j["materials"]["wall"]["reflectivity"] = {0.5, 0.5};
      })),
      "materials.wall.reflectivity: expected a number (grey) or [r, g, b] (colour), got an array of 2 elements");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["wall"]["reflectivity"] = {0.5, nullptr, 0.5};
                  })),
                  "materials.wall.reflectivity[1]: expected a number, got null");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"] = Json::object(); })),
                  "curves: expected an array of curves, got an object");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1] = "floor"; })), "curves[1]: expected a curve object");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1]["id"] = 7; })),
                  "curves[1].id: expected an id (a string), got a number");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1]["material"] = true; })),
                  "curves[1].material: expected a material name (a string), got a boolean");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1]["line"] = 1; })),
                  "curves[1].line: expected an array of points [[x, y], ...], got a number");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1]["line"][1] = "x"; })),
                  "curves[1].line[1]: expected a point [x, y], got a string");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["curves"][1]["line"][1] = {1, 2, 3};
                  })),
                  "curves[1].line[1]: expected a point [x, y], got an array of 3 elements");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["curves"][1]["line"][1] = {1, "2"};
                  })),
                  "curves[1].line[1][1]: expected a number, got a string");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1]["sides"] = 2; })),
                  "curves[1].sides: expected \"front\", \"back\" or \"both\" (a string), got a number");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1]["joints"] = 1; })),
                  "curves[1].joints: expected \"C1\", \"C0\" or \"C-1\" for every joint");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1]["emittance"] = Json::object(); })),
                  "curves[1].emittance: expected a number (grey) or [r, g, b] (colour), got an object");
}

TEST(SceneIoErrors, MissingFields) {
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j.erase("materials"); })), "missing \"materials\"");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j.erase("curves"); })), "missing \"curves\"");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1].erase("id"); })),
                  "curves[1]: missing \"id\"; give the curve a unique \"id\"");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1].erase("material"); })),
                  "curves[1]: missing \"material\"");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1].erase("line"); })),
                  "curves[1]: missing geometry; give \"line\"");
  EXPECT_CONTAINS(
      error_of(edited([](Json& j) { j["curves"][1]["bezier"] = Json::parse("[[0,0],[1,0],[2,0],[3,0]]"); })),
      "curves[1]: has both \"line\" and \"bezier\"; give exactly one");
}

TEST(SceneIoErrors, EmptyCollectionsAndNames) {
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"] = Json::array(); })),
                  "curves: the scene has no curves; add at least one");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["materials"] = Json::object(); })),
                  "materials: no materials defined");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["materials"][""] = Json::object(); })),
                  "materials[\"\"]: a material name must not be empty");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1]["id"] = ""; })),
                  "curves[1].id: the id must not be empty");
}

TEST(SceneIoErrors, DuplicateIdsNameBothCurves) {
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1]["id"] = "lamp"; })),
                  "curves[1].id: duplicate id \"lamp\" (curves[0] and curves[1]); give each curve its own id");
}

TEST(SceneIoErrors, UnknownMaterialSuggestsTheClosest) {
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1]["material"] = "wal"; })),
                  "curves[1].material: unknown material \"wal\"; did you mean \"wall\"? (defined: \"lamp\", \"wall\")");
  // Transpositions count as one edit.
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1]["material"] = "lmap"; })), "did you mean \"lamp\"?");
  const std::string far = error_of(edited([](Json& j) { j["curves"][1]["material"] = "concrete"; }));
  EXPECT_EQ(far.find("did you mean"), std::string::npos) << far;
  EXPECT_CONTAINS(far, "unknown material \"concrete\" (defined: \"lamp\", \"wall\")");
}

TEST(SceneIoErrors, ReflectivityAndEmittanceRanges) {
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["materials"]["wall"]["reflectivity"] = 1; })),
                  "materials.wall.reflectivity: must be below 1: a surface that reflects everything "
                  "never converges (got 1); use at most 0.99");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["wall"]["reflectivity"] = {0.5, 1.25, 0.5};
                  })),
                  "materials.wall.reflectivity[1]: must be below 1");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["materials"]["wall"]["reflectivity"] = -0.1; })),
                  "materials.wall.reflectivity: must be in [0, 1), got -0.1");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["materials"]["lamp"]["emittance"] = -1; })),
                  "materials.lamp.emittance: must be >= 0 (power per unit length), got -1");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["curves"][0]["emittance"] = {1, -2, 1};
                  })),
                  "curves[0].emittance[1]: must be >= 0");
  // Just below 1 is accepted.
  EXPECT_TRUE(parse(edited([](Json& j) { j["materials"]["wall"]["reflectivity"] = 0.999999; })).ok());
}

TEST(SceneIo, SpecularMaterialsAndTheirDefaults) {
  const Result<Scene> r = parse(edited([](Json& j) {
    j["materials"]["mirror"] = {{"type", "mirror"}};
    j["materials"]["tinted"] = {{"type", "mirror"}, {"reflectance", {0.9, 0.5, 0.2}}};
    j["materials"]["glass"] = {{"type", "dielectric"}, {"ior", 1.5}};
    j["materials"]["flint"] = {
        {"type", "dielectric"}, {"ior", {{"cauchy", {1.6, 0.01}}}}, {"ior_back", 1.33}, {"absorption", 0.5}};
    j["materials"]["probe"] = {{"type", "detector"}, {"bins", 16}};
    j["materials"]["plain"] = {{"type", "diffuse"}, {"reflectivity", 0.3}};
    j["curves"][1]["material"] = "glass";
  }));
  ASSERT_TRUE(r.ok()) << r.error().message;
  const Scene& s = *r;
  auto material = [&](const std::string& name) -> const Material& {
    for (const Material& m : s.materials)
      if (m.name == name) return m;
    ADD_FAILURE() << name;
    return s.materials[0];
  };
  EXPECT_EQ(material("lamp").optics, Optics::Diffuse);
  EXPECT_EQ(material("plain").optics, Optics::Diffuse);
  EXPECT_EQ(material("mirror").optics, Optics::Mirror);
  EXPECT_EQ(material("mirror").reflectance, (Spectrum{1.0, 1.0, 1.0}));
  EXPECT_EQ(material("tinted").reflectance, (Spectrum{0.9, 0.5, 0.2}));
  EXPECT_EQ(s.channels, 3);  // an [r, g, b] reflectance makes the scene colour
  EXPECT_EQ(material("glass").optics, Optics::Dielectric);
  EXPECT_DOUBLE_EQ(material("glass").ior.at(0.5), 1.5);
  EXPECT_DOUBLE_EQ(material("glass").ior_back, 1.0);
  EXPECT_DOUBLE_EQ(material("flint").ior.at(0.5), 1.6 + 0.01 / 0.25);
  EXPECT_DOUBLE_EQ(material("flint").ior_back, 1.33);
  EXPECT_EQ(material("flint").absorption, (Spectrum{0.5, 0.5, 0.5}));
  EXPECT_EQ(material("probe").optics, Optics::Detector);
  EXPECT_EQ(material("probe").detector_bins, 16u);
  EXPECT_TRUE(s.has_specular());
  // A specular curve holds no diffuse light on either side.
  EXPECT_FALSE(s.stores(s.curves[1], Side::Front));
  EXPECT_TRUE(s.stores(s.curves[0], Side::Front));
  EXPECT_FALSE(s.holds_light(s.curves[1]));
  EXPECT_TRUE(s.holds_light(s.curves[0]));
}

TEST(SceneIoErrors, SpecularMaterials) {
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["materials"]["wall"]["type"] = "mirorr"; })),
                  "materials.wall.type: unknown material type \"mirorr\"; did you mean \"mirror\"? (accepted: "
                  "\"diffuse\", \"mirror\", \"dielectric\", \"detector\")");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["wall"] = {{"type", "mirror"}, {"emittance", 1}};
                  })),
                  "materials.wall.emittance: a mirror does not emit; give the lamp a diffuse material of its own");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["wall"] = {{"type", "mirror"}, {"reflectivity", 0.5}};
                  })),
                  "materials.wall.reflectivity: a mirror reflects specularly: give its fraction as \"reflectance\"");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["wall"] = {{"type", "mirror"}, {"reflectance", 1.5}};
                  })),
                  "materials.wall.reflectance: must be in [0, 1] (the fraction reflected), got 1.5");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["wall"] = {{"type", "dielectric"}};
                  })),
                  "materials.wall: missing \"ior\"");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["wall"] = {{"type", "dielectric"}, {"ior", 0.5}};
                  })),
                  "materials.wall.ior: a refractive index must be in [1, 10] (1 is vacuum, 1.5 glass), got 0.5");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["wall"] = {{"type", "dielectric"}, {"ior", {{"cauchy", {1.0, -0.2}}}}};
                  })),
                  "materials.wall.ior.cauchy: gives n = ");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["wall"] = {{"type", "dielectric"}, {"ior", {{"cauchy", {1.5}}}}};
                  })),
                  "materials.wall.ior.cauchy: expected [A, B]");
  // Both ends of a range get the message that names the range.
  for (double absorption : {-1.0, 1e101})
    EXPECT_CONTAINS(error_of(edited([absorption](Json& j) {
                      j["materials"]["wall"] = {{"type", "dielectric"}, {"ior", 1.5}, {"absorption", absorption}};
                    })),
                    "materials.wall.absorption: must be between 0 and 1e100 (attenuation per unit length inside)");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["wall"] = {{"type", "mirror"}, {"roughness", 1.5}};
                  })),
                  "materials.wall.roughness: must be in [0, 1] (the microfacets' slope spread; 0 is smooth), got 1.5");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["wall"] = {{"type", "detector"}, {"roughness", 0.1}};
                  })),
                  "unknown key \"roughness\"");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["wall"] = {{"type", "detector"}, {"bins", 2.5}};
                  })),
                  "materials.wall.bins: expected a whole number of bins from 1 to 4096, got 2.5");
  EXPECT_CONTAINS(
      error_of(edited([](Json& j) {
        j["materials"]["probe"] = {{"type", "detector"}, {"bins", 4096}};
        for (int k = 0; k < 17; ++k)
          j["curves"].push_back(
              {{"id", "probe" + std::to_string(k)}, {"material", "probe"}, {"line", {{0, k + 2}, {1, k + 2}}}});
      })),
      "curves: the detector curves have 69632 bins in all; at most 65536");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["wall"] = {{"type", "mirror"}};
                    j["curves"][1]["emittance"] = 1;
                  })),
                  "curves[1].emittance: material \"wall\" is not diffuse and does not emit");
}

TEST(SceneIoErrors, Spectra) {
  for (double power : {-1.0, 1e308})
    EXPECT_CONTAINS(error_of(edited([power](Json& j) {
                      j["materials"]["lamp"]["spectrum"] = Json::array({{500, 1}, {600, power}});
                    })),
                    "materials.lamp.spectrum[1][1]: relative power must be between 0 and 1e100");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["lamp"]["spectrum"] = {{"blackbody", 100}};
                  })),
                  "materials.lamp.spectrum.blackbody: a temperature from 500 to 100000 kelvin, got 100");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["lamp"]["spectrum"] = {{"line", 900}};
                  })),
                  "materials.lamp.spectrum.line: a visible wavelength from 380 to 780 nanometres, got 900");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["lamp"]["spectrum"] = Json::array({{500, 1}, {450, 1}});
                  })),
                  "materials.lamp.spectrum[1][0]: wavelengths must increase along the table, got 450 after 500");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["lamp"]["spectrum"] = Json::array({{800, 1}, {900, 1}});
                  })),
                  "materials.lamp.spectrum: the spectrum has no power between 380 and 780 nm");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["lamp"]["spectrum"] = {{"laser", 532}};
                  })),
                  "materials.lamp.spectrum: unknown key \"laser\"");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["wall"]["spectrum"] = {{"line", 532}};
                  })),
                  "materials.wall.spectrum: a spectrum shapes emitted light: give the material an \"emittance\" > 0");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["lamp"]["emittance"] = {1, 1, 1};
                    j["materials"]["lamp"]["spectrum"] = {{"line", 532}};
                  })),
                  "materials.lamp.emittance: with a \"spectrum\" the emittance is one number");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["lamp"]["spectrum"] = {{"line", 532}};
                    j["curves"][0]["emittance"] = {1, 2, 3};
                  })),
                  "curves[0].emittance: material \"lamp\" has a spectrum: the curve's emittance is one number");
  // A table in the visible range is accepted and makes the scene colour.
  const Result<Scene> r = parse(edited([](Json& j) {
    j["materials"]["lamp"]["spectrum"] = Json::array({{400, 0}, {600, 2}, {700, 1}});
  }));
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->channels, 3);
  EXPECT_TRUE(r->has_spectra());
}

TEST(SceneIoErrors, NumbersThatOverflowAreRejectedWithTheirPlace) {
  const std::string text = R"({"flatland": 1, "materials": {"lamp": {"emittance": 1}},
  "curves": [{"id": "a", "material": "lamp", "line": [[0, 0], [1e999, 0]]}]})";
  EXPECT_CONTAINS(error_of(text),
                  "test.json:2:64: curves[0].line[1][0]: the number 1e999 is too large "
                  "for a double (it overflows to infinity); use a finite value");
  EXPECT_CONTAINS(error_of(R"({"flatland": 1, "materials": {"lamp": {"emittance": -12.5e400}}})"),
                  "materials.lamp.emittance: the number -12.5e400 is too large");
  // Underflow is harmless: it reads as 0.
  const std::string tiny = R"({"flatland": 1, "materials": {"lamp": {"emittance": 1}},
  "curves": [{"id": "a", "material": "lamp", "line": [[1e-999, 0], [1, 0]]}]})";
  EXPECT_TRUE(parse(tiny).ok());
}

TEST(SceneIoErrors, Lines) {
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1]["line"] = Json::parse("[[0,0]]"); })),
                  "curves[1].line: a line needs at least 2 points, got 1");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1]["line"] = Json::parse("[[0,0],[1,0],[1,0]]"); })),
                  "curves[1].line[2]: coincides with the previous point (line[1]), which would make a "
                  "zero-length segment; remove one of them");
  // Nearly coincident (closer than 1e-12 of the scene's size) is caught by finalize_scene.
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1]["line"] = Json::parse("[[0,0],[1,0],[1,1e-14]]"); })),
                  "curves[1].line[2]: coincides with the previous point, so segment 1 has zero length");
}

TEST(SceneIoErrors, Beziers) {
  auto with_bezier = [](const char* points) {
    return edited([&](Json& j) {
      j["curves"][1].erase("line");
      j["curves"][1]["bezier"] = Json::parse(points);
    });
  };
  EXPECT_CONTAINS(error_of(with_bezier("[[0,0],[1,0],[2,0],[3,0],[4,0]]")),
                  "curves[1].bezier: expected 3k+1 points, got 5");
  EXPECT_CONTAINS(error_of(with_bezier("[[0,0]]")), "curves[1].bezier: expected 3k+1 points, got 1");
  EXPECT_CONTAINS(error_of(with_bezier("[]")), "curves[1].bezier: expected 3k+1 points, got 0");
  EXPECT_CONTAINS(error_of(with_bezier("[[2,2],[2,2],[2,2],[2,2]]")),
                  "curves[1].bezier: all points coincide, so the curve has zero length");
  EXPECT_CONTAINS(error_of(with_bezier("[[0,0],[1,0],[2,0],[3,0],[3,0],[3,0],[3,0]]")),
                  "curves[1].bezier[3]: segment 1 (control points 3 to 6) has zero length");
  // P0=(0,0), P1=(1,1), P2=(0,1), P3=(1,0): C'(1/2) = 3 (d0/4 + d1/2 + d2/4) = 0, a cusp.
  EXPECT_CONTAINS(error_of(with_bezier("[[0,0],[1,1],[0,1],[1,0]]")),
                  "curves[1].bezier[0]: segment 0 has a cusp at t = 0.5, point (0.5, 0.75), where the "
                  "normal flips; split the curve at t = 0.5");
  // The same cusp in the second segment of a chain is located at that segment's first point.
  EXPECT_CONTAINS(error_of(with_bezier("[[-3,0],[-2,0],[-1,0],[0,0],[1,1],[0,1],[1,0]]")),
                  "curves[1].bezier[3]: segment 1 has a cusp at t = 0.5");
  // Coincident end handles (C'(0) = 0) are not a cusp: the curve is smooth there.
  EXPECT_TRUE(parse(with_bezier("[[0,0],[0,0],[1,1],[2,0]]")).ok());
  // A closed loop in one segment (P0 == P3) is fine.
  EXPECT_TRUE(parse(with_bezier("[[0,0],[1,1],[-1,1],[0,0]]")).ok());
}

TEST(SceneIoErrors, JointsAndSides) {
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["curves"][1]["line"] = Json::parse("[[0,0],[1,0],[2,0]]");
                    j["curves"][1]["joints"] = {"C1", "C0"};
                  })),
                  "curves[1].joints: expected 1 entry (one per joint between the 2 segments), got 2");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1]["joints"] = {"C1"}; })),
                  "curves[1].joints: expected 0 entries (one per joint between the 1 segment), got 1");
  EXPECT_CONTAINS(
      error_of(edited([](Json& j) {
        j["curves"][1]["line"] = Json::parse("[[0,0],[1,0],[2,0]]");
        j["curves"][1]["joints"] = {"c1"};
      })),
      "curves[1].joints[0]: unknown continuity \"c1\"; did you mean \"C1\"? (accepted: \"C1\", \"C0\", \"C-1\")");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["curves"][1]["line"] = Json::parse("[[0,0],[1,0],[2,0]]");
                    j["curves"][1]["joints"] = {3};
                  })),
                  "curves[1].joints[0]: expected \"C1\", \"C0\" or \"C-1\" (a string), got a number");
  EXPECT_CONTAINS(
      error_of(edited([](Json& j) { j["curves"][1]["sides"] = "fornt"; })),
      "curves[1].sides: unknown value \"fornt\"; did you mean \"front\"? (accepted: \"front\", \"back\", \"both\")");
}

TEST(SceneIoErrors, NoEmitter) {
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["materials"]["lamp"]["emittance"] = 0; })),
                  "curves: no curve emits light, so nothing would be lit");
  // An emitting material that no curve uses does not count.
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][0]["material"] = "wall"; })), "nothing would be lit");
  // A per-curve override can make an emitter out of a non-emitting material.
  EXPECT_TRUE(parse(edited([](Json& j) {
                j["materials"]["lamp"]["emittance"] = 0;
                j["curves"][1]["emittance"] = 0.5;
              })).ok());
}

TEST(SceneIoErrors, ValidationErrorsPointAtTheValue) {
  const std::string text =
      "{\n"
      "  \"flatland\": 1,\n"
      "  \"materials\": {\"lamp\": {\"emittance\": 1}},\n"
      "  \"curves\": [\n"
      "    {\"id\": \"a\", \"material\": \"lamp\", \"line\": [[0, 0], [1, 0]]},\n"
      "    {\"id\": \"b\", \"material\": \"lamp\",\n"
      "     \"bezier\": [[0, 0], [1, 0], [2, 0], [3, 0], [4, 0]]},\n"
      "    {\"id\": \"c\", \"matrial\": \"lamp\", \"line\": [[0, 0], [1, 0]]}\n"
      "  ]\n"
      "}\n";
  EXPECT_CONTAINS(error_of(text), "test.json:7:16: curves[1].bezier: expected 3k+1 points, got 5");
  std::string typo = text;
  typo.replace(typo.find("[[0, 0], [1, 0], [2, 0], [3, 0], [4, 0]]"), 40, "[[0, 0], [1, 0], [2, 0], [3, 0]]");
  // Unknown keys point at the key itself.
  EXPECT_CONTAINS(error_of(typo), "test.json:8:17: curves[2]: unknown key \"matrial\"");
  // A missing field points at the object that lacks it.
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][1].erase("id"); })), "test.json:1:");
}

TEST(SceneIoErrors, KeysThatNeedQuotingInPaths) {
  const std::string text = R"({"flatland": 1, "materials": {"my lamp": {"emittance": -1}}, "curves": []})";
  EXPECT_CONTAINS(error_of(text), "test.json:1:56: materials[\"my lamp\"].emittance: must be >= 0");
  // Escapes in keys are decoded by the position scanner the same way as by the parser.
  const std::string escaped = R"({"flatland": 1, "materials": {"l\u00e4mp\n": {"emittance": -1}}, "curves": []})";
  EXPECT_CONTAINS(error_of(escaped), "test.json:1:60: materials[\"l\xC3\xA4mp\\n\"].emittance: must be >= 0");
}

TEST(SceneIoErrors, DeepNestingIsRejectedWithoutCrashing) {
  const std::string deep = "{\"flatland\": 1, \"x\": " + std::string(100000, '[') + std::string(100000, ']') + "}";
  EXPECT_CONTAINS(error_of(deep), "nested more than 64 deep");
}

// ------------------------------------------------------------------------------------------------
// Files

TEST(SceneIoFiles, MissingFileAndDirectory) {
  const Result<Scene> missing = load_scene("/nonexistent/dir/scene.json");
  ASSERT_FALSE(missing.ok());
  EXPECT_EQ(missing.error().message,
            "/nonexistent/dir/scene.json: cannot read the scene file: No such file or directory");
  const Result<Scene> directory = load_scene(kSourceDir + "/scenes2d");
  ASSERT_FALSE(directory.ok());
  EXPECT_CONTAINS(directory.error().message, "scenes2d: is a directory, not a scene file");
}

TEST(SceneIoFiles, ErrorsFromAFileNameThePath) {
  const std::string path = kSourceDir + "/scenes2d/tests/typo_key.json";
  const Result<Scene> r = load_scene(path);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.error().message, path + ":6:41: curves[1]: unknown key \"emitance\"; did you mean \"emittance\"?");
}

TEST(SceneIoFiles, EveryExampleSceneLoads) {
  int count = 0;
  // Every scene file, the generated ones of scenes2d/experiments too; scenes2d/tests holds
  // deliberately broken fixtures.
  for (const auto& entry : std::filesystem::recursive_directory_iterator(kSourceDir + "/scenes2d")) {
    if (entry.path().extension() != ".json" || entry.path().parent_path().filename() == "tests") continue;
    const Result<Scene> r = load_scene(entry.path().string());
    EXPECT_TRUE(r.ok()) << r.error().message;
    ++count;
  }
  EXPECT_GE(count, 14);
  // The examples of docs/scene-format.md explain themselves and keep to the documented size.
  for (const char* name : {"default", "room_reflector", "penumbra", "enclosure", "mixed", "curved_room", "syndrome"}) {
    const Result<Scene> r = load_scene(kSourceDir + "/scenes2d/" + name + ".json");
    ASSERT_TRUE(r.ok()) << r.error().message;
    EXPECT_FALSE(r->description.empty()) << name;
    EXPECT_GT(r->emitted_power(), 0.0) << name;
    EXPECT_GT(r->scale, 1.0) << name;
    EXPECT_LT(r->scale, 20.0) << name;
  }
}

TEST(SceneIoFiles, TheDocumentedExampleParses) {
  // The first ```json block of docs/scene-format.md.
  std::string doc;
  {
    std::FILE* f = std::fopen((kSourceDir + "/docs/scene-format.md").c_str(), "rb");
    ASSERT_NE(f, nullptr);
    char buffer[4096];
    std::size_t got = 0;
    while ((got = std::fread(buffer, 1, sizeof buffer, f)) > 0) doc.append(buffer, got);
    std::fclose(f);
  }
  const std::size_t start = doc.find("```json\n");
  ASSERT_NE(start, std::string::npos);
  const std::size_t end = doc.find("```", start + 8);
  ASSERT_NE(end, std::string::npos);
  const Result<Scene> r = parse_scene(doc.substr(start + 8, end - start - 8), "docs/scene-format.md");
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->curves.size(), 3u);
}

TEST(SceneIoFiles, ExampleScenesHaveTheirDocumentedProperties) {
  const Result<Scene> room = load_scene(kSourceDir + "/scenes2d/default.json");
  ASSERT_TRUE(room.ok()) << room.error().message;
  EXPECT_EQ(room->channels, 3);
  EXPECT_TRUE(room->has_cubics());

  // Enclosure: one closed counter-clockwise curve of four tangent-continuous cubics, uniform
  // E = 1 and rho = 0.5; its length is within 0.1% of the ellipse's (a = 2, b = 1) perimeter.
  const Result<Scene> enclosure = load_scene(kSourceDir + "/scenes2d/enclosure.json");
  ASSERT_TRUE(enclosure.ok()) << enclosure.error().message;
  ASSERT_EQ(enclosure->curves.size(), 1u);
  const Curve& ellipse = enclosure->curves[0];
  EXPECT_EQ(ellipse.segment_count, 4u);
  EXPECT_EQ(ellipse.points.front(), ellipse.points.back());
  // Closed and smooth all round: four joints, the last at the closing point (format version 2).
  EXPECT_TRUE(ellipse.closed);
  EXPECT_EQ(ellipse.joints, std::vector<Continuity>(4, Continuity::C1));
  EXPECT_TRUE(ellipse.periodic());
  EXPECT_NEAR(ellipse.length, 9.688448220547675, 0.01);
  EXPECT_EQ(enclosure->material_of(ellipse).reflectivity[0], 0.5);
  EXPECT_EQ(ellipse.emittance[0], 1.0);
  // Counter-clockwise: the signed area (shoelace over a fine polygon) is positive, so the front
  // (left of travel) faces inward.
  double area = 0.0;
  for (std::uint32_t k = 0; k < ellipse.segment_count; ++k) {
    const Cubic& c = enclosure->segments[ellipse.first_segment + k].geometry.shape;
    for (int i = 0; i < 100; ++i) area += 0.5 * cross(evaluate(c, i / 100.0), evaluate(c, (i + 1) / 100.0));
  }
  EXPECT_NEAR(area, 2.0 * std::numbers::pi, 0.01);

  // Penumbra: three straight lines, a black emitter of length 1 facing down onto the receiver.
  const Result<Scene> penumbra = load_scene(kSourceDir + "/scenes2d/penumbra.json");
  ASSERT_TRUE(penumbra.ok()) << penumbra.error().message;
  EXPECT_FALSE(penumbra->has_cubics());
  EXPECT_DOUBLE_EQ(penumbra->emitted_power(), 1.0);
  const SceneSegment& emitter = penumbra->segments[penumbra->curves[0].first_segment];
  EXPECT_EQ(unit_normal(emitter.geometry.shape, 0.5, penumbra->scale), (Vec2{0, -1}));
  const SceneSegment& receiver = penumbra->segments[penumbra->curves[2].first_segment];
  EXPECT_EQ(unit_normal(receiver.geometry.shape, 0.5, penumbra->scale), (Vec2{0, 1}));

  // Mixed: lines and cubics, a two-sided curve, explicit and default joints, an override.
  const Result<Scene> mixed = load_scene(kSourceDir + "/scenes2d/mixed.json");
  ASSERT_TRUE(mixed.ok()) << mixed.error().message;
  bool two_sided = false;
  bool line = false;
  bool cubic = false;
  for (const Curve& c : mixed->curves) {
    two_sided = two_sided || c.sides == Sides::Both;
    line = line || c.kind == SegmentKind::Line;
    cubic = cubic || c.kind == SegmentKind::Cubic;
  }
  EXPECT_TRUE(two_sided && line && cubic);
}

// ------------------------------------------------------------------------------------------------
// Fuzzing: mutated text and mutated values never crash, never throw, and fail with one-line
// messages that name the source.

void expect_well_formed(const std::string& text) {
  Result<Scene> r = parse_scene(text, "fuzz.json");
  if (!r.ok()) {
    const std::string& m = r.error().message;
    ASSERT_EQ(m.rfind("fuzz.json", 0), 0u) << m;
    ASSERT_EQ(m.find('\n'), std::string::npos) << m;
  } else {
    ASSERT_FALSE(r->segments.empty());
    ASSERT_GT(r->emitted_power(), 0.0);
  }
}

TEST(SceneIoFuzz, MutatedTextNeverCrashes) {
  std::string base;
  {
    std::FILE* f = std::fopen((kSourceDir + "/scenes2d/mixed.json").c_str(), "rb");
    ASSERT_NE(f, nullptr);
    char buffer[4096];
    std::size_t got = 0;
    while ((got = std::fread(buffer, 1, sizeof buffer, f)) > 0) base.append(buffer, got);
    std::fclose(f);
  }
  std::mt19937_64 rng(20240611);
  const std::string alphabet = "{}[],:\"0123456789.eE-+ \n\\uabcfnrt\x01\xff\xc3";
  auto pick = [&](std::size_t n) { return std::uniform_int_distribution<std::size_t>(0, n - 1)(rng); };
  for (int trial = 0; trial < 3000; ++trial) {
    std::string text = base;
    const std::size_t edits = 1 + pick(4);
    for (std::size_t e = 0; e < edits && !text.empty(); ++e) {
      const std::size_t at = pick(text.size());
      switch (pick(5)) {
        case 0: text[at] = alphabet[pick(alphabet.size())]; break;
        case 1: text.erase(at, 1 + pick(8)); break;
        case 2: text.insert(at, 1, alphabet[pick(alphabet.size())]); break;
        case 3: text.resize(at); break;
        default: {  // duplicate a slice elsewhere
          const std::size_t from = pick(text.size());
          const std::string slice = text.substr(from, 1 + pick(40));
          text.insert(at, slice);
        }
      }
    }
    expect_well_formed(text);
    if (HasFatalFailure()) return;
  }
}

TEST(SceneIoFuzz, MutatedValuesNeverCrash) {
  const Json base = Json::parse(R"({"flatland": 1, "materials": {"lamp": {"emittance": 1},
    "wall": {"reflectivity": [0.5, 0.2, 0.1]}},
    "curves": [{"id": "a", "material": "lamp", "line": [[0, 1], [1, 1], [1, 2]]},
               {"id": "b", "material": "wall", "bezier": [[0, 0], [1, 0], [2, 1], [3, 1], [4, 1], [5, 0], [6, 0]],
                "joints": ["C0"], "sides": "both"}]})");
  // Every value and every container reachable in the base, by JSON pointer.
  std::vector<Json::json_pointer> pointers;
  std::vector<std::pair<Json::json_pointer, const Json*>> todo{{Json::json_pointer(), &base}};
  while (!todo.empty()) {
    auto [pointer, value] = todo.back();
    todo.pop_back();
    pointers.push_back(pointer);
    if (value->is_object()) {
      for (const auto& item : value->items()) todo.push_back({pointer / item.key(), &item.value()});
    } else if (value->is_array()) {
      for (std::size_t k = 0; k < value->size(); ++k) todo.push_back({pointer / k, &(*value)[k]});
    }
  }
  const std::vector<Json> replacements = {nullptr,
                                          true,
                                          0,
                                          -1,
                                          1,
                                          0.5,
                                          1e308,
                                          -1e308,
                                          1e-320,
                                          "",
                                          "C1",
                                          "both",
                                          "lamp",
                                          "x",
                                          Json::array(),
                                          Json::object(),
                                          Json::parse("[0, 0]"),
                                          Json::parse("[[0, 0], [0, 0]]"),
                                          Json::parse("[1, 2, 3]"),
                                          Json::parse("[[0,0],[1,1],[0,1],[1,0]]"),
                                          Json::parse("{\"a\": 1}")};
  std::mt19937_64 rng(7);
  auto pick = [&](std::size_t n) { return std::uniform_int_distribution<std::size_t>(0, n - 1)(rng); };
  for (int trial = 0; trial < 3000; ++trial) {
    Json j = base;
    for (std::size_t e = 0, edits = 1 + pick(3); e < edits; ++e) {
      const auto& pointer = pointers[pick(pointers.size())];
      if (!j.contains(pointer)) continue;
      if (pick(4) == 0 && !pointer.empty()) {
        Json& parent = j[pointer.parent_pointer()];
        if (parent.is_object())
          parent.erase(pointer.back());
        else if (parent.is_array() && !parent.empty())
          parent.erase(parent.size() - 1);
      } else {
        j[pointer] = replacements[pick(replacements.size())];
      }
    }
    expect_well_formed(j.dump());
    if (HasFatalFailure()) return;
  }
}

}  // namespace
}  // namespace flatland

namespace flatland {
namespace {

TEST(SceneIo, EmissionForms) {
  const Result<Scene> plain = parse(kMinimal);
  ASSERT_TRUE(plain.ok());
  EXPECT_EQ(plain->materials[0].emission.kind, Emission::Kind::Diffuse);
  const Result<Scene> lobe = parse(edited([](Json& j) { j["materials"]["lamp"]["emission"] = {{"lobe", 8}}; }));
  ASSERT_TRUE(lobe.ok()) << lobe.error().message;
  EXPECT_EQ(lobe->materials[0].emission.kind, Emission::Kind::Lobe);
  EXPECT_EQ(lobe->materials[0].emission.exponent, 8.0);
  const Result<Scene> beam = parse(edited([](Json& j) { j["materials"]["lamp"]["emission"] = {{"beam", 45}}; }));
  ASSERT_TRUE(beam.ok()) << beam.error().message;
  EXPECT_EQ(beam->materials[0].emission.kind, Emission::Kind::Beam);
  EXPECT_NEAR(beam->materials[0].emission.half_angle, 0.7853981633974483, 1e-15);
  const Result<Scene> diffuse = parse(edited([](Json& j) { j["materials"]["lamp"]["emission"] = "diffuse"; }));
  ASSERT_TRUE(diffuse.ok());
  EXPECT_EQ(diffuse->materials[0].emission.kind, Emission::Kind::Diffuse);
}

TEST(SceneIoErrors, EmissionForms) {
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["materials"]["lamp"]["emission"] = "laser"; })),
                  "materials.lamp.emission: unknown emission");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["lamp"]["emission"] = {{"beam", 0}};
                  })),
                  "materials.lamp.emission.beam: the half-angle must be in (0, 90] degrees");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["lamp"]["emission"] = {{"beam", 120}};
                  })),
                  "materials.lamp.emission.beam");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["lamp"]["emission"] = {{"lobe", -1}};
                  })),
                  "materials.lamp.emission.lobe: the exponent must be in [0, 1000]");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["lamp"]["emission"] = {{"lobe", 2}, {"beam", 3}};
                  })),
                  "materials.lamp.emission: expected one emission form");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["materials"]["lamp"]["emission"] = {{"lobes", 2}};
                  })),
                  "did you mean \"lobe\"?");
}

}  // namespace
}  // namespace flatland

namespace flatland {
namespace {

TEST(SceneIo, EmittanceProfile) {
  const Result<Scene> scene = parse(edited([](Json& j) { j["curves"][0]["emittance_profile"] = {1, 3}; }));
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  // A line from (1,1) to (0,1) with factors 1 and 3: mean 2, maximum 3.
  EXPECT_NEAR(scene->curves[0].profile_mean, 2.0, 1e-14);
  EXPECT_EQ(scene->curves[0].profile_max, 3.0);
  EXPECT_NEAR(emittance_factor(scene->curves[0], 0.25), 1.5, 1e-15);
  EXPECT_NEAR(scene->emitted_power(), 2.0, 1e-14);  // emittance 1 x length 1 x mean 2
}

TEST(SceneIoErrors, EmittanceProfile) {
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["curves"][0]["emittance_profile"] = {1, 2, 3};
                  })),
                  "curves[0].emittance_profile: expected 2 factors (one per point), got 3");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["curves"][0]["emittance_profile"] = {1, -2};
                  })),
                  "curves[0].emittance_profile[1]: must be between 0 and 1e100");
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["curves"][0]["emittance_profile"] = {0, 0};
                  })),
                  "every factor is zero");
  EXPECT_CONTAINS(error_of(edited([](Json& j) { j["curves"][0]["emittance_profile"] = 2; })),
                  "expected an array of factors");
}

// Emitted power E x length must stay inside a double with room for the books: emittance is 0 or
// within 1e-100 .. 1e100 (both ends accepted), and profile factors at most 1e100.
TEST(SceneIoErrors, EmittanceOutsideItsRange) {
  for (const double accepted : {1e-100, 1e100}) {
    const Result<Scene> scene = parse(edited([&](Json& j) { j["materials"]["lamp"]["emittance"] = accepted; }));
    EXPECT_TRUE(scene.ok()) << accepted << ": " << scene.error().message;
  }
  for (const double refused : {1e308, 1.1e100, 1e-300, 9e-101}) {
    EXPECT_CONTAINS(error_of(edited([&](Json& j) { j["materials"]["lamp"]["emittance"] = refused; })),
                    "materials.lamp.emittance: must be 0 or between 1e-100 and 1e100");
  }
  EXPECT_CONTAINS(error_of(edited([](Json& j) {
                    j["curves"][0]["emittance_profile"] = {1, 1e101};
                  })),
                  "curves[0].emittance_profile[1]: must be between 0 and 1e100");
}

// Coordinates of 1e-300 are distinct points: the scene is too small to solve (its squared lengths
// underflow), which is what the error must say, not "all points coincide".
TEST(SceneIoErrors, ATinySceneIsNamedAsTooSmall) {
  const std::string message = error_of(edited([](Json& j) {
    for (Json& curve : j["curves"])
      for (Json& point : curve.contains("line") ? curve["line"] : curve["bezier"])
        for (Json& coordinate : point) coordinate = coordinate.get<double>() * 1e-300;
  }));
  EXPECT_CONTAINS(message, "scale it up to at least 1e-100");
  EXPECT_EQ(message.find("coincide"), std::string::npos) << message;
}

// Two stretches of curve on top of each other are refused, naming both curves and where; curves
// that cross, touch at a point or rest tangentially on each other are not overlaps.
TEST(SceneIoErrors, OverlappingCurvesAreRefused) {
  const auto with = [](const char* curve) {
    return edited([&](Json& j) { j["curves"].push_back(Json::parse(curve)); });
  };
  const Scene base = *parse(edited([](Json&) {}));
  const Curve& first = base.curves[0];
  const Vec2 a = first.points.front();
  const Vec2 b = first.points.back();
  char same[256], reversed[256], part[256];
  std::snprintf(same, sizeof same, R"({"id": "copy", "material": "%s", "line": [[%.17g, %.17g], [%.17g, %.17g]]})",
                base.materials[first.material].name.c_str(), a.x, a.y, b.x, b.y);
  std::snprintf(
      reversed, sizeof reversed,
      R"({"id": "copy", "material": "%s", "bezier": [[%.17g, %.17g], [%.17g, %.17g], [%.17g, %.17g], [%.17g, %.17g]]})",
      base.materials[first.material].name.c_str(), b.x, b.y, (2 * b.x + a.x) / 3, (2 * b.y + a.y) / 3,
      (b.x + 2 * a.x) / 3, (b.y + 2 * a.y) / 3, a.x, a.y);
  std::snprintf(part, sizeof part, R"({"id": "copy", "material": "%s", "line": [[%.17g, %.17g], [%.17g, %.17g]]})",
                base.materials[first.material].name.c_str(), 0.7 * a.x + 0.3 * b.x, 0.7 * a.y + 0.3 * b.y,
                0.4 * a.x + 0.6 * b.x, 0.4 * a.y + 0.6 * b.y);
  for (const char* curve : {same, reversed, part}) {
    const std::string message = error_of(with(curve));
    EXPECT_CONTAINS(message, "(\"" + first.id + "\") segment 0 and curves[");
    EXPECT_CONTAINS(message, "(\"copy\") segment 0 lie on top of each other near (");
  }
  // A line that folds back over itself.
  EXPECT_CONTAINS(error_of(with(R"({"id": "fold", "material": "wall", "line": [[5, 5], [6, 5], [5.5, 5]]})")),
                  "(\"fold\") segment 0 and its own segment 1 lie on top of each other");
  // Crossing, touching end to end, and a half circle resting tangentially on a line: accepted.
  for (const char* curve : {R"({"id": "x", "material": "wall", "line": [[4, 4], [6, 6]]})",
                            R"({"id": "y", "material": "wall", "line": [[4, 6], [6, 4]]})"}) {
    const Result<Scene> scene = parse(with(curve));
    EXPECT_TRUE(scene.ok()) << scene.error().message;
  }
  const Result<Scene> resting = parse(edited([](Json& j) {
    j["curves"].push_back(Json::parse(R"({"id": "ground", "material": "wall", "line": [[4, 4], [6, 4]]})"));
    j["curves"].push_back(Json::parse(R"({"id": "ball", "material": "wall", "bezier":
        [[5, 4], [5.1656854, 4], [5.3, 4.1343146], [5.3, 4.3], [5.3, 4.4656854], [5.1656854, 4.6], [5, 4.6]]})"));
  }));
  EXPECT_TRUE(resting.ok()) << resting.error().message;
}

}  // namespace
}  // namespace flatland

namespace flatland {
namespace {

// A closed square (four straight sides, corners everywhere) and a closed smooth loop (a circle of
// two cubic halves, handles 4/3 r), in either format version, with the given "joints" entry.
std::string closed_curves(int version, const std::string& loop_joints) {
  return "{\"flatland\": " + std::to_string(version) + R"(,
    "materials": {"wall": {"reflectivity": 0.5, "emittance": 1}},
    "curves": [
      {"id": "square", "material": "wall", "line": [[0,0],[1,0],[1,1],[0,1],[0,0]]},
      {"id": "loop", "material": "wall", "bezier": [[3,0],[3,1.3333333333333333],[5,1.3333333333333333],[5,0],
                                                     [5,-1.3333333333333333],[3,-1.3333333333333333],[3,0]])" +
         (loop_joints.empty() ? "" : ", \"joints\": " + loop_joints) + "}]}";
}

TEST(SceneIoClosedCurves, TheClosingPointIsAJointInVersionTwo) {
  const Result<Scene> v2 = parse(closed_curves(2, ""));
  ASSERT_TRUE(v2.ok()) << v2.error().message;
  const Curve& square = v2->curves[0];
  const Curve& loop = v2->curves[1];
  EXPECT_TRUE(square.closed);
  EXPECT_TRUE(loop.closed);
  // One joint per segment; the square's closing corner is a jump, the loop's smooth closing C1.
  EXPECT_EQ(square.joints, std::vector<Continuity>(4, Continuity::Jump));
  EXPECT_FALSE(square.periodic());
  EXPECT_EQ(loop.joints, (std::vector<Continuity>{Continuity::C1, Continuity::C1}));
  EXPECT_TRUE(loop.periodic());
  EXPECT_TRUE(is_tangent_continuous(*v2, loop, 1));  // the closing joint
  EXPECT_FALSE(is_tangent_continuous(*v2, square, 3));
  // Version 1: the same loop keeps its seam.
  const Result<Scene> v1 = parse(closed_curves(1, ""));
  ASSERT_TRUE(v1.ok()) << v1.error().message;
  EXPECT_EQ(v1->curves[1].joints, (std::vector<Continuity>{Continuity::C1, Continuity::Jump}));
  EXPECT_FALSE(v1->curves[1].periodic());
  // Explicit entries: one string for all joints (the closing one too in version 2, not in 1),
  // s - 1 entries (closing by default) or s.
  EXPECT_EQ(parse(closed_curves(2, "\"C0\""))->curves[1].joints, std::vector<Continuity>(2, Continuity::C0));
  EXPECT_EQ(parse(closed_curves(1, "\"C0\""))->curves[1].joints,
            (std::vector<Continuity>{Continuity::C0, Continuity::Jump}));
  EXPECT_EQ(parse(closed_curves(2, "[\"C0\"]"))->curves[1].joints,
            (std::vector<Continuity>{Continuity::C0, Continuity::C1}));
  EXPECT_EQ(parse(closed_curves(2, "[\"C1\", \"C-1\"]"))->curves[1].joints,
            (std::vector<Continuity>{Continuity::C1, Continuity::Jump}));
  EXPECT_FALSE(parse(closed_curves(2, "[\"C1\", \"C-1\"]"))->curves[1].periodic());
  EXPECT_CONTAINS(error_of(closed_curves(2, "[\"C1\", \"C1\", \"C1\"]")),
                  "curves[1].joints: expected 2 entries (one per joint of the closed chain, the last "
                  "at the closing point) or 1 (the closing point by its tangents), got 3");
  // Version 1 has no closing entry.
  EXPECT_CONTAINS(error_of(closed_curves(1, "[\"C1\", \"C1\"]")), "curves[1].joints: expected 1 entry");
}

}  // namespace
}  // namespace flatland
