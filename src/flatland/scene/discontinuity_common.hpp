// What finding contacts (contacts.cpp) and direct-light events (visibility_events.cpp) share,
// internal to those two files: tolerances, a curve's vertices, and node bookkeeping.
#pragma once

#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "flatland/scene/discontinuities.hpp"
#include "flatland/scene/scene.hpp"

namespace flatland::discontinuity_detail {

inline constexpr double kEpsilon = std::numeric_limits<double>::epsilon();
// A point lies on a curve, and two points coincide, within kTouch * scale (the scene's size).
inline constexpr double kTouch = 1e-9;
// A cubic whose inner control points lie within kStraight * scale of its chord is straight here:
// it has no interior tangent points (g is zero up to rounding along all of it).
inline constexpr double kStraight = 1e-9;
// Curve parameters closer than this are the same node.
inline constexpr double kSameParameter = 1e-9;

// Appends to `out` each pair of `found` (parameters on two curves) that is not within
// kSameParameter in both of a pair already there: one crossing found twice (from both sides of a
// split, or at a shared end) is kept once.
void append_new_pairs(const std::vector<std::pair<double, double>>& found, std::vector<std::pair<double, double>>& out);

// Whether the segment is straight for the purpose of tangent points: a line, or a cubic whose inner
// control points lie within kStraight * scale of the chord (then the whole curve does).
bool is_straight(const SegmentGeometry& g, double scale);

// The point of segment g nearest to p: the nearest of 32 samples, then Newton on
// h(t) = C'(t) . (C(t) - p) (half the derivative of the squared distance) kept inside the samples'
// bracket. Lines in closed form.
std::pair<double, double> closest_parameter(const SegmentGeometry& g, Vec2 p);

// A vertex: the end point of an open curve or a corner (the closing point of a closed curve only
// if it is a corner).
struct Vertex {
  Vec2 position;
  std::uint32_t curve = 0;
  double u = 0.0;                     // curve parameter (0 for a closing corner)
  std::uint32_t before = kNoSegment;  // segment ending here (t = 1)
  std::uint32_t after = kNoSegment;   // segment starting here (t = 0)
  std::uint32_t segment() const { return after != kNoSegment ? after : before; }
  double t() const { return after != kNoSegment ? 0.0 : 1.0; }
};

std::vector<Vertex> vertices_of(const Scene& scene, std::uint32_t c);

// A curve parameter on a closed curve wrapped into [0, segment_count), the closing point as 0.
double wrap(const Curve& curve, double u);

bool before_node(const DiscontinuityNode& a, const DiscontinuityNode& b);

// Sorted, with nodes of one curve within kSameParameter in u (around the closing point of a closed
// curve too) merged into the first, keeping the lower continuity.
std::vector<DiscontinuityNode> sorted_unique(const Scene& scene, std::vector<DiscontinuityNode> nodes);

}  // namespace flatland::discontinuity_detail
