// Derived scene data: the flat segment list shared by the ray caster and the solver, per-segment arc
// length tables, per-curve cumulative lengths, bounds and the scene scale. Also the geometric
// validation (zero-length segments, interior cusps) that needs the scene's size for its tolerances.
#include "flatland/scene/scene.hpp"

#include "flatland/base/text.hpp"

#include "flatland/base/quadrature.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace flatland {
namespace {

// A segment shorter than kZeroLength * scale counts as a point (scale: the bounding-box diagonal).
// unit_tangent and find_cusp apply the same relative threshold to |C'(t)| given the scale.
constexpr double kZeroLength = 1e-12;
// Coordinates and the scene's extent are kept far from double's limits, so derivatives (3 (P1 -
// P0)), squared lengths and the quadratures of arc length stay finite and normal.
constexpr double kMaxCoordinate = 1e100;
constexpr double kMinExtent = 1e-100;
// Two unit tangents within this angle (radians) make a tangent-continuous joint.
constexpr double kTangentAngle = 1e-9;

std::string point_text(Vec2 p) {
  // Appended piece by piece: GCC 12 warns falsely (-Wrestrict) about "(" + std::string.
  std::string text = "(";
  text += format_number(p.x, 6);
  text += ", ";
  text += format_number(p.y, 6);
  text += ")";
  return text;
}

const char* geometry_key(const Curve& c) { return c.kind == SegmentKind::Line ? "line" : "bezier"; }

std::string curve_path(std::size_t index) { return "curves[" + std::to_string(index) + "]"; }

std::string point_path(const Curve& c, std::size_t curve_index, std::size_t point_index) {
  return curve_path(curve_index) + "." + geometry_key(c) + "[" + std::to_string(point_index) + "]";
}

Error fail(const std::string& field, const std::string& what) { return Error{field + ": " + what}; }

std::size_t expected_segment_count(const Curve& c) {
  if (c.kind == SegmentKind::Line) return c.points.size() >= 2 ? c.points.size() - 1 : 0;
  if (c.points.size() < 4 || (c.points.size() - 1) % 3 != 0) return 0;
  return (c.points.size() - 1) / 3;
}

Cubic segment_shape(const Curve& c, std::size_t j) {
  if (c.kind == SegmentKind::Line) return line_as_cubic(c.points[j], c.points[j + 1]);
  return Cubic{{c.points[3 * j], c.points[3 * j + 1], c.points[3 * j + 2], c.points[3 * j + 3]}};
}

// The default continuity at the joint between segments a (its end) and b (its start): C1 where the
// unit tangents agree to kTangentAngle, a jump (C-1) at a corner. The angle between unit vectors u,
// v, atan2(|u x v|, u . v), is at most kTangentAngle exactly when u . v > 0 and |u x v| <=
// tan(kTangentAngle) u . v, with tan(t) = t + t^3/3 to far below an ulp at t = 1e-9 (no library
// call: its last bit varies between C libraries).
Continuity default_joint(const Cubic& a, const Cubic& b, double scale) {
  const Vec2 u = unit_tangent(a, 1.0, scale);
  const Vec2 v = unit_tangent(b, 0.0, scale);
  constexpr double kTangentTan = kTangentAngle + kTangentAngle * kTangentAngle * kTangentAngle / 3.0;
  const double along = dot(u, v);
  return along > 0.0 && std::fabs(cross(u, v)) <= kTangentTan * along ? Continuity::C1 : Continuity::Jump;
}

// Distance from p to a scene segment: closed form for a line, distance_to_cubic otherwise.
double distance_to_segment(const SceneSegment& segment, Vec2 p) {
  const Cubic& c = segment.geometry.shape;
  if (segment.geometry.kind == SegmentKind::Line) {
    const Vec2 d = c.p[3] - c.p[0];
    const double t = std::clamp(dot(p - c.p[0], d) / dot(d, d), 0.0, 1.0);
    return length(c.p[0] + t * d - p);
  }
  return distance_to_cubic(c, p);
}

// Where segment a runs along segment b: three consecutive of 16 sample points of a (a stretch of
// at least an eighth of a) within `tolerance` of b. Crossings and tangential contacts touch b at
// isolated points only, so they never give three in a row.
// A point outside b's control-point box grown by the tolerance is farther than that from b; the
// box test spares the closest-point search for most samples of neighbouring segments.
std::optional<Vec2> runs_along(const SceneSegment& a, const SceneSegment& b, const Box& b_box, double tolerance) {
  constexpr int kSamples = 16;
  int run = 0;
  for (int k = 0; k < kSamples; ++k) {
    const Vec2 p = evaluate(a.geometry.shape, (k + 0.5) / kSamples);
    const bool near = p.x >= b_box.lower.x - tolerance && p.x <= b_box.upper.x + tolerance &&
                      p.y >= b_box.lower.y - tolerance && p.y <= b_box.upper.y + tolerance &&
                      distance_to_segment(b, p) <= tolerance;
    run = near ? run + 1 : 0;
    if (run == 3) return evaluate(a.geometry.shape, (k - 0.5) / kSamples);
  }
  return std::nullopt;
}

// Two stretches of curve on top of each other (the same surface twice, or a line folding back
// over itself) make light between them undefined: the solver and the reference disagree there.
// Candidate pairs come from a sweep over the segments' boxes in x; the tolerance is relative to
// the shorter segment, plus the rounding of the coordinates' magnitude.
Status check_overlaps(const Scene& scene) {
  const std::vector<SceneSegment>& segments = scene.segments;
  std::vector<Box> boxes;
  boxes.reserve(segments.size());
  double magnitude = 0.0;
  for (const SceneSegment& segment : segments) {
    boxes.push_back(hull_bounds(segment.geometry.shape));
    for (const Vec2& p : segment.geometry.shape.p) magnitude = std::max({magnitude, std::fabs(p.x), std::fabs(p.y)});
  }
  const double rounding = 64.0 * std::numeric_limits<double>::epsilon() * magnitude;
  std::vector<std::uint32_t> order(segments.size());
  for (std::uint32_t i = 0; i < order.size(); ++i) order[i] = i;
  std::sort(order.begin(), order.end(),
            [&](std::uint32_t a, std::uint32_t b) { return boxes[a].lower.x < boxes[b].lower.x; });
  std::vector<std::uint32_t> active;
  for (const std::uint32_t i : order) {
    const Box& box = boxes[i];
    std::erase_if(active, [&](std::uint32_t j) { return boxes[j].upper.x + rounding < box.lower.x; });
    for (const std::uint32_t j : active) {
      const Box& other = boxes[j];
      if (other.upper.y + rounding < box.lower.y || box.upper.y + rounding < other.lower.y) continue;
      const std::uint32_t ia = std::min(i, j);
      const std::uint32_t ib = std::max(i, j);
      const SceneSegment& a = segments[ia];
      const SceneSegment& b = segments[ib];
      const double tolerance = 1e-9 * std::min(a.length, b.length) + rounding;
      std::optional<Vec2> where = runs_along(a, b, boxes[ib], tolerance);
      if (!where) where = runs_along(b, a, boxes[ia], tolerance);
      if (!where) continue;
      const Curve& ca = scene.curves[a.curve];
      const Curve& cb = scene.curves[b.curve];
      const std::string first =
          curve_path(a.curve) + " (\"" + ca.id + "\") segment " + std::to_string(a.index_in_curve);
      const std::string second =
          a.curve == b.curve ? "its own segment " + std::to_string(b.index_in_curve)
                             : curve_path(b.curve) + " (\"" + cb.id + "\") segment " + std::to_string(b.index_in_curve);
      return fail(curve_path(b.curve),
                  first + " and " + second + " lie on top of each other near " + point_text(*where) +
                      ": light between coincident surfaces is undefined; remove one of them or move it apart");
    }
    active.push_back(i);
  }
  return ok_status();
}
}  // namespace

double emittance_factor(const Curve& curve, double u) {
  if (curve.emittance_profile.empty()) return 1.0;
  const auto local = static_cast<std::size_t>(std::clamp(std::floor(u), 0.0, curve.segment_count - 1.0));
  const double t = u - static_cast<double>(local);
  const std::vector<double>& v = curve.emittance_profile;
  if (curve.kind == SegmentKind::Line) return (1.0 - t) * v[local] + t * v[local + 1];
  const double s = 1.0 - t;
  const std::size_t i = 3 * local;
  return s * s * s * v[i] + 3.0 * s * s * t * v[i + 1] + 3.0 * s * t * t * v[i + 2] + t * t * t * v[i + 3];
}

double arc_length_at(const Scene& scene, const Curve& curve, double u) {
  const auto index = static_cast<std::uint32_t>(std::clamp(std::floor(u), 0.0, curve.segment_count - 1.0));
  const SceneSegment& segment = scene.segments[curve.first_segment + index];
  return curve.segment_start[index] + segment.arc_length.length_at(segment.geometry.shape, u - index);
}

CurvePoint point_at_arc_length(const Scene& scene, const Curve& curve, double s) {
  // The last segment whose start is <= s; clamp s into the curve.
  s = std::clamp(s, 0.0, curve.length);
  const auto begin = curve.segment_start.begin();
  const auto end = begin + curve.segment_count;
  auto it = std::upper_bound(begin, end, s);
  const auto index = static_cast<std::uint32_t>(std::max<std::ptrdiff_t>(0, (it - begin) - 1));
  const SceneSegment& segment = scene.segments[curve.first_segment + index];
  CurvePoint point;
  point.segment_in_curve = index;
  point.t = segment.arc_length.parameter_at(segment.geometry.shape, s - curve.segment_start[index]);
  point.u = index + point.t;
  point.position = evaluate(segment.geometry.shape, point.t);
  return point;
}

bool is_tangent_continuous(const Scene& scene, const Curve& curve, std::uint32_t joint) {
  const std::uint32_t next = joint + 1 == curve.segment_count ? 0 : joint + 1;  // closing joint
  const Cubic& a = scene.segments[curve.first_segment + joint].geometry.shape;
  const Cubic& b = scene.segments[curve.first_segment + next].geometry.shape;
  return default_joint(a, b, scene.scale) == Continuity::C1;
}

namespace {

// Pass 1: a curve's structure (its material, its point count) and its points, which must be finite
// and within range; `bounds` grows by them.
Status check_curve_points(const Scene& scene, std::size_t i, Box& bounds) {
  const Curve& c = scene.curves[i];
  if (c.material >= scene.materials.size()) {
    return fail(curve_path(i) + ".material", "material index " + std::to_string(c.material) +
                                                 " is out of range (the scene has " +
                                                 std::to_string(scene.materials.size()) + ")");
  }
  if (expected_segment_count(c) == 0) {
    return fail(curve_path(i) + "." + geometry_key(c),
                c.kind == SegmentKind::Line ? "a line needs at least 2 points, got " + std::to_string(c.points.size())
                                            : "expected 3k+1 points (k >= 1), got " + std::to_string(c.points.size()));
  }
  for (std::size_t k = 0; k < c.points.size(); ++k) {
    const Vec2 p = c.points[k];
    if (!is_finite(p)) return fail(point_path(c, i, k), "coordinates must be finite");
    if (std::fmax(std::fabs(p.x), std::fabs(p.y)) > kMaxCoordinate) {
      return fail(point_path(c, i, k),
                  "coordinate too large: " + point_text(p) + "; coordinates must lie within +-1e100");
    }
    bounds.extend(p);
  }
  return ok_status();
}

// Segment j of curve i: refused when it has zero length (every control point within zero_length
// of the first: the hull is a point) or a cusp; else its shape, arc-length table, length and
// speed bound.
Result<SceneSegment> make_segment(const Curve& c, std::size_t i, std::size_t j, double size, double zero_length) {
  const Cubic shape = segment_shape(c, j);
  const std::size_t first_point = c.kind == SegmentKind::Line ? j : 3 * j;
  double spread = 0.0;
  for (const Vec2& p : shape.p) spread = std::fmax(spread, length(p - shape.p[0]));
  if (spread <= zero_length) {
    if (c.kind == SegmentKind::Line) {
      return fail(point_path(c, i, first_point + 1), "coincides with the previous point, so segment " +
                                                         std::to_string(j) +
                                                         " has zero length; remove one of the two points");
    }
    return fail(point_path(c, i, first_point),
                "segment " + std::to_string(j) + " (control points " + std::to_string(first_point) + " to " +
                    std::to_string(first_point + 3) +
                    ") has zero length: its control points coincide; remove the segment");
  }
  if (c.kind == SegmentKind::Cubic) {
    if (const auto cusp = find_cusp(shape, size)) {
      return fail(point_path(c, i, first_point),
                  "segment " + std::to_string(j) + " has a cusp at t = " + format_number(*cusp, 6) + ", point " +
                      point_text(evaluate(shape, *cusp)) + ", where the normal flips; split the curve at t = " +
                      format_number(*cusp, 6) + " into two curves or two segments");
    }
  }
  SceneSegment segment;
  segment.geometry.kind = c.kind;
  segment.geometry.shape = shape;
  segment.curve = static_cast<std::uint32_t>(i);
  segment.index_in_curve = static_cast<std::uint32_t>(j);
  segment.arc_length = ArcLengthTable(shape);
  segment.length = c.kind == SegmentKind::Line ? length(shape.p[3] - shape.p[0]) : segment.arc_length.total();
  // A line traced by line_as_cubic has constant speed |C'| = its length.
  segment.speed_bound = c.kind == SegmentKind::Line ? segment.length : speed_bound(shape);
  if (!(segment.length > zero_length) || !std::isfinite(segment.length)) {
    return fail(point_path(c, i, first_point), "segment " + std::to_string(j) +
                                                   " has zero or non-finite length; "
                                                   "remove it or give it distinct points");
  }
  return segment;
}

// The emittance profile: its size, and its mean over arc length by Gauss-Legendre on each segment
// (8 panels of 4 points: the cubic profile times the smooth speed).
Status measure_profile(Curve& c, std::size_t i, const std::vector<Cubic>& shapes) {
  c.profile_mean = 1.0;
  c.profile_max = 1.0;
  if (c.emittance_profile.empty()) return ok_status();
  if (c.emittance_profile.size() != c.points.size())
    return fail(curve_path(i) + ".emittance_profile", "expected one factor per point (" +
                                                          std::to_string(c.points.size()) + "), got " +
                                                          std::to_string(c.emittance_profile.size()));
  c.profile_max = *std::max_element(c.emittance_profile.begin(), c.emittance_profile.end());
  if (!(c.profile_max > 0.0))
    return fail(curve_path(i) + ".emittance_profile", "every factor is zero; remove the emittance instead");
  const auto& kNodes = gauss::kNodes4;
  const auto& kWeights = gauss::kWeights4;
  double integral = 0.0;
  for (std::size_t j = 0; j < shapes.size(); ++j) {
    const Cubic& shape = shapes[j];
    for (int panel = 0; panel < 8; ++panel) {
      for (int g = 0; g < 4; ++g) {
        const double t = (panel + 0.5 + 0.5 * kNodes[g]) / 8.0;
        integral +=
            kWeights[g] * 0.5 / 8.0 * length(derivative(shape, t)) * emittance_factor(c, static_cast<double>(j) + t);
      }
    }
  }
  c.profile_mean = integral / c.length;
  return ok_status();
}

// Closed: the chain ends where it starts. Its closing point is a joint too (the last entry of
// `joints`); version-1 files meant a seam there, so their default is a jump. Joints not given
// follow the tangents (default_joint).
Status settle_joints(Curve& c, std::size_t i, const std::vector<Cubic>& shapes, double size, double zero_length,
                     int format_version) {
  const std::size_t count = shapes.size();
  c.closed = length(c.points.back() - c.points.front()) <= zero_length;
  const std::size_t inner_joints = count - 1;
  if (c.joints.empty()) {
    for (std::size_t j = 0; j < inner_joints; ++j) c.joints.push_back(default_joint(shapes[j], shapes[j + 1], size));
  } else if (c.joints.size() != inner_joints && !(c.closed && c.joints.size() == count)) {
    return fail(curve_path(i) + ".joints",
                c.closed ? "expected " + std::to_string(count) + " entries (one per joint of the closed chain of " +
                               std::to_string(count) + (count == 1 ? " segment" : " segments") +
                               ", the last at the closing point) or " + std::to_string(inner_joints) +
                               " (the closing point by its tangents), got " + std::to_string(c.joints.size())
                         : "expected " + std::to_string(inner_joints) + " entries (one per joint between the " +
                               std::to_string(count) + " segments), got " + std::to_string(c.joints.size()));
  }
  if (c.closed && c.joints.size() == inner_joints) {
    c.joints.push_back(format_version == 1 ? Continuity::Jump : default_joint(shapes[count - 1], shapes[0], size));
  }
  return ok_status();
}

}  // namespace

Status finalize_scene(Scene& scene) {
  scene.segments.clear();
  scene.bounds = Box{};
  if (scene.channels != 1 && scene.channels != 3) {
    return Error{"channels: expected 1 (grey) or 3 (colour), got " + std::to_string(scene.channels)};
  }
  if (scene.curves.empty()) return Error{"curves: the scene has no curves; add at least one"};

  // Pass 1: structure and the size of the scene, which sets every tolerance below.
  Box point_bounds;
  for (std::size_t i = 0; i < scene.curves.size(); ++i)
    if (Status status = check_curve_points(scene, i, point_bounds); !status) return status;
  const double size = point_bounds.diagonal();
  if (size == 0.0) {
    return fail(curve_path(0),
                "all points of the scene coincide, so every curve has zero length; "
                "give the curves distinct points");
  }
  if (size < kMinExtent) {
    return fail("curves", "the scene is only " + format_number(size, 6) +
                              " across; scale it up to at least 1e-100 (the unit is the metre)");
  }
  const double zero_length = kZeroLength * size;

  // Pass 2: segments, lengths, profiles, joints.
  for (std::size_t i = 0; i < scene.curves.size(); ++i) {
    Curve& c = scene.curves[i];
    const std::size_t count = expected_segment_count(c);
    c.first_segment = static_cast<std::uint32_t>(scene.segments.size());
    c.segment_count = static_cast<std::uint32_t>(count);
    c.segment_start.assign(1, 0.0);
    c.length = 0.0;
    std::vector<Cubic> shapes;
    shapes.reserve(count);
    for (std::size_t j = 0; j < count; ++j) {
      Result<SceneSegment> segment = make_segment(c, i, j, size, zero_length);
      if (!segment) return segment.error();
      scene.bounds.extend(hull_bounds(segment->geometry.shape));
      c.length += segment->length;
      c.segment_start.push_back(c.length);
      shapes.push_back(segment->geometry.shape);
      scene.segments.push_back(std::move(*segment));
    }
    if (Status status = measure_profile(c, i, shapes); !status) return status;
    if (Status status = settle_joints(c, i, shapes, size, zero_length, scene.format_version); !status) return status;
  }
  scene.scale = scene.bounds.diagonal();
  return check_overlaps(scene);
}

bool Scene::has_cubics() const {
  for (const SceneSegment& s : segments) {
    if (s.geometry.kind == SegmentKind::Cubic) return true;
  }
  return false;
}

bool Scene::has_specular() const {
  for (const Curve& c : curves)
    if (material_of(c).optics != Optics::Diffuse) return true;
  return false;
}

bool Scene::has_spectra() const {
  for (const Material& m : materials)
    if (m.spectrum) return true;
  return false;
}

bool Scene::is_emitter(const Curve& c) const {
  for (int channel = 0; channel < channels; ++channel) {
    if (c.emittance[static_cast<std::size_t>(channel)] > 0.0) return true;
  }
  return false;
}

double Scene::emitted_power() const {
  double total = 0.0;
  for (const Curve& c : curves) {
    const double emitting_sides = c.sides == Sides::Both ? 2.0 : 1.0;
    for (int channel = 0; channel < channels; ++channel) {
      total += emitting_sides * c.length * c.profile_mean * c.emittance[static_cast<std::size_t>(channel)];
    }
  }
  return total;
}

}  // namespace flatland
