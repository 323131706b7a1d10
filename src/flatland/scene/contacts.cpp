// Contacts (D0) from the geometry: another curve's end point or corner on a curve, and crossings,
// as polynomial roots in Bernstein form isolated by subdivision (the convex hull property).
#include "flatland/scene/discontinuities.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

#include "flatland/base/roots.hpp"
#include "flatland/geometry/bernstein.hpp"
#include "flatland/scene/discontinuity_common.hpp"

namespace flatland {

using namespace discontinuity_detail;
using bernstein::isolate_roots;

namespace {

// Proper crossings stay this far (in t) from the segments' ends; closer ones are contacts at the
// end point (found by the vertex and joint rules).
constexpr double kInteriorMargin = 1e-10;

// ---------------------------------------------------------------------------------------------
// Contacts.

// Proper crossings of two segments, (t_a, t_b) strictly inside both (kInteriorMargin).
void segment_crossings(const SegmentGeometry& a, const SegmentGeometry& b, double scale,
                       std::vector<std::pair<double, double>>& out) {
  auto interior = [](double t) { return t > kInteriorMargin && t < 1.0 - kInteriorMargin; };
  if (a.kind == SegmentKind::Line && b.kind == SegmentKind::Line) {
    // a0 + s (a1 - a0) = b0 + t (b1 - b0): s = cross(b0 - a0, eb) / cross(ea, eb), likewise t.
    const Vec2 ea = a.shape.p[3] - a.shape.p[0];
    const Vec2 eb = b.shape.p[3] - b.shape.p[0];
    const double denominator = cross(ea, eb);
    if (std::fabs(denominator) <= 1e-12 * length(ea) * length(eb)) return;  // parallel
    const Vec2 w = b.shape.p[0] - a.shape.p[0];
    const double s = cross(w, eb) / denominator;
    const double t = cross(w, ea) / denominator;
    if (interior(s) && interior(t)) out.emplace_back(s, t);
    return;
  }
  if (a.kind == SegmentKind::Line || b.kind == SegmentKind::Line) {
    const bool line_first = a.kind == SegmentKind::Line;
    const SegmentGeometry& line = line_first ? a : b;
    const Cubic& c = line_first ? b.shape : a.shape;
    // f(t) = cross(e, C(t) - l0) / |e| is the cubic's signed distance to the line, in Bernstein form
    // with coefficients cross(e, P_i - l0) / |e|.
    const Vec2 l0 = line.shape.p[0];
    const Vec2 e = line.shape.p[3] - l0;
    const double e_length = length(e);
    double k[4];
    double magnitude = 0.0;
    for (int i = 0; i < 4; ++i) {
      k[i] = cross(e, c.p[i] - l0) / e_length;
      magnitude = std::max(magnitude, length(c.p[i] - l0));
    }
    std::vector<double> roots;
    isolate_roots(
        k, 3, 0.0, 1.0, 16.0 * kEpsilon * magnitude, [&](double t) { return cross(e, evaluate(c, t) - l0) / e_length; },
        0, roots);
    for (const double t : roots) {
      const double s = dot(evaluate(c, t) - l0, e) / (e_length * e_length);
      if (!interior(t) || !interior(s)) continue;
      if (line_first) {
        out.emplace_back(s, t);
      } else {
        out.emplace_back(t, s);
      }
    }
    return;
  }
  // Two cubics: halve the pair while the control-point boxes overlap; from pieces 1/16 wide, Newton
  // on A(t) - B(u) = 0 (Jacobian [A', -B']) from their centres, accepted where it converges inside
  // the pieces and the crossing is transversal (a tangential touching is not a crossing).
  struct Pair {
    double t0, t1, u0, u1;
    Cubic a, b;
  };
  const double pad = kTouch * scale;
  std::vector<Pair> stack{{0.0, 1.0, 0.0, 1.0, a.shape, b.shape}};
  std::vector<std::pair<double, double>> found;
  int budget = 4000;
  while (!stack.empty() && budget-- > 0) {
    const Pair pair = stack.back();
    stack.pop_back();
    if (!hull_bounds(pair.a).padded(pad).overlaps(hull_bounds(pair.b))) continue;
    const double wt = pair.t1 - pair.t0;
    const double wu = pair.u1 - pair.u0;
    if (wt <= 1.0 / 16 && wu <= 1.0 / 16) {
      double t = 0.5 * (pair.t0 + pair.t1);
      double u = 0.5 * (pair.u0 + pair.u1);
      bool converged = false;
      for (int iteration = 0; iteration < 30 && !converged; ++iteration) {
        const Vec2 f = evaluate(a.shape, t) - evaluate(b.shape, u);
        const Vec2 da = derivative(a.shape, t);
        const Vec2 db = derivative(b.shape, u);
        const double det = cross(db, da);  // det [da, -db]
        if (!(std::fabs(det) > 0.0)) break;
        // [da -db] (dt, du) = f: Cramer's rule.
        const double dt = cross(db, f) / det;
        const double du = cross(da, f) / det;
        t -= dt;
        u -= du;
        if (!(t > -0.5 && t < 1.5 && u > -0.5 && u < 1.5)) break;
        converged = std::fabs(dt) <= 1e-15 && std::fabs(du) <= 1e-15;
      }
      if (converged && t >= pair.t0 - 0.1 * wt && t <= pair.t1 + 0.1 * wt && u >= pair.u0 - 0.1 * wu &&
          u <= pair.u1 + 0.1 * wu) {
        const Vec2 da = derivative(a.shape, t);
        const Vec2 db = derivative(b.shape, u);
        if (interior(t) && interior(u) && std::fabs(cross(da, db)) > 1e-6 * length(da) * length(db))
          found.emplace_back(t, u);
        continue;
      }
      if (wt <= 1.0 / 4096 && wu <= 1.0 / 4096) continue;
    }
    if (wt >= wu) {
      const auto [left, right] = split(pair.a, 0.5);
      const double middle = 0.5 * (pair.t0 + pair.t1);
      stack.push_back({middle, pair.t1, pair.u0, pair.u1, right, pair.b});
      stack.push_back({pair.t0, middle, pair.u0, pair.u1, left, pair.b});
    } else {
      const auto [left, right] = split(pair.b, 0.5);
      const double middle = 0.5 * (pair.u0 + pair.u1);
      stack.push_back({pair.t0, pair.t1, middle, pair.u1, pair.a, right});
      stack.push_back({pair.t0, pair.t1, pair.u0, middle, pair.a, left});
    }
  }
  append_new_pairs(found, out);
}

// Whether segments i and j of one curve share an end point (neighbours, also across the closing
// point).
bool neighbours(const Curve& curve, std::uint32_t i, std::uint32_t j) {
  if (i == j) return true;
  const std::uint32_t lo = std::min(i, j);
  const std::uint32_t hi = std::max(i, j);
  return hi == lo + 1 || (curve.closed && lo == 0 && hi + 1 == curve.segment_count);
}

}  // namespace

std::vector<DiscontinuityNode> find_contacts(const Scene& scene) {
  std::vector<SegmentGeometry> geometry;
  geometry.reserve(scene.segments.size());
  for (const SceneSegment& segment : scene.segments) geometry.push_back(segment.geometry);
  return find_contacts(scene, SegmentAccelerator(std::move(geometry), SegmentAccelerator::Queries::Overlaps));
}

std::vector<DiscontinuityNode> find_contacts(const Scene& scene, const SegmentAccelerator& tree) {
  const double touch = kTouch * scene.scale;
  // The segments near a place: those whose box comes within `touch` of it (the caster's tree
  // answers that as well as rays).
  std::vector<DiscontinuityNode> nodes;
  auto add = [&](std::uint32_t c, double u) {
    const Curve& curve = scene.curves[c];
    if (!curve.closed && (u <= kSameParameter || u >= curve.segment_count - kSameParameter)) return;
    nodes.push_back({c, wrap(curve, u), Continuity::Jump});
  };
  auto point_box = [](Vec2 p) {
    Box box;
    box.extend(p);
    return box;
  };

  // Vertices on other curves, or on segments of their own curve that do not end there.
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    for (const Vertex& v : vertices_of(scene, c)) {
      tree.for_each_overlapping(point_box(v.position).padded(touch), [&](std::uint32_t s) {
        const SceneSegment& segment = scene.segments[s];
        if (segment.curve == c && (s == v.before || s == v.after)) return;
        const auto [t, distance] = closest_parameter(segment.geometry, v.position);
        if (distance <= touch) add(segment.curve, segment.index_in_curve + t);
      });
    }
  }

  // Tangent-continuous joints on another curve (or a segment of their own curve that does not end
  // there), where the curve passes through: the joint's neighbours on both sides of the other
  // curve's tangent line. A crossing exactly at a joint is not interior to either segment.
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    const Curve& curve = scene.curves[c];
    for (std::uint32_t j = 0; j < curve.joint_count(); ++j) {
      if (!is_tangent_continuous(scene, curve, j)) continue;
      const std::uint32_t before = curve.first_segment + j;
      const std::uint32_t after = j + 1 == curve.segment_count ? curve.first_segment : before + 1;
      const Vec2 joint = scene.segments[after].geometry.shape.p[0];
      tree.for_each_overlapping(point_box(joint).padded(touch), [&](std::uint32_t s) {
        const SceneSegment& segment = scene.segments[s];
        if (segment.curve == c && (s == before || s == after)) return;
        const auto [t, distance] = closest_parameter(segment.geometry, joint);
        if (distance > touch) return;
        const Vec2 base = evaluate(segment.geometry.shape, t);
        const Vec2 tangent = unit_tangent(segment.geometry.shape, t, scene.scale);
        const double h = 1e-3;
        const double side_before = cross(tangent, evaluate(scene.segments[before].geometry.shape, 1.0 - h) - base);
        const double side_after = cross(tangent, evaluate(scene.segments[after].geometry.shape, h) - base);
        if (!((side_before < 0.0 && side_after > 0.0) || (side_before > 0.0 && side_after < 0.0))) return;
        add(c, j + 1.0);
        add(segment.curve, segment.index_in_curve + t);
      });
    }
  }

  // Proper crossings of two segments.
  std::vector<std::pair<double, double>> crossings;
  for (std::uint32_t i = 0; i < scene.segments.size(); ++i) {
    const SceneSegment& a = scene.segments[i];
    tree.for_each_overlapping(segment_box(a.geometry).padded(touch).padded(touch), [&](std::uint32_t j) {
      if (j <= i) return;
      const SceneSegment& b = scene.segments[j];
      if (a.curve == b.curve && neighbours(scene.curves[a.curve], a.index_in_curve, b.index_in_curve)) return;
      crossings.clear();
      segment_crossings(a.geometry, b.geometry, scene.scale, crossings);
      for (const auto& [t, u] : crossings) {
        add(a.curve, a.index_in_curve + t);
        add(b.curve, b.index_in_curve + u);
      }
    });
  }
  return sorted_unique(scene, std::move(nodes));
}

}  // namespace flatland
