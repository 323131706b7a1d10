#include "flatland/reference/form_factors.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "flatland/base/quadrature.hpp"

namespace flatland {

namespace reference_detail {

void Sweeper::run(const std::vector<ReferenceElement>& elements, Vec2 x, Vec2 normal, std::uint32_t self,
                  Side self_side, std::vector<VisibleElement>& out) {
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

void Sweeper::push(const Piece& piece) {
  const auto index = static_cast<std::uint32_t>(pieces_.size());
  pieces_.push_back(piece);
  events_.push_back({piece.low, index, true});
  events_.push_back({piece.high, index, false});
}

double PairVisibility::factor(const std::vector<ReferenceElement>& elements,
                              const std::vector<std::uint32_t>& occluders, Vec2 x, Vec2 normal, std::uint32_t j,
                              Side side_j) {
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

bool PairVisibility::span_of(const ReferenceElement& e, Vec2 x, Vec2 normal, Vec2 lateral_axis, Span& span) {
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

PairQuadrature::PairQuadrature(const std::vector<ReferenceElement>& elements, const std::vector<double>& nodes,
                               const std::vector<double>& weights)
    : elements_(elements), nodes_(nodes), weights_(weights) {
  bounds_.reserve(elements.size());
  for (const ReferenceElement& e : elements)
    bounds_.push_back({std::min(e.a.x, e.b.x), std::min(e.a.y, e.b.y), std::max(e.a.x, e.b.x), std::max(e.a.y, e.b.y)});
}

double PairQuadrature::form_factor(std::uint32_t i, Side side_i, std::uint32_t j, Side side_j, bool split) {
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

void PairQuadrature::find_occluders(std::uint32_t i, std::uint32_t j) {
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

void PairQuadrature::convex_hull(std::array<Vec2, 4> points) {
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

bool PairQuadrature::meets_hull(Vec2 a, Vec2 b) const {
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

bool PairQuadrature::inside_hull(Vec2 p) const {
  const std::size_t n = hull_.size();
  if (n < 3) return true;
  for (std::size_t k = 0; k < n; ++k)
    if (cross(hull_[(k + 1) % n] - hull_[k], p - hull_[k]) < 0.0) return false;
  return true;
}

void PairQuadrature::add_events(const ReferenceElement& ei, const ReferenceElement& ej) {
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

Vec2 mirrored_point(Vec2 p, const ReferenceMirror& mirror) {
  return p - (2.0 * dot(p - mirror.origin, mirror.normal)) * mirror.normal;
}

}  // namespace reference_detail

using reference_detail::PairQuadrature;
using reference_detail::Sweeper;

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

ReferenceElement chord_element(Vec2 a, Vec2 b) {
  ReferenceElement e;
  e.a = a;
  e.b = b;
  e.length = length(b - a);
  e.normal = (1.0 / e.length) * perp(b - a);
  return e;
}

}  // namespace flatland
