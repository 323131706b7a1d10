#include "flatland/scene/discontinuity_common.hpp"

#include <algorithm>
#include <cmath>

namespace flatland {

const char* to_string(DiscontinuityMode mode) {
  switch (mode) {
    case DiscontinuityMode::None: return "none";
    case DiscontinuityMode::Scene: return "scene";
    case DiscontinuityMode::Auto: return "auto";
    case DiscontinuityMode::Secondary: return "secondary";
  }
  return "?";
}

namespace discontinuity_detail {

void append_new_pairs(const std::vector<std::pair<double, double>>& found,
                      std::vector<std::pair<double, double>>& out) {
  for (const auto& s : found) {
    bool seen = false;
    for (const auto& q : out)
      seen =
          seen || (std::fabs(q.first - s.first) <= kSameParameter && std::fabs(q.second - s.second) <= kSameParameter);
    if (!seen) out.push_back(s);
  }
}

bool is_straight(const SegmentGeometry& g, double scale) {
  if (g.kind == SegmentKind::Line) return true;
  const Cubic& c = g.shape;
  const Vec2 chord = c.p[3] - c.p[0];
  const double chord_length = length(chord);
  const double limit = kStraight * scale;
  if (chord_length <= limit) return false;  // a closed loop in one segment
  for (int i = 1; i <= 2; ++i) {
    if (std::fabs(cross(chord, c.p[i] - c.p[0])) > limit * chord_length) return false;
    const double along = dot(chord, c.p[i] - c.p[0]);
    if (along < -limit * chord_length || along > chord_length * (chord_length + limit)) return false;
  }
  return true;
}

std::pair<double, double> closest_parameter(const SegmentGeometry& g, Vec2 p) {
  const Cubic& c = g.shape;
  if (g.kind == SegmentKind::Line) {
    const Vec2 d = c.p[3] - c.p[0];
    const double t = std::clamp(dot(p - c.p[0], d) / dot(d, d), 0.0, 1.0);
    return {t, length(lerp(c.p[0], c.p[3], t) - p)};
  }
  const CubicPoint nearest = closest_point_on_cubic(c, p);
  return {nearest.t, nearest.distance};
}

std::vector<Vertex> vertices_of(const Scene& scene, std::uint32_t c) {
  const Curve& curve = scene.curves[c];
  const std::uint32_t first = curve.first_segment;
  const std::uint32_t last = first + curve.segment_count - 1;
  std::vector<Vertex> out;
  auto start_of = [&](std::uint32_t s) { return scene.segments[s].geometry.shape.p[0]; };
  if (!curve.closed) out.push_back({start_of(first), c, 0.0, kNoSegment, first});
  for (std::uint32_t j = 0; j < curve.joint_count(); ++j) {
    if (is_tangent_continuous(scene, curve, j)) continue;
    const bool closing = j + 1 == curve.segment_count;
    const std::uint32_t after = closing ? first : first + j + 1;
    out.push_back({start_of(after), c, closing ? 0.0 : j + 1.0, first + j, after});
  }
  if (!curve.closed) {
    out.push_back(
        {scene.segments[last].geometry.shape.p[3], c, static_cast<double>(curve.segment_count), last, kNoSegment});
  }
  return out;
}

double wrap(const Curve& curve, double u) {
  if (!curve.closed) return u;
  const double n = curve.segment_count;
  if (u >= n - kSameParameter) u -= n;
  if (u < 0.0 && u > -kSameParameter) u = 0.0;
  return u;
}

bool before_node(const DiscontinuityNode& a, const DiscontinuityNode& b) {
  return a.curve < b.curve || (a.curve == b.curve && a.u < b.u);
}

std::vector<DiscontinuityNode> sorted_unique(const Scene& scene, std::vector<DiscontinuityNode> nodes) {
  std::sort(nodes.begin(), nodes.end(), before_node);
  std::vector<DiscontinuityNode> out;
  for (const DiscontinuityNode& node : nodes) {
    if (!out.empty() && out.back().curve == node.curve && node.u - out.back().u <= kSameParameter) {
      out.back().continuity = std::min(out.back().continuity, node.continuity);
      continue;
    }
    out.push_back(node);
  }
  // Wrap-around on closed curves: a node just below segment_count is the node at 0.
  std::vector<DiscontinuityNode> result;
  for (std::size_t i = 0; i < out.size(); ++i) {
    const Curve& curve = scene.curves[out[i].curve];
    const bool last_of_curve = i + 1 == out.size() || out[i + 1].curve != out[i].curve;
    if (curve.closed && last_of_curve && out[i].u >= curve.segment_count - kSameParameter) continue;
    result.push_back(out[i]);
  }
  return result;
}

}  // namespace discontinuity_detail

}  // namespace flatland
