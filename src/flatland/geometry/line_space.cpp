// A grid over the space of lines (line_space.hpp): its build and its query.
#include "flatland/geometry/line_space.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include "flatland/base/bits.hpp"
#include "flatland/geometry/nearest.hpp"

namespace flatland {
namespace {

constexpr std::ptrdiff_t kShortList = 8;

// The diamond angle of a direction: 0, 1, 2, 3 at +x, +y, -x, -y and monotone in the angle
// between them (the position along the square |x| + |y| = 1), in [0, 4] after rounding. Not a
// direction (zero or not finite): NaN or out of range, which the caller checks.
double diamond_angle(Vec2 d) {
  if (d.y >= 0.0) return d.x >= 0.0 ? d.y / (d.x + d.y) : 1.0 - d.x / (d.y - d.x);
  return d.x < 0.0 ? 2.0 - d.y / (-d.x - d.y) : 3.0 + d.x / (d.x - d.y);
}

// The point of the square |x| + |y| = 1 at diamond angle a in [0, 4].
Vec2 diamond_point(double a) {
  if (a < 1.0) return {1.0 - a, a};
  if (a < 2.0) return {1.0 - a, 2.0 - a};
  if (a < 3.0) return {a - 3.0, 2.0 - a};
  return {a - 3.0, a - 4.0};
}

// The float next to f towards -infinity (+infinity): its bits one step on, as std::nextafter but
// inline (a library call per entry was a tenth of the build). f is finite.
float float_below(float f) {
  if (f == 0.0f) return -std::numeric_limits<float>::denorm_min();
  const auto bits = bit_cast<std::uint32_t>(f);
  return bit_cast<float>(f > 0.0f ? bits - 1 : bits + 1);
}

float float_above(float f) { return -float_below(-f); }

float round_down(double x) {
  const auto f = static_cast<float>(x);
  return static_cast<double>(f) > x ? float_below(f) : f;
}

float round_up(double x) {
  const auto f = static_cast<float>(x);
  return static_cast<double>(f) < x ? float_above(f) : f;
}

struct Interval {
  double lower = std::numeric_limits<double>::infinity();
  double upper = -std::numeric_limits<double>::infinity();
  void add(double lo, double hi) {
    lower = std::min(lower, lo);
    upper = std::max(upper, hi);
  }
};

}  // namespace

LineSpaceCaster::LineSpaceCaster(std::span<const SegmentGeometry> segments, Shape shape)
    : shape_(shape), segments_(segments.begin(), segments.end()) {
  shape_.angle_bins = std::max(shape_.angle_bins, 1);
  shape_.offset_cells = std::max(shape_.offset_cells, 1);
  shape_.cell_limit = std::max(shape_.cell_limit, 1);
  if (segments_.empty()) return;
  // The control points bound every segment (a cubic lies in their hull); a line has only its ends.
  auto for_each_point = [](const SegmentGeometry& g, auto visit) {
    for (int i = 0; i < 4; ++i)
      if (g.kind == SegmentKind::Cubic || i == 0 || i == 3) visit(g.shape.p[i]);
  };
  Box box;
  for (const SegmentGeometry& g : segments_) for_each_point(g, [&box](Vec2 p) { box.extend(p); });
  centre_ = 0.5 * (box.lower + box.upper);
  for (const SegmentGeometry& g : segments_)
    for_each_point(g, [this](Vec2 p) { radius_ = std::max(radius_, length(p - centre_)); });
  if (!(radius_ > 0.0) || !std::isfinite(radius_)) return;
  // Relative to the scene's size and its distance from the origin: the rounding of a hit's
  // distance (world coordinates) and of the bounds below are both far smaller.
  pad_ = 1e-9 * (radius_ + std::max(std::fabs(centre_.x), std::fabs(centre_.y)));
  const int bins = shape_.angle_bins;
  const int cells = shape_.offset_cells;
  cell_width_ = 2.0 * radius_ / cells;

  // Per bin and segment: the extents across (offset) and along the bin's directions. A point's
  // projection P . u(theta) is a sinusoid of amplitude |P|; over a bin of width w it leaves the
  // range of its end values by at most |P| (1 - cos(w / 2)).
  struct Hull {
    Vec2 p[4];  // relative to the centre
    double r[4];
    int count = 0;
  };
  std::vector<Hull> hulls(segments_.size());
  for (std::size_t s = 0; s < segments_.size(); ++s)
    for_each_point(segments_[s], [&](Vec2 point) {
      Hull& h = hulls[s];
      h.p[h.count] = point - centre_;
      h.r[h.count] = length(h.p[h.count]);
      ++h.count;
    });
  struct Bin {
    Vec2 da, db, na, nb;  // the directions and normals at the bin's two ends
    double sag = 0.0;
  };
  std::vector<Bin> bin_ends(static_cast<std::size_t>(bins));
  for (int k = 0; k < bins; ++k) {
    const Vec2 a = diamond_point(4.0 * k / bins);
    const Vec2 b = diamond_point(4.0 * (k + 1) / bins);
    const double theta_a = std::atan2(a.y, a.x);
    double theta_b = std::atan2(b.y, b.x);
    while (theta_b <= theta_a) theta_b += 2.0 * std::numbers::pi;
    Bin& bin = bin_ends[static_cast<std::size_t>(k)];
    bin.sag = 1.0 - std::cos(std::min(0.5 * (theta_b - theta_a), std::numbers::pi));
    bin.da = {std::cos(theta_a), std::sin(theta_a)};
    bin.db = {std::cos(theta_b), std::sin(theta_b)};
    bin.na = {-bin.da.y, bin.da.x};
    bin.nb = {-bin.db.y, bin.db.x};
  }
  struct Extent {
    Interval across;
    Interval along;
    int first_cell = 0;
    int last_cell = 0;
  };
  auto extent = [&](int k, std::size_t s) {
    const Bin& bin = bin_ends[static_cast<std::size_t>(k)];
    const Hull& h = hulls[s];
    Extent e;
    for (int i = 0; i < h.count; ++i) {
      const Vec2 p = h.p[i];
      const double bulge = h.r[i] * bin.sag + pad_;
      const double across_a = dot(p, bin.na), across_b = dot(p, bin.nb);
      const double along_a = dot(p, bin.da), along_b = dot(p, bin.db);
      e.across.add(std::min(across_a, across_b) - bulge, std::max(across_a, across_b) + bulge);
      e.along.add(std::min(along_a, along_b) - bulge, std::max(along_a, along_b) + bulge);
    }
    e.first_cell = std::clamp(static_cast<int>(std::floor((e.across.lower + radius_) / cell_width_)), 0, cells - 1);
    e.last_cell = std::clamp(static_cast<int>(std::floor((e.across.upper + radius_) / cell_width_)), 0, cells - 1);
    return e;
  };
  // Two passes (count, then fill) that compute the same extents, rather than keeping them all.
  std::vector<std::uint32_t> counts(static_cast<std::size_t>(bins) * cells + 1, 0);
  for (int k = 0; k < bins; ++k)
    for (std::size_t s = 0; s < segments_.size(); ++s) {
      const Extent e = extent(k, s);
      for (int j = e.first_cell; j <= e.last_cell; ++j) ++counts[static_cast<std::size_t>(k) * cells + j];
    }
  // Overfull cells keep no entries.
  std::vector<std::uint8_t> left(counts.size() - 1, 0);
  for (std::size_t c = 0; c + 1 < counts.size(); ++c)
    if (counts[c] > static_cast<std::uint32_t>(shape_.cell_limit)) {
      left[c] = 1;
      counts[c] = 0;
      ++cells_left_;
    }
  heads_.assign(counts.size(), Head{0, 0.0f});
  for (std::size_t c = 0; c + 1 < counts.size(); ++c) heads_[c + 1].first = heads_[c].first + counts[c];
  entries_.resize(heads_.back().first);
  std::vector<std::uint32_t> fill(counts.size() - 1);
  for (std::size_t c = 0; c < fill.size(); ++c) fill[c] = heads_[c].first;
  for (int k = 0; k < bins; ++k)
    for (std::size_t s = 0; s < segments_.size(); ++s) {
      const Extent e = extent(k, s);
      for (int j = e.first_cell; j <= e.last_cell; ++j) {
        const std::size_t c = static_cast<std::size_t>(k) * cells + j;
        if (!left[c])
          entries_[fill[c]++] =
              Entry{round_down(e.along.lower), round_up(e.along.upper), static_cast<std::uint32_t>(s)};
      }
    }
  for (std::size_t c = 0; c + 1 < heads_.size(); ++c) {
    Entry* first = entries_.data() + heads_[c].first;
    Entry* last = entries_.data() + heads_[c + 1].first;
    std::sort(first, last, [](const Entry& x, const Entry& y) {
      return x.lower < y.lower || (x.lower == y.lower && x.segment < y.segment);
    });
    double reach = 0.0;
    for (const Entry* e = first; e != last; ++e)
      reach = std::max(reach, static_cast<double>(e->upper) - static_cast<double>(e->lower));
    heads_[c].reach = left[c] ? std::numeric_limits<float>::quiet_NaN() : round_up(reach);
  }
}

std::size_t LineSpaceCaster::memory_bytes() const {
  return segments_.size() * sizeof(SegmentGeometry) + heads_.size() * sizeof(Head) + entries_.size() * sizeof(Entry);
}

SceneHit LineSpaceCaster::scan_all(const Ray& ray, const RayOrigin& from) const {
  detail::Nearest nearest;
  for (std::uint32_t i = 0; i < segments_.size(); ++i) nearest.consider(i, segments_[i], ray, from);
  return nearest.answer();
}

SceneHit LineSpaceCaster::closest_hit_or_scan(const Ray& ray, const RayOrigin& from) const {
  SceneHit hit;
  return closest_hit(ray, from, &hit) ? hit : scan_all(ray, from);
}

bool LineSpaceCaster::closest_hit(const Ray& ray, const RayOrigin& from, SceneHit* hit) const {
  if (heads_.empty()) return false;  // not built
  const Vec2 d = ray.direction;
  const double a = diamond_angle(d) * (shape_.angle_bins / 4.0);
  if (!(a >= 0.0 && a <= shape_.angle_bins)) return false;  // not a direction
  const int bin = std::min(static_cast<int>(a), shape_.angle_bins - 1);
  const Vec2 relative = ray.origin - centre_;
  // The ray's line: its offset across (with the ray's own normal, which lies in the bin's range of
  // normals) and the origin's position along.
  const double across = d.x * relative.y - d.y * relative.x;
  const double along = dot(d, relative);
  if (!std::isfinite(across) || !std::isfinite(along)) return false;
  // Every control point lies within radius_ of the centre, so a line farther off meets nothing.
  if (std::fabs(across) > radius_ + pad_) {
    *hit = SceneHit{};
    return true;
  }
  const int cell = std::clamp(static_cast<int>((across + radius_) / cell_width_), 0, shape_.offset_cells - 1);
  const std::size_t c = static_cast<std::size_t>(bin) * shape_.offset_cells + cell;
  const Head head = heads_[c];
  if (std::isnan(head.reach)) return false;
  const Entry* first = entries_.data() + head.first;
  const Entry* last = entries_.data() + heads_[c + 1].first;
  // A hit on a segment lies at a distance in [lower - along, upper - along], up to the rounding
  // of `along` and of the hit's own distance, which `margin` covers (it grows with a far origin).
  const double margin = pad_ + 1e-12 * (std::fabs(relative.x) + std::fabs(relative.y));
  // Entries starting before `along - margin - reach` end before the origin: a long list skips
  // them by binary search; a short one (a cache line or two) is read in order, which is faster
  // than the search's dependent loads, and its entries behind the origin are passed over below.
  if (last - first > kShortList) {
    const double skip_below = along - margin - static_cast<double>(head.reach);
    first = std::partition_point(first, last, [skip_below](const Entry& e) { return e.lower < skip_below; });
  }
  detail::Nearest nearest;
  for (const Entry* e = first; e != last; ++e) {
    if (static_cast<double>(e->lower) - along - margin > nearest.limit) break;
    if (static_cast<double>(e->upper) - along + margin < 0.0) continue;
    nearest.consider(e->segment, segments_[e->segment], ray, from);
  }
  *hit = nearest.answer();
  return true;
}

}  // namespace flatland
