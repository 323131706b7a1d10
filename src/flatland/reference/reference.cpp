#include "flatland/reference/reference.hpp"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <string>
#include <thread>

#include "flatland/base/quadrature.hpp"
#include "flatland/base/resources.hpp"
#include "flatland/base/workers.hpp"
#include "flatland/geometry/discontinuities.hpp"
#include "flatland/results/result_io.hpp"
#include "flatland/results/sampled_result.hpp"

namespace flatland {

namespace {

std::size_t patch_index(std::uint32_t element, Side side) {
  return 2 * static_cast<std::size_t>(element) + static_cast<std::size_t>(side);
}

bool any_positive(const Spectrum& s, int channels) {
  for (int c = 0; c < channels; ++c)
    if (s[static_cast<std::size_t>(c)] > 0.0) return true;
  return false;
}

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
           std::vector<VisibleElement>& out) {
    out.clear();
    events_.clear();
    pieces_.clear();
    const std::size_t count = elements.size();
    const Vec2 lateral_axis{normal.y, -normal.x};
    // x and the element ends carry the rounding of their coordinates (a point evaluated on a
    // curve far from the origin differs from the chord end at the same place by a few units in
    // the last place of |x|, 1.5e-8 at 1e8): an end that near x is at x.
    const double rounding = 64.0 * std::numeric_limits<double>::epsilon() * (std::fabs(x.x) + std::fabs(x.y));
    auto add_attached = [&](std::uint32_t j, Vec2 r, double length_r, bool own) {
      const double depth = dot(r, normal);
      if (!(depth > 1e-12 * length_r)) return;  // convex there (or on the chord): not seen
      const double key = dot(r, lateral_axis) / length_r;
      Piece piece;
      piece.element = j;
      piece.attached = true;
      piece.low = key > 0.0 ? key : -1.0;
      piece.high = key > 0.0 ? 1.0 : key;
      if (!(piece.high > piece.low)) return;
      if (own) {
        piece.side = self_side;
      } else {
        // x is on the line of j, and the arc of j bulges to the side of the chord's line these
        // directions go to; they meet the arc from its concave side, the side that faces the
        // chord: the front when they go to the chord's back half-plane (d . n_j < 0).
        const double s = 0.5 * (piece.low + piece.high);
        const Vec2 d = std::sqrt(std::max(0.0, 1.0 - s * s)) * normal + s * lateral_axis;
        piece.side = dot(d, elements[j].normal) < 0.0 ? Side::Front : Side::Back;
      }
      push(piece);
    };
    for (std::uint32_t j = 0; j < count; ++j) {
      const ReferenceElement& e = elements[j];
      const Vec2 ra = e.a - x;
      const Vec2 rb = e.b - x;
      const double la = length(ra);
      const double lb = length(rb);
      const double at_vertex = std::max(1e-12 * std::max(la + lb, e.length), rounding);
      if (j == self) {
        if (la > at_vertex) add_attached(j, ra, la, true);
        if (lb > at_vertex) add_attached(j, rb, lb, true);
        continue;
      }
      // x at an end point of j (a neighbour in the chain).
      if (la <= at_vertex) {
        if (lb > at_vertex) add_attached(j, rb, lb, false);
        continue;
      }
      if (lb <= at_vertex) {
        add_attached(j, ra, la, false);
        continue;
      }
      // cross(ra, rb) = (x - a) . perp(b - a): positive when x is in front of j. Zero: x on the
      // line of j, which is then seen edge-on.
      const double orientation = cross(ra, rb);
      if (std::fabs(orientation) <= 1e-12 * la * lb) continue;
      Piece piece;
      piece.element = j;
      piece.a = {dot(ra, normal), dot(ra, lateral_axis)};
      piece.b = {dot(rb, normal), dot(rb, lateral_axis)};
      if (piece.a.x <= 0.0 && piece.b.x <= 0.0) continue;  // behind the half-plane
      auto key_of = [&](Vec2 p, Vec2 q, double length_p) {
        if (p.x >= 0.0) return p.y / length_p;
        // Clip at depth 0: the crossing's lateral sign gives theta = +-90 degrees.
        piece.clipped = true;
        const double s = p.x / (p.x - q.x);
        const double lateral = p.y + s * (q.y - p.y);
        return lateral > 0.0 ? 1.0 : -1.0;
      };
      const double ka = key_of(piece.a, piece.b, la);
      const double kb = key_of(piece.b, piece.a, lb);
      piece.low = std::min(ka, kb);
      piece.high = std::max(ka, kb);
      if (!(piece.high > piece.low)) continue;
      piece.side = orientation > 0.0 ? Side::Front : Side::Back;
      push(piece);
    }
    std::sort(events_.begin(), events_.end(), [](const Event& p, const Event& q) {
      if (p.key != q.key) return p.key < q.key;
      return p.piece < q.piece;
    });
    active_.clear();
    std::size_t i = 0;
    while (i < events_.size()) {
      const double key = events_[i].key;
      for (; i < events_.size() && events_[i].key == key; ++i) {
        if (events_[i].start) {
          active_.push_back(events_[i].piece);
        } else {
          const auto it = std::find(active_.begin(), active_.end(), events_[i].piece);
          *it = active_.back();
          active_.pop_back();
        }
      }
      if (i == events_.size() || active_.empty()) continue;
      const double next = events_[i].key;
      // Middle direction of the gap, in (depth, lateral) coordinates.
      const double s = 0.5 * (key + next);
      const Vec2 d{std::sqrt(std::max(0.0, 1.0 - s * s)), s};
      std::uint32_t nearest = kNoElement;
      double nearest_distance = INFINITY;
      for (const std::uint32_t k : active_) {
        const Piece& piece = pieces_[k];
        double r = 0.0;
        if (!piece.attached) {
          // x + r d = a + w (b - a): r = cross(a, b - a) / cross(d, b - a) (x is the origin).
          const Vec2 edge = piece.b - piece.a;
          r = cross(piece.a, edge) / cross(d, edge);
        }
        if (r < nearest_distance || (r == nearest_distance && k < nearest)) {
          nearest_distance = r;
          nearest = k;
        }
      }
      pieces_[nearest].seen += 0.5 * (next - key);
    }
    // Sum per (element, side); pieces come in increasing element order.
    for (const Piece& piece : pieces_) {
      if (!(piece.seen > 0.0)) continue;
      if (!out.empty() && out.back().element == piece.element && out.back().side == piece.side) {
        out.back().form_factor += piece.seen;
        out.back().whole = false;
      } else {
        const double full = 0.5 * (piece.high - piece.low);
        out.push_back({piece.element, piece.side, piece.seen,
                       !piece.attached && !piece.clipped && std::fabs(piece.seen - full) <= 1e-12});
      }
    }
  }

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
  void push(const Piece& piece) {
    const auto index = static_cast<std::uint32_t>(pieces_.size());
    pieces_.push_back(piece);
    events_.push_back({piece.low, index, true});
    events_.push_back({piece.high, index, false});
  }
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
                Vec2 normal, std::uint32_t j, Side side_j) {
    const Vec2 lateral_axis{normal.y, -normal.x};
    Span target;
    const ReferenceElement& e = elements[j];
    const double orientation = cross(e.a - x, e.b - x);
    if (std::fabs(orientation) <= 1e-12 * length(e.a - x) * length(e.b - x)) return 0.0;
    if ((orientation > 0.0 ? Side::Front : Side::Back) != side_j) return 0.0;
    if (!span_of(e, x, normal, lateral_axis, target)) return 0.0;
    hidden_.clear();
    for (const std::uint32_t k : occluders) {
      Span occluder;
      if (!span_of(elements[k], x, normal, lateral_axis, occluder)) continue;
      const double low = std::max(target.low, occluder.low);
      const double high = std::min(target.high, occluder.high);
      if (!(high > low)) continue;
      const double s = 0.5 * (low + high);
      const Vec2 d{std::sqrt(std::max(0.0, 1.0 - s * s)), s};
      // x + r d = a + w (b - a): r = cross(a, b - a) / cross(d, b - a) (x is the origin).
      auto distance = [d](const Span& span) {
        const Vec2 edge = span.b - span.a;
        return cross(span.a, edge) / cross(d, edge);
      };
      if (distance(occluder) < distance(target)) hidden_.emplace_back(low, high);
    }
    double hidden = 0.0;
    if (!hidden_.empty()) {
      std::sort(hidden_.begin(), hidden_.end());
      double low = hidden_[0].first;
      double high = hidden_[0].second;
      for (std::size_t k = 1; k < hidden_.size(); ++k) {
        if (hidden_[k].first > high) {
          hidden += high - low;
          low = hidden_[k].first;
        }
        high = std::max(high, hidden_[k].second);
      }
      hidden += high - low;
    }
    return 0.5 * std::max(0.0, target.high - target.low - hidden);
  }

 private:
  struct Span {
    Vec2 a;  // (depth, lateral) of the element's ends relative to x
    Vec2 b;
    double low = 0.0;
    double high = 0.0;
  };
  // The sin(theta) interval of an element seen from x, clipped to the half-plane in front of x;
  // false when it lies behind, or edge-on.
  static bool span_of(const ReferenceElement& e, Vec2 x, Vec2 normal, Vec2 lateral_axis, Span& span) {
    const Vec2 ra = e.a - x;
    const Vec2 rb = e.b - x;
    span.a = {dot(ra, normal), dot(ra, lateral_axis)};
    span.b = {dot(rb, normal), dot(rb, lateral_axis)};
    if (span.a.x <= 0.0 && span.b.x <= 0.0) return false;
    const double la = length(ra);
    const double lb = length(rb);
    if (!(la > 0.0) || !(lb > 0.0)) return false;
    if (std::fabs(cross(ra, rb)) <= 1e-12 * la * lb) return false;
    auto key_of = [](Vec2 p, Vec2 q, double length_p) {
      if (p.x >= 0.0) return p.y / length_p;
      const double s = p.x / (p.x - q.x);
      return p.y + s * (q.y - p.y) > 0.0 ? 1.0 : -1.0;
    };
    const double ka = key_of(span.a, span.b, la);
    const double kb = key_of(span.b, span.a, lb);
    span.low = std::min(ka, kb);
    span.high = std::max(ka, kb);
    return span.high > span.low;
  }
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
                 const std::vector<double>& weights)
      : elements_(elements), nodes_(nodes), weights_(weights) {
    bounds_.reserve(elements.size());
    for (const ReferenceElement& e : elements)
      bounds_.push_back(
          {std::min(e.a.x, e.b.x), std::min(e.a.y, e.b.y), std::max(e.a.x, e.b.x), std::max(e.a.y, e.b.y)});
  }

  // (1/L_i) integral over element i of F(x -> j, side_j), x on the chord, normal of side_i.
  double form_factor(std::uint32_t i, Side side_i, std::uint32_t j, Side side_j, bool split = true) {
    const ReferenceElement& ei = elements_[i];
    const ReferenceElement& ej = elements_[j];
    const Vec2 normal = side_i == Side::Front ? ei.normal : -ei.normal;
    find_occluders(i, j);
    breaks_.assign({0.0, 1.0});
    if (split) add_events(ei, ej);
    double sum = 0.0;
    for (std::size_t piece = 0; piece + 1 < breaks_.size(); ++piece) {
      const double t0 = breaks_[piece];
      const double width = breaks_[piece + 1] - t0;
      for (std::size_t q = 0; q < nodes_.size(); ++q) {
        const Vec2 x = lerp(ei.a, ei.b, t0 + width * nodes_[q]);
        sum += width * weights_[q] * visibility_.factor(elements_, occluders_, x, normal, j, side_j);
      }
    }
    return sum;
  }
  std::size_t pieces() const { return breaks_.size() - 1; }

 private:
  struct Box {
    double min_x, min_y, max_x, max_y;
  };

  // Elements (other than i and j) that meet the convex hull of i and j: bounding boxes first, then
  // separating axes (the hull's edges and the element's line).
  void find_occluders(std::uint32_t i, std::uint32_t j) {
    occluders_.clear();
    const ReferenceElement& ei = elements_[i];
    const ReferenceElement& ej = elements_[j];
    convex_hull({ei.a, ei.b, ej.a, ej.b});
    const Box box{std::min({ei.a.x, ei.b.x, ej.a.x, ej.b.x}), std::min({ei.a.y, ei.b.y, ej.a.y, ej.b.y}),
                  std::max({ei.a.x, ei.b.x, ej.a.x, ej.b.x}), std::max({ei.a.y, ei.b.y, ej.a.y, ej.b.y})};
    for (std::uint32_t k = 0; k < bounds_.size(); ++k) {
      const Box& b = bounds_[k];
      if (b.min_x > box.max_x || b.max_x < box.min_x || b.min_y > box.max_y || b.max_y < box.min_y) continue;
      if (k == i || k == j) continue;
      if (meets_hull(elements_[k].a, elements_[k].b)) occluders_.push_back(k);
    }
  }

  // Counter-clockwise convex hull of four points (Andrew's monotone chain), into hull_.
  void convex_hull(std::array<Vec2, 4> points) {
    std::sort(points.begin(), points.end(), [](Vec2 p, Vec2 q) { return p.x < q.x || (p.x == q.x && p.y < q.y); });
    hull_.clear();
    for (int pass = 0; pass < 2; ++pass) {
      const std::size_t start = hull_.size();
      for (int k = 0; k < 4; ++k) {
        const Vec2 p = points[static_cast<std::size_t>(pass == 0 ? k : 3 - k)];
        while (hull_.size() >= start + 2 &&
               cross(hull_[hull_.size() - 1] - hull_[hull_.size() - 2], p - hull_[hull_.size() - 2]) <= 0.0)
          hull_.pop_back();
        hull_.push_back(p);
      }
      hull_.pop_back();
    }
  }

  // Whether the closed hull meets segment (a, b): no hull edge has both points strictly outside,
  // and the segment's line does not have the whole hull strictly on one side.
  bool meets_hull(Vec2 a, Vec2 b) const {
    const std::size_t n = hull_.size();
    if (n < 3) return true;  // degenerate hull (collinear pair): keep the element, to be safe
    for (std::size_t k = 0; k < n; ++k) {
      const Vec2 p = hull_[k];
      const Vec2 edge = hull_[(k + 1) % n] - p;
      if (cross(edge, a - p) < 0.0 && cross(edge, b - p) < 0.0) return false;
    }
    int above = 0;
    int below = 0;
    for (const Vec2 p : hull_) {
      const double side = cross(b - a, p - a);
      above += side > 0.0 ? 1 : 0;
      below += side < 0.0 ? 1 : 0;
    }
    return above != static_cast<int>(n) && below != static_cast<int>(n);
  }

  bool inside_hull(Vec2 p) const {
    const std::size_t n = hull_.size();
    if (n < 3) return true;
    for (std::size_t k = 0; k < n; ++k)
      if (cross(hull_[(k + 1) % n] - hull_[k], p - hull_[k]) < 0.0) return false;
    return true;
  }

  // The parameters on element i where x crosses a line through two bounding points, sorted, with
  // 0 and 1; pieces shorter than 1e-9 of the element are merged.
  void add_events(const ReferenceElement& ei, const ReferenceElement& ej) {
    points_.clear();
    points_.push_back({ej.a});
    points_.push_back({ej.b});
    for (const std::uint32_t k : occluders_) {
      const ReferenceElement& e = elements_[k];
      // Each chain vertex once: the element that starts there adds it, unless its predecessor is
      // not an occluder here.
      for (int end = 0; end < 2; ++end) {
        const Vec2 v = end == 0 ? e.a : e.b;
        const std::uint32_t neighbour = end == 0 ? e.previous : e.next;
        if (end == 1 && neighbour != kNoElement && std::binary_search(occluders_.begin(), occluders_.end(), neighbour))
          continue;  // the neighbour adds it as its start
        if (v == ej.a || v == ej.b || !inside_hull(v)) continue;
        const Vec2 other = end == 0 ? e.b : e.a;
        Vec2 across = other;
        bool chained = false;
        if (neighbour != kNoElement) {
          const ReferenceElement& n = elements_[neighbour];
          across = end == 0 ? n.a : n.b;
          chained = true;
        }
        points_.push_back({v, other, across, chained, true});
      }
    }
    const double scale = ei.length;
    const Vec2 edge = ei.b - ei.a;
    for (std::size_t p = 0; p < points_.size(); ++p) {
      for (std::size_t q = p + 1; q < points_.size(); ++q) {
        const Vec2 d = points_[q].position - points_[p].position;
        if (!(length_squared(d) > 1e-24 * scale * scale)) continue;
        if (!points_[p].touches(d) || !points_[q].touches(d)) continue;
        // x = a_i + t edge on the line through p with direction d: cross(x - p, d) = 0.
        const double denominator = cross(edge, d);
        if (denominator == 0.0) continue;
        const double t = cross(points_[p].position - ei.a, d) / denominator;
        if (t > 1e-9 && t < 1.0 - 1e-9) breaks_.push_back(t);
      }
    }
    std::sort(breaks_.begin(), breaks_.end());
    std::size_t kept = 1;
    for (std::size_t k = 1; k < breaks_.size(); ++k) {
      if (breaks_[k] - breaks_[kept - 1] < 1e-9) continue;
      breaks_[kept++] = breaks_[k];
    }
    breaks_.resize(kept);
    breaks_.back() = 1.0;
  }

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

// Whether element j lies wholly in the closed half-plane in front of `side` of element i.
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

ReferenceElement chord_element(Vec2 a, Vec2 b) {
  ReferenceElement e;
  e.a = a;
  e.b = b;
  e.length = length(b - a);
  e.normal = (1.0 / e.length) * perp(b - a);
  return e;
}

Vec2 mirrored_point(Vec2 p, const ReferenceMirror& mirror) {
  return p - (2.0 * dot(p - mirror.origin, mirror.normal)) * mirror.normal;
}

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

bool in_front_of(const ReferenceElement& i, Side side, const ReferenceElement& j) {
  const Vec2 n = side == Side::Front ? i.normal : -i.normal;
  const double tolerance = 1e-12 * (i.length + j.length);
  return dot(j.a - i.a, n) >= -tolerance && dot(j.b - i.a, n) >= -tolerance;
}

unsigned thread_count(unsigned requested) {
  if (requested != 0) return requested;
  return std::max(1u, std::thread::hardware_concurrency());
}

double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

// Restarted GMRES (Saad and Schultz 1986) for A x = rhs, x holding the first guess. Each cycle
// builds an orthonormal Krylov basis v_0 = r / |r|, v_(j+1) ~ A v_j - sum_i h_ij v_i (modified
// Gram-Schmidt, done twice: the radiosity matrix is close to the identity, so one pass loses
// orthogonality once the residual is small), turns the Hessenberg matrix h upper triangular with
// Givens rotations and minimises |r|_2 over x + span(v). A cycle ends after `kRestart` steps or
// when the rotated right-hand side says |r|_2 <= threshold; the true residual is then recomputed.
// Stops when |r|_inf <= threshold * |x|_inf (|r|_inf <= |r|_2), after max_iterations steps, or
// when a whole cycle fails to halve the true residual (the round-off floor).
//
// Why not Gauss-Seidel: its error shrinks by about rho per sweep in a closed scene (10^4 sweeps at
// rho = 0.999), while the spectrum of F (similar to a symmetric matrix by reciprocity) has few
// eigenvalues near 1, which Krylov methods remove in a few steps each.
struct KrylovOutcome {
  int iterations = 0;
  double relative_residual = 0.0;  // |r|_inf / |x|_inf at the end
  bool cancelled = false;
};

template <class Apply>
KrylovOutcome gmres(const Apply& apply, const std::vector<double>& rhs, std::vector<double>& x, double threshold,
                    int max_iterations, const std::atomic<bool>* cancel) {
  constexpr int kRestart = 60;
  const std::size_t n = rhs.size();
  KrylovOutcome outcome;
  auto dot_product = [n](const std::vector<double>& a, const std::vector<double>& b) {
    double sum = 0.0;
    for (std::size_t i = 0; i < n; ++i) sum += a[i] * b[i];
    return sum;
  };
  auto inf_norm = [](const std::vector<double>& a) {
    double largest = 0.0;
    for (const double value : a) largest = std::max(largest, std::fabs(value));
    return largest;
  };
  std::vector<double> r(n);
  std::vector<double> w(n);
  auto residual = [&]() {
    apply(x, w);
    for (std::size_t i = 0; i < n; ++i) r[i] = rhs[i] - w[i];
  };
  std::vector<std::vector<double>> basis(kRestart + 1, std::vector<double>(n));
  std::vector<std::vector<double>> h(kRestart + 1, std::vector<double>(kRestart, 0.0));
  std::vector<double> cosines(kRestart);
  std::vector<double> sines(kRestart);
  std::vector<double> g(kRestart + 1);
  residual();
  double previous = INFINITY;
  for (;;) {
    const double scale = inf_norm(x);
    const double r_inf = inf_norm(r);
    outcome.relative_residual = scale > 0.0 ? r_inf / scale : 0.0;
    if (r_inf <= threshold * scale || outcome.iterations >= max_iterations || !(r_inf < 0.5 * previous)) break;
    previous = r_inf;
    const double target = threshold * scale;
    const double beta = std::sqrt(dot_product(r, r));
    for (std::size_t i = 0; i < n; ++i) basis[0][i] = r[i] / beta;
    std::fill(g.begin(), g.end(), 0.0);
    g[0] = beta;
    int steps = 0;
    for (int j = 0; j < kRestart && outcome.iterations < max_iterations; ++j) {
      if (cancel != nullptr && cancel->load(std::memory_order_relaxed)) {
        outcome.cancelled = true;
        return outcome;
      }
      apply(basis[static_cast<std::size_t>(j)], w);
      ++outcome.iterations;
      const auto jj = static_cast<std::size_t>(j);
      for (std::size_t i = 0; i <= jj; ++i) h[i][jj] = 0.0;
      for (int pass = 0; pass < 2; ++pass)
        for (std::size_t i = 0; i <= jj; ++i) {
          const double projection = dot_product(w, basis[i]);
          h[i][jj] += projection;
          for (std::size_t k = 0; k < n; ++k) w[k] -= projection * basis[i][k];
        }
      const double norm = std::sqrt(dot_product(w, w));
      // Earlier rotations, then a new one that zeroes h[j+1][j].
      for (std::size_t i = 0; i < jj; ++i) {
        const double upper = cosines[i] * h[i][jj] + sines[i] * h[i + 1][jj];
        h[i + 1][jj] = -sines[i] * h[i][jj] + cosines[i] * h[i + 1][jj];
        h[i][jj] = upper;
      }
      const double radius = std::hypot(h[jj][jj], norm);
      cosines[jj] = radius > 0.0 ? h[jj][jj] / radius : 1.0;
      sines[jj] = radius > 0.0 ? norm / radius : 0.0;
      h[jj][jj] = radius;
      g[jj + 1] = -sines[jj] * g[jj];
      g[jj] = cosines[jj] * g[jj];
      steps = j + 1;
      if (std::fabs(g[jj + 1]) <= target || !(norm > 0.0)) break;  // converged, or exact
      for (std::size_t k = 0; k < n; ++k) basis[jj + 1][k] = w[k] / norm;
    }
    // x += V y with h y = g (upper triangular, back substitution).
    std::vector<double> y(static_cast<std::size_t>(steps), 0.0);
    for (int i = steps - 1; i >= 0; --i) {
      const auto ii = static_cast<std::size_t>(i);
      double sum = g[ii];
      for (std::size_t k = ii + 1; k < static_cast<std::size_t>(steps); ++k) sum -= h[ii][k] * y[k];
      y[ii] = h[ii][ii] != 0.0 ? sum / h[ii][ii] : 0.0;
    }
    for (std::size_t i = 0; i < y.size(); ++i)
      for (std::size_t k = 0; k < n; ++k) x[k] += y[i] * basis[i][k];
    residual();
  }
  return outcome;
}

// Element boundaries of every segment, as arc lengths from its start: the segment is cut at the
// contacts that lie inside it (find_contacts: another curve's end point or corner on it, or a
// crossing), where light on the two sides is unrelated, and each piece between cuts is divided
// into equal arc-length chords no longer than max_length. Without the cuts a constant element
// straddling a contact averages the two sides and re-emits the lit side's light on the dark side
// (a leak of about its length times B): the reference then changes by about the same amount at
// every halving of h, as much where the contact's position inside the element moves.
std::vector<std::vector<double>> element_boundaries(const Scene& scene, double max_length) {
  std::vector<std::vector<double>> cuts(scene.segments.size());
  for (const DiscontinuityNode& node : find_contacts(scene)) {
    const Curve& curve = scene.curves[node.curve];
    const double local = std::clamp(std::floor(node.u), 0.0, static_cast<double>(curve.segment_count) - 1.0);
    const double t = node.u - local;
    if (!(t > 1e-9 && t < 1.0 - 1e-9)) continue;  // at a joint: already a boundary
    const SceneSegment& segment = scene.segments[curve.first_segment + static_cast<std::uint32_t>(local)];
    cuts[curve.first_segment + static_cast<std::uint32_t>(local)].push_back(
        segment.arc_length.length_at(segment.geometry.shape, t));
  }
  std::vector<std::vector<double>> boundaries(scene.segments.size());
  for (std::size_t si = 0; si < scene.segments.size(); ++si) {
    const double total = scene.segments[si].length;
    std::vector<double>& cut = cuts[si];
    cut.push_back(total);
    std::sort(cut.begin(), cut.end());
    std::vector<double>& b = boundaries[si];
    b.push_back(0.0);
    for (const double end : cut) {
      const double start = b.back();
      if (!(end - start > 1e-9 * total)) continue;
      const double pieces = std::max(1.0, std::ceil((end - start) / max_length));
      if (pieces > 1e8) {  // far beyond kMaxReferenceElements: marked, never built
        b.push_back(std::numeric_limits<double>::infinity());
        return boundaries;
      }
      for (double k = 1.0; k < pieces; ++k) b.push_back(start + (end - start) * k / pieces);
      b.push_back(end);
    }
    b.back() = total;
  }
  return boundaries;
}

}  // namespace

Status validate(const ReferenceSettings& settings) {
  if (!std::isfinite(settings.max_element_length) || settings.max_element_length < 0.0)
    return Error{"max element length: must be a finite length >= 0 (0: scene scale / 400)"};
  if (settings.quadrature < 1 || settings.quadrature > 64)
    return Error{"quadrature: must be between 1 and 64 points per element"};
  if (!std::isfinite(settings.tolerance) || settings.tolerance <= 0.0 || settings.tolerance >= 1.0)
    return Error{"tolerance: must be a number in (0, 1), e.g. 1e-12"};
  if (settings.max_iterations < 1) return Error{"max iterations: must be at least 1"};
  if (settings.threads > 1024) return Error{"threads: at most 1024 (0 uses every core)"};
  return ok_status();
}

std::vector<VisibleElement> visible_elements(const std::vector<ReferenceElement>& elements, Vec2 x, Vec2 normal,
                                             std::uint32_t self) {
  Sweeper sweeper;
  std::vector<VisibleElement> out;
  Side side = Side::Front;
  if (self != kNoElement && dot(normal, elements[self].normal) < 0.0) side = Side::Back;
  sweeper.run(elements, x, normal, self, side, out);
  return out;
}

double pair_form_factor(const std::vector<ReferenceElement>& elements, std::uint32_t i, Side si, std::uint32_t j,
                        Side sj, int points, bool split, std::size_t* pieces) {
  std::vector<double> nodes;
  std::vector<double> weights;
  gauss::legendre_unit_rule(points, nodes, weights);
  PairQuadrature quadrature(elements, nodes, weights);
  const double f = quadrature.form_factor(i, si, j, sj, split);
  if (pieces != nullptr) *pieces = quadrature.pieces();
  return f;
}

double crossed_strings(Vec2 a1, Vec2 b1, Vec2 a2, Vec2 b2) {
  // Of the two pairings of the ends, the crossed one (the diagonals of the convex quadrilateral
  // the two segments span) is the longer; with a shared end point it degenerates to
  // (L1 + L2 - |far ends|) / (2 L1).
  const double pairing_one = length(a1 - a2) + length(b1 - b2);
  const double pairing_two = length(a1 - b2) + length(b1 - a2);
  return std::fabs(pairing_one - pairing_two) / (2.0 * length(b1 - a1));
}

Spectrum ReferenceSolution::element_radiosity(std::uint32_t element, Side side) const {
  Spectrum b{0.0, 0.0, 0.0};
  for (int c = 0; c < scene_.channels; ++c)
    b[static_cast<std::size_t>(c)] = radiosity_[static_cast<std::size_t>(c)][patch_index(element, side)];
  return b;
}

double ReferenceSolution::form_factor(std::uint32_t i, Side si, std::uint32_t j, Side sj) const {
  const std::uint32_t row = patch_row_[patch_index(i, si)];
  if (row == kNoElement) return 0.0;
  const auto target = static_cast<std::uint32_t>(patch_index(j, sj));
  const auto begin = column_.begin() + static_cast<std::ptrdiff_t>(row_begin_[row]);
  const auto end = column_.begin() + static_cast<std::ptrdiff_t>(row_begin_[row + 1]);
  const auto it = std::lower_bound(begin, end, target);
  if (it == end || *it != target) return 0.0;
  return value_[static_cast<std::size_t>(it - column_.begin())];
}

double ReferenceSolution::row_sum(std::uint32_t i, Side si) const {
  const std::uint32_t row = patch_row_[patch_index(i, si)];
  return row == kNoElement ? -1.0 : row_sums_[row];
}

Spectrum ReferenceSolution::radiosity(std::uint32_t curve_index, Side side, double u) const {
  Spectrum result{0.0, 0.0, 0.0};
  const Curve& curve = scene_.curves[curve_index];
  if (!curve.has_side(side)) return result;
  const double clamped = std::clamp(u, 0.0, static_cast<double>(curve.segment_count));
  const auto local =
      static_cast<std::uint32_t>(std::min(std::floor(clamped), static_cast<double>(curve.segment_count) - 1.0));
  const double t = clamped - local;
  const std::uint32_t segment_index = curve.first_segment + local;
  const SceneSegment& segment = scene_.segments[segment_index];
  const Material& material = scene_.material_of(curve);
  const double factor = emittance_factor(curve, local + t);
  for (int c = 0; c < scene_.channels; ++c) {
    const auto k = static_cast<std::size_t>(c);
    result[k] = curve.emittance[k] * factor;
  }
  if (!any_positive(material.reflectivity, scene_.channels)) return result;

  // The element that holds the point: the last whose start is at or before it.
  const std::uint32_t pieces = segment_count_[segment_index];
  const double s = segment.arc_length.length_at(segment.geometry.shape, t);
  const auto first = boundary_.begin() + static_cast<std::ptrdiff_t>(segment_first_[segment_index] + segment_index);
  const auto found = std::upper_bound(first, first + pieces, s);
  const auto piece = static_cast<std::uint32_t>(std::clamp<std::ptrdiff_t>(found - first - 1, 0, pieces - 1));
  const std::uint32_t self = segment_first_[segment_index] + piece;

  const Vec2 x = evaluate(segment.geometry.shape, t);
  Vec2 normal = unit_normal(segment.geometry.shape, t, scene_.scale);
  if (side == Side::Back) normal = -normal;
  Sweeper sweeper;
  std::vector<VisibleElement> visible;
  sweeper.run(elements_, x, normal, self, side, visible);
  // (element side, F) seen directly and by the mirrors.
  std::vector<std::pair<std::size_t, double>> seen;
  for (const VisibleElement& v : visible) seen.emplace_back(patch_index(v.element, v.side), v.form_factor);
  std::vector<VisibleElement> scratch;
  for (const ReferenceMirror& mirror : mirrors_)
    gather_by_mirror(sweeper, mirror, x, normal, self, side, 1e-12 * scene_.scale, scratch,
                     [&](std::uint32_t j, Side side_j, double f) { seen.emplace_back(patch_index(j, side_j), f); });
  for (int c = 0; c < scene_.channels; ++c) {
    const auto k = static_cast<std::size_t>(c);
    double gathered = 0.0;
    for (const auto& [p, f] : seen) gathered += f * radiosity_[k][p];
    result[k] += material.reflectivity[k] * gathered;
  }
  return result;
}

double reference_element_count(const Scene& scene, const ReferenceSettings& settings) {
  const double max_length = settings.max_element_length > 0.0 ? settings.max_element_length : scene.scale / 400.0;
  double count = 0.0;
  for (const std::vector<double>& b : element_boundaries(scene, max_length)) {
    if (!std::isfinite(b.back())) return INFINITY;
    count += static_cast<double>(b.size() - 1);
  }
  return count;
}

// solve_reference's steps, each a method; a friend of ReferenceSolution, whose members it fills.
class ReferenceBuilder {
 public:
  ReferenceBuilder(const Scene& scene, const ReferenceSettings& settings, ReferenceSolution& solution)
      : scene_(scene),
        settings_(settings),
        solution_(solution),
        elements_(solution.elements_),
        memory_limit_(settings.memory_limit != 0 ? settings.memory_limit : default_memory_budget()) {}

  // Refuses what the reference cannot solve (non-diffuse emitters) or cannot finish (too many
  // elements, by their count alone), before any work is done.
  Status check() const;
  // Refuses scenes where light can meet two flat mirrors in a row (one reflection is followed).
  Status check_single_reflections() const;
  // 1. Elements: the chords of every segment, equal in arc length between contacts.
  Status build_elements();
  // Mirrors: every reflecting side of every flat mirror segment, its view of the elements.
  void build_mirrors();
  // Chain neighbours: consecutive elements of a curve that share an end point exactly (joints
  // share their control point), and the last and first of a closed curve.
  void link_neighbours();
  // Patches (element sides) that carry radiosity (reflect or emit) and those that need a row of
  // F (reflect).
  void number_patches();
  // 2-3. The rows of F, by quadrature over the element, with crossed strings where the pair sees
  // each other whole from every quadrature point and each lies in front of the other; then in
  // compressed rows.
  Status form_factors();
  // 4. Per channel, (I - diag(rho) F) b = e by restarted GMRES, starting from b = e.
  Status solve_channels();

 private:
  bool cancelled() const { return settings_.cancel != nullptr && settings_.cancel->load(std::memory_order_relaxed); }
  // A mirror the reference follows: every segment straight, no roughness, one reflectance for
  // every channel.
  bool is_flat_grey_mirror(const Curve& curve) const {
    const Material& material = scene_.material_of(curve);
    if (material.roughness > 0.0) return false;
    for (int c = 1; c < scene_.channels; ++c)
      if (material.reflectance[static_cast<std::size_t>(c)] != material.reflectance[0]) return false;
    for (std::uint32_t k = 0; k < curve.segment_count; ++k)
      if (scene_.segments[curve.first_segment + k].geometry.kind != SegmentKind::Line) return false;
    return true;
  }
  double max_length() const {
    return settings_.max_element_length > 0.0 ? settings_.max_element_length : scene_.scale / 400.0;
  }
  std::size_t patch_count() const { return 2 * elements_.size(); }
  // One worker's share of the rows; `reports` says whether it calls the progress callback.
  void compute_rows(bool reports);
  void compress_rows();

  // Bytes of the rows so far (each entry of a row and of the final CSR copy: a column index and
  // a value); past the memory limit every worker stops.
  static constexpr double kBytesPerEntry = 2.0 * (sizeof(std::uint32_t) + sizeof(double)) + 4.0;

  const Scene& scene_;
  const ReferenceSettings& settings_;
  ReferenceSolution& solution_;
  std::vector<ReferenceElement>& elements_;
  // The bytes the rows may take: fixed before any work (the budget left shrinks as threads start).
  const std::size_t memory_limit_;
  std::vector<char> carries_;  // per patch
  // The rows being computed: shared by the workers, each row written by one.
  std::vector<double> nodes_;
  std::vector<double> weights_;
  std::vector<std::vector<std::pair<std::uint32_t, double>>> row_entries_;
  std::vector<double> row_sums_;
  std::atomic<std::size_t> next_row_{0};
  std::atomic<std::size_t> entry_count_{0};
  std::atomic<bool> out_of_memory_{false};
  std::atomic<std::size_t> rows_done_{0};
};

Status ReferenceBuilder::check() const {
  if (Status status = validate(settings_); !status) return status;
  // Light through specular chains is not in its equations (form factors between diffuse elements),
  // but for one reflection in a flat, smooth, grey mirror (its images, below).
  std::string specular;
  for (const Curve& curve : scene_.curves) {
    const Material& material = scene_.material_of(curve);
    const Optics optics = material.optics;
    if (optics == Optics::Diffuse) continue;
    if (optics == Optics::Mirror && is_flat_grey_mirror(curve)) continue;
    if (!specular.empty()) specular += ", ";
    specular += "'" + curve.id + "' (" +
                (optics == Optics::Mirror       ? "a curved, rough or coloured mirror"
                 : optics == Optics::Dielectric ? "dielectric"
                                                : "detector") +
                ")";
  }
  if (!specular.empty())
    return Error{scene_.source + ": the reference solver handles diffuse surfaces and flat mirrors only, and curves " +
                 specular +
                 " are not; use a solve with many more photons as the reference (flatland solve --out REF.json, then "
                 "compare or converge --reference REF.json)"};
  if (Status status = check_single_reflections(); !status) return status;
  for (const Curve& curve : scene_.curves) {
    if (scene_.is_emitter(curve) && scene_.material_of(curve).emission.kind != Emission::Kind::Diffuse)
      return Error{scene_.source + ": curve '" + curve.id + "': the reference solver supports diffuse emitters only"};
  }
  const double element_total = reference_element_count(scene_, settings_);
  if (element_total > static_cast<double>(kMaxReferenceElements)) {
    char message[320];
    std::snprintf(message, sizeof message,
                  "%.4g reference elements (elements of length %.3g); at most %zu: form factors "
                  "take time and memory growing as the square of the count; use fewer elements "
                  "(--elements or --max-element-length)",
                  element_total, max_length(), kMaxReferenceElements);
    return Error{message};
  }
  return ok_status();
}

// Light reaches a second mirror after the first only if the two reflecting sides face each other:
// part of B lies strictly in front of A's reflecting side and part of A strictly in front of B's.
// Where no such pair exists, every path from a diffuse point to a diffuse point meets at most one
// mirror (a path that leaves mirror A toward mirror B needs B in front of A, and to be reflected
// by B it must arrive on B's reflecting side, which needs A in front of B), so one image per
// mirror is the whole of the specular light. Where one exists, the reference refuses the scene
// rather than report an error estimate that does not bound its error. The test ignores occluders
// between the two (conservative: such a pair is refused even if walls hide them from each other).
Status ReferenceBuilder::check_single_reflections() const {
  struct MirrorSide {
    Vec2 a, b, normal;
    std::uint32_t curve;
  };
  std::vector<MirrorSide> sides;
  for (const SceneSegment& segment : scene_.segments) {
    const Curve& curve = scene_.curves[segment.curve];
    if (scene_.material_of(curve).optics != Optics::Mirror) continue;
    const Vec2 a = segment.geometry.shape.p[0], b = segment.geometry.shape.p[3];
    const Vec2 front = normalized(perp(b - a));
    for (const Side side : {Side::Front, Side::Back})
      if (curve.has_side(side)) sides.push_back({a, b, side == Side::Front ? front : -front, segment.curve});
  }
  const double touch = 1e-9 * scene_.scale;
  const auto in_front = [&](const MirrorSide& of, const MirrorSide& other) {
    return dot(other.a - of.a, of.normal) > touch || dot(other.b - of.a, of.normal) > touch;
  };
  for (std::size_t i = 0; i < sides.size(); ++i) {
    if (cancelled()) return Error{kReferenceCancelled};
    for (std::size_t j = i + 1; j < sides.size(); ++j) {
      if (!in_front(sides[i], sides[j]) || !in_front(sides[j], sides[i])) continue;
      const std::string& first = scene_.curves[sides[i].curve].id;
      const std::string& second = scene_.curves[sides[j].curve].id;
      return Error{scene_.source + ": " +
                   (first == second ? "mirror '" + first + "' faces itself (two of its segments face each other)"
                                    : "mirrors '" + first + "' and '" + second + "' face each other") +
                   ": light reflected by one reaches the other, and the reference solver follows one reflection; use "
                   "a solve with many more photons as the reference (flatland solve --out REF.json, then compare or "
                   "converge --reference REF.json)"};
    }
  }
  return ok_status();
}

Status ReferenceBuilder::build_elements() {
  const std::vector<std::vector<double>> boundaries = element_boundaries(scene_, max_length());
  solution_.segment_first_.assign(scene_.segments.size(), 0);
  solution_.segment_count_.assign(scene_.segments.size(), 0);
  for (std::uint32_t si = 0; si < scene_.segments.size(); ++si) {
    const SceneSegment& segment = scene_.segments[si];
    const Curve& curve = scene_.curves[segment.curve];
    const Material& material = scene_.material_of(curve);
    const Cubic& shape = segment.geometry.shape;
    const std::vector<double>& boundary = boundaries[si];
    const auto pieces = static_cast<std::uint32_t>(boundary.size() - 1);
    solution_.segment_first_[si] = static_cast<std::uint32_t>(elements_.size());
    solution_.segment_count_[si] = pieces;
    // Per segment pieces + 1 boundaries; segment si's start at segment_first_[si] + si.
    solution_.boundary_.insert(solution_.boundary_.end(), boundary.begin(), boundary.end());
    auto point_at = [&](std::uint32_t k) {
      if (k == 0) return shape.p[0];
      if (k == pieces) return shape.p[3];
      return evaluate(shape, segment.arc_length.parameter_at(shape, boundary[k]));
    };
    Vec2 start = point_at(0);
    for (std::uint32_t k = 0; k < pieces; ++k) {
      const Vec2 end = point_at(k + 1);
      ReferenceElement e;
      e.a = start;
      e.b = end;
      e.length = length(end - start);
      if (!(e.length > 0.0)) return Error{scene_.source + ": curve '" + curve.id + "': a chord of zero length"};
      e.normal = (1.0 / e.length) * perp(end - start);
      e.curve = segment.curve;
      e.segment = si;
      e.u_mid = segment.index_in_curve + segment.arc_length.parameter_at(shape, 0.5 * (boundary[k] + boundary[k + 1]));
      const double factor = emittance_factor(curve, e.u_mid);
      for (const Side side : {Side::Front, Side::Back}) {
        if (!curve.has_side(side)) continue;
        const auto sd = static_cast<std::size_t>(side);
        for (int c = 0; c < scene_.channels; ++c) {
          const auto ch = static_cast<std::size_t>(c);
          e.reflectivity[sd][ch] = material.reflectivity[ch];
          e.emittance[sd][ch] = curve.emittance[ch] * factor;
        }
      }
      elements_.push_back(e);
      start = end;
    }
  }
  return ok_status();
}

void ReferenceBuilder::build_mirrors() {
  const double touch = 1e-12 * scene_.scale;
  for (std::uint32_t si = 0; si < scene_.segments.size(); ++si) {
    const SceneSegment& segment = scene_.segments[si];
    const Curve& curve = scene_.curves[segment.curve];
    const Material& material = scene_.material_of(curve);
    if (material.optics != Optics::Mirror) continue;
    const Vec2 p0 = segment.geometry.shape.p[0];
    const Vec2 p1 = segment.geometry.shape.p[3];
    const Vec2 along = normalized(p1 - p0);
    for (const Side side : {Side::Front, Side::Back}) {
      if (!curve.has_side(side)) continue;
      ReferenceMirror mirror;
      mirror.origin = p0;
      mirror.normal = side == Side::Front ? perp(along) : -perp(along);
      mirror.reflectance = material.reflectance[0];
      mirror.image_of.assign(elements_.size(), kNoElement);
      // The elements in front, clipped at the line (their chain links dropped: they index the
      // scene's elements), then their images, then the blockers.
      for (std::uint32_t j = 0; j < elements_.size(); ++j) {
        const ReferenceElement& e = elements_[j];
        if (e.segment == si) continue;
        const double da = dot(e.a - p0, mirror.normal);
        const double db = dot(e.b - p0, mirror.normal);
        if (da <= touch && db <= touch) continue;
        ReferenceElement clipped = e;
        clipped.previous = kNoElement;
        clipped.next = kNoElement;
        if (da < 0.0 || db < 0.0) {
          const Vec2 cut = e.a + (da / (da - db)) * (e.b - e.a);
          (da < 0.0 ? clipped.a : clipped.b) = cut;
          clipped.length = length(clipped.b - clipped.a);
          if (!(clipped.length > touch)) continue;
        }
        mirror.real.push_back(j);
        mirror.elements.push_back(clipped);
      }
      const std::size_t in_front = mirror.elements.size();
      for (std::size_t k = 0; k < in_front; ++k) {
        const ReferenceElement& e = mirror.elements[k];
        mirror.image_of[mirror.real[k]] = static_cast<std::uint32_t>(mirror.elements.size());
        mirror.elements.push_back(chord_element(mirrored_point(e.b, mirror), mirrored_point(e.a, mirror)));
        mirror.real.push_back(kNoElement);
      }
      const double far = 10.0 * scene_.scale + length(p1 - p0);
      mirror.elements.push_back(chord_element(p0 - far * along, p0));
      mirror.elements.push_back(chord_element(p1, p1 + far * along));
      mirror.real.push_back(kNoElement);
      mirror.real.push_back(kNoElement);
      solution_.mirrors_.push_back(std::move(mirror));
    }
  }
}

void ReferenceBuilder::link_neighbours() {
  const auto element_count = static_cast<std::uint32_t>(elements_.size());
  for (std::uint32_t k = 0; k + 1 < element_count; ++k) {
    if (elements_[k + 1].curve == elements_[k].curve && elements_[k + 1].a == elements_[k].b) {
      elements_[k].next = k + 1;
      elements_[k + 1].previous = k;
    }
  }
  for (std::uint32_t first = 0; first < element_count;) {
    std::uint32_t last = first;
    while (last + 1 < element_count && elements_[last + 1].curve == elements_[first].curve) ++last;
    if (last != first && elements_[last].b == elements_[first].a) {
      elements_[last].next = first;
      elements_[first].previous = last;
    }
    first = last + 1;
  }
}

void ReferenceBuilder::number_patches() {
  carries_.assign(patch_count(), 0);
  solution_.patch_row_.assign(patch_count(), kNoElement);
  for (std::uint32_t j = 0; j < elements_.size(); ++j) {
    for (const Side side : {Side::Front, Side::Back}) {
      const auto sd = static_cast<std::size_t>(side);
      const bool reflects = any_positive(elements_[j].reflectivity[sd], scene_.channels);
      const bool emits = any_positive(elements_[j].emittance[sd], scene_.channels);
      carries_[patch_index(j, side)] = reflects || emits;
      if (reflects) {
        solution_.patch_row_[patch_index(j, side)] = static_cast<std::uint32_t>(solution_.row_patch_.size());
        solution_.row_patch_.push_back(static_cast<std::uint32_t>(patch_index(j, side)));
      }
    }
  }
}

void ReferenceBuilder::compute_rows(bool reports) {
  const std::size_t rows = solution_.row_patch_.size();
  auto last_report = std::chrono::steady_clock::now();
  Sweeper sweeper;
  PairQuadrature pair_quadrature(elements_, nodes_, weights_);
  std::vector<VisibleElement> visible;
  std::vector<double> accumulated(patch_count(), 0.0);
  std::vector<int> whole_count(patch_count(), 0);
  // Seen directly from some quadrature point; listed in `touched`; F by the mirrors.
  std::vector<char> direct(patch_count(), 0);
  std::vector<char> listed(patch_count(), 0);
  std::vector<double> mirrored(patch_count(), 0.0);
  const double touch = 1e-12 * scene_.scale;
  std::vector<std::uint32_t> touched;
  for (;;) {
    if (cancelled() || out_of_memory_.load(std::memory_order_relaxed)) break;
    const std::size_t row = next_row_.fetch_add(1);
    if (row >= rows) break;
    const std::uint32_t patch = solution_.row_patch_[row];
    const std::uint32_t i = patch / 2;
    const Side side = static_cast<Side>(patch % 2);
    const ReferenceElement& ei = elements_[i];
    const Vec2 normal = side == Side::Front ? ei.normal : -ei.normal;
    touched.clear();
    for (std::size_t q = 0; q < nodes_.size(); ++q) {
      const Vec2 x = lerp(ei.a, ei.b, nodes_[q]);
      sweeper.run(elements_, x, normal, i, side, visible);
      for (const VisibleElement& v : visible) {
        const std::size_t p = patch_index(v.element, v.side);
        if (!listed[p]) touched.push_back(static_cast<std::uint32_t>(p));
        listed[p] = 1;
        direct[p] = 1;
        accumulated[p] += weights_[q] * v.form_factor;
        whole_count[p] += v.whole ? 1 : 0;
      }
      for (const ReferenceMirror& mirror : solution_.mirrors_)
        gather_by_mirror(sweeper, mirror, x, normal, i, side, touch, visible,
                         [&](std::uint32_t j, Side side_j, double f) {
                           const std::size_t p = patch_index(j, side_j);
                           if (!listed[p]) touched.push_back(static_cast<std::uint32_t>(p));
                           listed[p] = 1;
                           mirrored[p] += weights_[q] * f;
                         });
    }
    std::sort(touched.begin(), touched.end());
    auto& entries = row_entries_[row];
    double sum = 0.0;
    for (const std::uint32_t p : touched) {
      double f = 0.0;
      const std::uint32_t j = p / 2;
      const Side side_j = static_cast<Side>(p % 2);
      if (!direct[p]) {
        // Seen by a mirror only.
      } else if (whole_count[p] == settings_.quadrature && in_front_of(ei, side, elements_[j]) &&
                 in_front_of(elements_[j], side_j, ei)) {
        const ReferenceElement& ej = elements_[j];
        f = crossed_strings(ei.a, ei.b, ej.a, ej.b);
      } else {
        // Seen partly (or clipped by i's plane) from some quadrature point: integrate again,
        // split at the visibility events.
        f = pair_quadrature.form_factor(i, side, j, side_j);
      }
      // By the mirrors: the plain quadrature over the element (their images' visibility events are
      // not split at).
      f += mirrored[p];
      accumulated[p] = 0.0;
      whole_count[p] = 0;
      direct[p] = 0;
      listed[p] = 0;
      mirrored[p] = 0.0;
      sum += f;
      if (carries_[p] && f > 0.0) entries.emplace_back(p, f);
    }
    row_sums_[row] = sum;
    const std::size_t total = entry_count_.fetch_add(entries.size()) + entries.size();
    if (static_cast<double>(total) * kBytesPerEntry > static_cast<double>(memory_limit_)) out_of_memory_.store(true);
    const std::size_t done = rows_done_.fetch_add(1) + 1;
    if (reports && settings_.progress && seconds_since(last_report) >= 0.25) {
      last_report = std::chrono::steady_clock::now();
      settings_.progress(done, rows);
    }
  }
}

Status ReferenceBuilder::form_factors() {
  const auto clock_start = std::chrono::steady_clock::now();
  const std::size_t rows = solution_.row_patch_.size();
  gauss::legendre_unit_rule(settings_.quadrature, nodes_, weights_);
  row_entries_.assign(rows, {});
  row_sums_.assign(rows, 0.0);
  {
    const unsigned threads =
        static_cast<unsigned>(std::min<std::size_t>(thread_count(settings_.threads), std::max<std::size_t>(rows, 1)));
    WorkerPool pool(threads);
    solution_.thread_shortfall_ = pool.shortfall();
    pool.run(pool.threads(), [&](unsigned w) { compute_rows(w == 0); });
  }
  if (cancelled()) return Error{kReferenceCancelled};
  if (out_of_memory_.load()) {
    const std::size_t done = std::min(next_row_.load(), rows);
    const double projected = static_cast<double>(entry_count_.load()) * kBytesPerEntry * static_cast<double>(rows) /
                             static_cast<double>(std::max<std::size_t>(done, 1));
    return Error{std::to_string(elements_.size()) + " reference elements: the form factors would need about " +
                 format_bytes(projected) + ", more than the memory limit of " +
                 format_bytes(static_cast<double>(memory_limit_)) +
                 "; use fewer elements (--elements or --max-element-length)"};
  }
  compress_rows();
  solution_.form_factor_seconds_ = seconds_since(clock_start);
  return ok_status();
}

void ReferenceBuilder::compress_rows() {
  const std::size_t rows = row_entries_.size();
  solution_.row_begin_.assign(rows + 1, 0);
  for (std::size_t r = 0; r < rows; ++r) solution_.row_begin_[r + 1] = solution_.row_begin_[r] + row_entries_[r].size();
  solution_.column_.reserve(solution_.row_begin_[rows]);
  solution_.value_.reserve(solution_.row_begin_[rows]);
  for (std::size_t r = 0; r < rows; ++r) {
    for (const auto& [p, f] : row_entries_[r]) {
      solution_.column_.push_back(p);
      solution_.value_.push_back(f);
    }
    std::vector<std::pair<std::uint32_t, double>>().swap(row_entries_[r]);
  }
  solution_.row_sums_ = std::move(row_sums_);
}

// Patches without a row (non-reflecting) are identity rows: they keep b = e.
Status ReferenceBuilder::solve_channels() {
  const auto solve_start = std::chrono::steady_clock::now();
  const std::size_t rows = solution_.row_patch_.size();
  solution_.iterations_ = 0;
  solution_.residual_ = 0.0;
  solution_.error_bound_ = 0.0;
  for (int c = 0; c < scene_.channels; ++c) {
    const auto ch = static_cast<std::size_t>(c);
    std::vector<double> rhs(patch_count(), 0.0);
    std::vector<double> rho(rows, 0.0);
    // The contraction q = max_p rho_p sum_q F_pq bounds ||diag(rho) F||_inf, so
    // ||(I - diag(rho) F)^-1||_inf <= 1 / (1 - q).
    double contraction = 0.0;
    for (std::size_t p = 0; p < patch_count(); ++p) rhs[p] = elements_[p / 2].emittance[p % 2][ch];
    for (std::size_t r = 0; r < rows; ++r) {
      const std::uint32_t p = solution_.row_patch_[r];
      rho[r] = elements_[p / 2].reflectivity[p % 2][ch];
      contraction = std::max(contraction, rho[r] * solution_.row_sums_[r]);
    }
    const double amplification = 1.0 / std::max(1.0 - contraction, 1e-9);
    auto apply = [&](const std::vector<double>& x, std::vector<double>& y) {
      y = x;
      for (std::size_t r = 0; r < rows; ++r) {
        double gathered = 0.0;
        for (std::size_t k = solution_.row_begin_[r]; k < solution_.row_begin_[r + 1]; ++k)
          gathered += solution_.value_[k] * x[solution_.column_[k]];
        y[solution_.row_patch_[r]] -= rho[r] * gathered;
      }
    };
    std::vector<double>& b = solution_.radiosity_[ch];
    b = rhs;
    const KrylovOutcome outcome =
        gmres(apply, rhs, b, settings_.tolerance / amplification, settings_.max_iterations, settings_.cancel);
    if (outcome.cancelled) return Error{kReferenceCancelled};
    solution_.iterations_ = std::max(solution_.iterations_, outcome.iterations);
    solution_.residual_ = std::max(solution_.residual_, outcome.relative_residual);
    solution_.error_bound_ = std::max(solution_.error_bound_, outcome.relative_residual * amplification);
  }
  solution_.solve_seconds_ = seconds_since(solve_start);
  return ok_status();
}

Result<ReferenceSolution> solve_reference(const Scene& scene, const ReferenceSettings& settings) {
  ReferenceSolution solution;
  ReferenceBuilder build(scene, settings, solution);
  if (Status status = build.check(); !status) return status.error();
  solution.scene_ = scene;
  solution.settings_ = settings;
  if (Status status = build.build_elements(); !status) return status.error();
  build.build_mirrors();
  build.link_neighbours();
  build.number_patches();
  if (Status status = build.form_factors(); !status) return status.error();
  if (Status status = build.solve_channels(); !status) return status.error();
  return solution;
}

ReferenceErrorEstimate estimate_from_differences(const ErrorNorms& fine, const ErrorNorms& coarse, double round_off) {
  ReferenceErrorEstimate estimate;
  estimate.fine_difference = fine;
  estimate.coarse_difference = coarse;
  estimate.round_off = round_off;
  estimate.observed_order = NAN;
  estimate.order = NAN;
  char text[240];
  if (!(fine.l2 > round_off)) {
    std::snprintf(text, sizeof text,
                  "R_h and R_2h agree to round-off (%.2g): the reference reproduces this scene at "
                  "every resolution; the estimate is that difference",
                  fine.l2);
    estimate.note = text;
    estimate.error = fine;
    return estimate;
  }
  if (!(coarse.l2 > round_off)) {
    std::snprintf(text, sizeof text,
                  "R_4h and R_2h agree to round-off but R_h differs: no order observed; assumed "
                  "the lowest, %.2g",
                  kMinimumOrder);
    estimate.note = text;
    estimate.order = kMinimumOrder;
  } else {
    estimate.observed_order = std::log2(coarse.l2 / fine.l2);
    estimate.order = std::clamp(estimate.observed_order, kMinimumOrder, kMaximumOrder);
    if (estimate.order != estimate.observed_order) {
      std::snprintf(text, sizeof text, "observed order %.2f clamped to %.2g", estimate.observed_order, estimate.order);
      estimate.note = text;
    }
  }
  const double factor = 1.0 / (std::exp2(estimate.order) - 1.0);
  estimate.error = {factor * fine.l1, factor * fine.l2, factor * fine.linf};
  return estimate;
}

Result<ReferenceErrorEstimate> estimate_discretisation_error(const Scene& scene, const ReferenceSettings& settings,
                                                             int samples, const SampledResult& fine,
                                                             const std::function<void(int level)>& starting) {
  const double length = settings.max_element_length > 0.0 ? settings.max_element_length : scene.scale / 400.0;
  SampledResult previous = fine;
  std::array<ErrorNorms, 2> differences;
  double largest_bound = 0.0;
  for (int level = 1; level <= 2; ++level) {
    if (starting) starting(level);
    ReferenceSettings coarser = settings;
    coarser.max_element_length = std::ldexp(length, level);
    Result<ReferenceSolution> solved = solve_reference(scene, coarser);
    if (!solved) return solved.error();
    const ReferenceSolution& solution = *solved;
    largest_bound = std::max(largest_bound, solution.error_bound());
    SampledResult sampled = sample_radiosity(
        scene, samples, [&solution](std::uint32_t c, Side side, double u) { return solution.radiosity(c, side, u); });
    Result<Comparison> difference = compare_sampled(sampled, previous);
    if (!difference) return difference.error();
    differences[static_cast<std::size_t>(level - 1)] = difference->scene;
    previous = std::move(sampled);
  }
  // Round-off: sums of rounded terms (about 1e-15 relative; 1e-13 leaves room for the many terms
  // of a gather), and the linear solves' own guaranteed error.
  const double round_off = std::max(1e-13, 4.0 * largest_bound);
  return estimate_from_differences(differences[0], differences[1], round_off);
}

}  // namespace flatland
