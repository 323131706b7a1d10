// Where illumination is not smooth, found from the geometry (flatland discontinuity meshing, after
// Heckbert 1992).
//  - Contacts (D0): where a curve's end point or corner lies on another curve, or two curves cross,
//    light on the two sides of the contact is unrelated: the receiving curve gets a value jump.
//  - Direct-light events (D1): a receiver sees the emitting part of a source S change
//    combinatorially where it crosses a line that touches S and an occluder O at extremal points
//    (an end point or corner V, or a tangent point T of a curved piece). Along that line, past O,
//    the irradiance on the first surface hit has a kink (a C0 node: value continuous, slope not).
#pragma once

#include <atomic>
#include <cstdint>
#include <optional>
#include <string_view>
#include <utility>
#include <vector>

#include "flatland/geometry/accelerator.hpp"
#include "flatland/scene/scene.hpp"

namespace flatland {

// Which nodes the storage mesh gets: none (every joint C1, the smooth baseline), the joints as the
// scene file sets them (by default C-1 at corners, C1 at tangent joints), or those joints plus C0
// nodes at the visibility events found below; secondary adds the events of every reflecting curve
// as a source (the kinks its reflected light makes past occluders).
enum class DiscontinuityMode { None, Scene, Auto, Secondary };
const char* to_string(DiscontinuityMode mode);

struct DiscontinuityNode {
  std::uint32_t curve = 0;
  double u = 0.0;  // curve parameter: segment index + t
  Continuity continuity = Continuity::C0;
};

// Value jumps (Continuity::Jump) where curves touch, sorted by curve, then u:
//  - an end point or corner of one curve (the closing point of a closed curve only if it is a
//    corner) lies on another curve, or on a segment of its own curve that does not end there:
//    a node on the receiving curve at the contact;
//  - two curves cross in the interior of both (also at a tangent-continuous joint): a node on both;
//    so do two segments of one curve that are not neighbours.
// "Lies on" is within 1e-9 of the scene's size. Tangential touching of two smooth pieces is not a
// contact (light is continuous there). Never a node at the ends (u = 0, u = segment_count) of an
// open curve; on a closed curve a contact at the closing point is reported as u = 0. Nodes within
// 1e-9 in u are one. Candidate pairs come from a box tree over the segments: O(n log n) for
// scenes whose segments do not all overlap. The second form reuses a tree over scene.segments
// (in their order) that the caller already has.
std::vector<DiscontinuityNode> find_contacts(const Scene& scene);
std::vector<DiscontinuityNode> find_contacts(const Scene& scene, const SegmentAccelerator& tree);

// How events are merged. The element length of a curve is curve.length / elements; events on one
// curve closer than merge_fraction of it (in arc length) become one node at their mean, and events
// that close to an end of an open curve or to a value-jump joint are dropped (that node already
// allows any kink).
struct EventOptions {
  int elements = 16;
  double merge_fraction = 0.05;
  // Reflecting curves are sources too (secondary sources: the light they reflect is continuous
  // along them, so the lines from their end points, corners and silhouettes bound the part of
  // them a point sees just as an emitter's do), each with the sides that the curve has.
  bool secondary = false;
  // Set (by a signal handler, say) to stop the search early: find_visibility_events then returns
  // what it has found so far, and the caller, which owns the flag, discards it.
  const std::atomic<bool>* cancel = nullptr;
};

// Complete direct-light events of every emitter S (a curve with positive emittance; with
// options.secondary also every curve whose material reflects): the critical
// lines VV, VT, TV and TT from a point A of S to a point B of any curve O (S itself included) that
//  - leave S on an emitting side at A: at a vertex, an adjacent segment whose emitting side faces
//    the line's direction (or a straight one that the line runs along; a corner that the line
//    passes through only for non-diffuse emission); at a tangent point of S, the convex side of S
//    emits;
//  - do not cross O at a vertex B (O stays on one side of the line there);
//  - have an unoccluded touching segment A-B (a ray cast);
// get a C0 node where the line, continued past B, first hits a curve, if the side it hits reflects.
// Events are merged per EventOptions. Sorted by curve, then u.
std::vector<DiscontinuityNode> find_visibility_events(const Scene& scene, const SegmentAccelerator& accelerator,
                                                      const EventOptions& options = {});

// The tangent points of curve `curve` seen from p: the parameters u (sorted) of its curved pieces
// where the line from p touches the curve, the simple roots of g(t) = cross(C(t) - p, C'(t)).
// Vertices (end points, corners) are not tangent points; a straight piece, or a cubic within 1e-9 of
// the scene's size of its chord, has none; a tangent point at a tangent-continuous joint is found
// once.
std::vector<double> tangent_points(const Scene& scene, std::uint32_t curve, Vec2 p);

// The bitangents of two curves (or of one curve with itself, between different segments): pairs
// (u_a, u_b) of curve parameters where one line touches curve a at u_a and curve b at u_b, the
// solutions of cross(C_a(t) - C_b(u), C_a'(t)) = 0 = cross(C_a(t) - C_b(u), C_b'(u)) with the two
// points apart. Curved pieces only, not at vertices. Sorted by u_a, then u_b.
std::vector<std::pair<double, double>> bitangents(const Scene& scene, std::uint32_t curve_a, std::uint32_t curve_b);

}  // namespace flatland
