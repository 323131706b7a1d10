#pragma once
// The reference's visibility machinery, internal to reference/ (reference.cpp and
// form_factors.cpp include it; nothing outside the folder does): the angular sweep that finds what
// a point sees, the exact visibility of one element pair, their form factor by quadrature split at
// visibility events, and the mirror images one reflection adds.

#include <array>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "flatland/base/vec2.hpp"
#include "flatland/reference/reference.hpp"

namespace flatland::reference_detail {

// The angular sweep of visible_elements with buffers reused across calls (one per thread).
//
// Around x, with n the normal and t = (n.y, -n.x), a point p has depth a = n.(p - x) and lateral
// offset l = t.(p - x); the direction's angle from n is theta = atan2(l, a), and on the front
// half-plane (a >= 0) sin(theta) = l / |p - x| increases with theta, so sin(theta) serves as the
// sweep key directly. Each element, clipped to a >= 0, spans one key interval. Between two
// consecutive keys no end point lies, and elements do not cross, so one element is nearest across
// the whole gap: the one nearest along the ray in the gap's middle direction. It receives
// (key_hi - key_lo) / 2 of the form factor.
//
// Elements attached to x (the one x lies on, `self`, and those with an end point at x) stand for
// the curve through x: a point on a concave arc sees the arc itself between its tangent and the
// chord to the arc's end (in the directions from that end's key to +-1), which the chords miss.
// Those directions are owned by the attached element at distance 0. A point on the chord itself
// (the quadrature points of the form factors) has its chord's ends at depth 0: no such range.
class Sweeper {
 public:
  void run(const std::vector<ReferenceElement>& elements, Vec2 x, Vec2 normal, std::uint32_t self, Side self_side,
           std::vector<VisibleElement>& out);

 private:
  struct Piece {
    std::uint32_t element = 0;
    Vec2 a;  // (depth, lateral) of the element's ends relative to x
    Vec2 b;
    double low = 0.0;
    double high = 0.0;
    double seen = 0.0;
    bool clipped = false;
    bool attached = false;
    Side side = Side::Front;
  };
  struct Event {
    double key;
    std::uint32_t piece;
    bool start;
  };
  void push(const Piece& piece);
  std::vector<Piece> pieces_;
  std::vector<Event> events_;
  std::vector<std::uint32_t> active_;
};

// The point-to-element factor of one element j seen from x (normal n) with only `occluders` as
// occluders, for element pairs that see each other partly. In the sweep's (depth, lateral)
// coordinates j spans one interval of sin(theta) (clipped to depth >= 0, as in the sweep). An
// occluder k spans another; where the two overlap, k hides j over the whole overlap or nowhere in
// it (elements do not cross), so one depth comparison in the overlap's middle direction decides.
// F = (1/2) (measure of j's interval - measure of the union of the hiding overlaps). Zero when x
// sees the other side of j than `side_j`, or sees j edge-on.
class PairVisibility {
 public:
  double factor(const std::vector<ReferenceElement>& elements, const std::vector<std::uint32_t>& occluders, Vec2 x,
                Vec2 normal, std::uint32_t j, Side side_j);

 private:
  struct Span {
    Vec2 a;  // (depth, lateral) of the element's ends relative to x
    Vec2 b;
    double low = 0.0;
    double high = 0.0;
  };
  // The sin(theta) interval of an element seen from x, clipped to the half-plane in front of x;
  // false when it lies behind, or edge-on.
  static bool span_of(const ReferenceElement& e, Vec2 x, Vec2 normal, Vec2 lateral_axis, Span& span);
  std::vector<std::pair<double, double>> hidden_;
};

// Form factors of element pairs that see each other partly, by quadrature split at the visibility
// events (Heckbert's flatland discontinuity meshing, applied to one pair at a time).
//
// As x moves along element i, the part of element j that x sees is bounded by the directions from
// x to j's ends and to occluder end points; F(x -> j) is smooth as long as the set of bounding
// points stays the same, and has a kink (or a jump of its derivative's order) where it changes:
// where x crosses a line through two bounding points (an occluder end point and an end of j, two
// occluder end points, or the line of j itself, where x starts seeing j's other side). On chord
// geometry a curved occluder is a chain of straight elements, so its tangent points are chord end
// points and the lines of its chords are among these lines. A fixed Gauss rule across such a kink
// converges only as O(n^-2); cut at the kinks, each piece is smooth and Gauss-Legendre converges
// fast again.
//
// Which occluders: the triangle (x, ends of j) lies in the convex hull of i and j for every x on i,
// so only elements meeting that hull can hide j, and only their end points inside it can bound
// what is seen. A line through an occluder end point v matters only if it touches the chain
// there: when v's two elements lie on opposite sides of the line, the chain crosses it and v
// bounds nothing. (Spurious lines cost a piece of quadrature, never accuracy.)
class PairQuadrature {
 public:
  PairQuadrature(const std::vector<ReferenceElement>& elements, const std::vector<double>& nodes,
                 const std::vector<double>& weights);

  // (1/L_i) integral over element i of F(x -> j, side_j), x on the chord, normal of side_i.
  double form_factor(std::uint32_t i, Side side_i, std::uint32_t j, Side side_j, bool split = true);
  std::size_t pieces() const { return breaks_.size() - 1; }

 private:
  struct Box {
    double min_x, min_y, max_x, max_y;
  };

  // Elements (other than i and j) that meet the convex hull of i and j: bounding boxes first, then
  // separating axes (the hull's edges and the element's line).
  void find_occluders(std::uint32_t i, std::uint32_t j);

  // Counter-clockwise convex hull of four points (Andrew's monotone chain), into hull_.
  void convex_hull(std::array<Vec2, 4> points);

  // Whether the closed hull meets segment (a, b): no hull edge has both points strictly outside,
  // and the segment's line does not have the whole hull strictly on one side.
  bool meets_hull(Vec2 a, Vec2 b) const;
  bool inside_hull(Vec2 p) const;

  // The parameters on element i where x crosses a line through two bounding points, sorted, with
  // 0 and 1; pieces shorter than 1e-9 of the element are merged.
  void add_events(const ReferenceElement& ei, const ReferenceElement& ej);

  struct BoundingPoint {
    Vec2 position;
    Vec2 other{};   // the other end of an occluder element at this point
    Vec2 across{};  // the other end of its neighbour in the chain (if chained)
    bool chained = false;
    bool occluder = false;
    // A line through an end of j always bounds j's interval; through an occluder vertex only
    // where it does not cross the chain (the vertex's two elements on opposite sides).
    bool touches(Vec2 d) const {
      if (!occluder || !chained) return true;
      const double s1 = cross(d, other - position);
      const double s2 = cross(d, across - position);
      return !((s1 > 0.0 && s2 < 0.0) || (s1 < 0.0 && s2 > 0.0));
    }
  };

  const std::vector<ReferenceElement>& elements_;
  const std::vector<double>& nodes_;
  const std::vector<double>& weights_;
  std::vector<Box> bounds_;
  std::vector<std::uint32_t> occluders_;
  std::vector<Vec2> hull_;
  std::vector<BoundingPoint> points_;
  std::vector<double> breaks_;
  PairVisibility visibility_;
};

// ---- Mirrors
//
// Light from y reaches x by one reflection in a flat mirror when the path x -> M -> y (M on the
// mirror segment) is free. Reflected in the mirror's line, x -> M becomes x' -> M, a straight line
// on with M -> y: x sees y by the mirror exactly where its image x' sees y through the mirror
// segment (a window in the line), the elements in front of the mirror occluding M -> y and their
// images occluding x' -> M (elements behind the line take no part: the path stays in front). A
// sweep from x' over those, with x's normal reflected (reflection keeps angles to the normal, so
// the measure (sin b - sin a) / 2 is x's), gives F(x -> j by the mirror) for every element j; times
// the reflectance, it adds to the direct F. One reflection is all there is when no two mirrors face
// each other; scenes where two do are refused (ReferenceBuilder::check_single_reflections).

// p reflected in the mirror's line.
Vec2 mirrored_point(Vec2 p, const ReferenceMirror& mirror);

// Calls add(j, side_j, F) for every element side that x (on element `self`, or kNoElement; normal
// `normal`, receiving side `side`) sees by one reflection in `mirror`, F its form factor times the
// reflectance. Nothing for a point not in front of the mirror (`touch`: the scene's tolerance).
template <class Add>
void gather_by_mirror(Sweeper& sweeper, const ReferenceMirror& mirror, Vec2 x, Vec2 normal, std::uint32_t self,
                      Side side, double touch, std::vector<VisibleElement>& scratch, const Add& add) {
  if (!(dot(x - mirror.origin, mirror.normal) > touch)) return;
  const Vec2 image = mirrored_point(x, mirror);
  const Vec2 image_normal = normal - (2.0 * dot(normal, mirror.normal)) * mirror.normal;
  const std::uint32_t image_self = self != kNoElement ? mirror.image_of[self] : kNoElement;
  sweeper.run(mirror.elements, image, image_normal, image_self, side, scratch);
  for (const VisibleElement& v : scratch)
    if (const std::uint32_t j = mirror.real[v.element]; j != kNoElement)
      add(j, v.side, mirror.reflectance * v.form_factor);
}

}  // namespace flatland::reference_detail
