// Nearest-hit queries: a binary BVH over the segments' control-point boxes, or a linear scan.
#include "flatland/bvh.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace flatland {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
constexpr std::uint32_t kLeafSize = 4;
constexpr std::size_t kLinearScanLimit = 8;  // up to this many segments a scan beats the tree
constexpr int kMaxSahDepth = 32;  // below it median splits: depth <= 32 + log2(n) + 1
constexpr int kStackSize = 72;

// One segment against the ray. The origin segment is special: a straight line cannot see itself,
// and a cubic deflates the root at the origin's parameter (a concave cubic lights itself).
inline bool test_geometry(const SegmentGeometry& g, bool is_origin, double t_origin, const Ray& ray,
                          double max_distance, SegmentHit* hit) {
  if (g.kind == SegmentKind::Line) {
    return !is_origin && intersect_line(g.shape.p[0], g.shape.p[3], ray, max_distance, hit);
  }
  return is_origin ? intersect_cubic_from(g.shape, t_origin, ray, max_distance, hit)
                   : intersect_cubic(g.shape, ray, max_distance, hit);
}

// The running answer. Segments are tested with the limit just above the best distance so that an
// equal distance (a ray through a joint hits both segments there) is still reported, and ties go
// to the smaller index: the answer is then the same whatever order the segments are visited in,
// so the tree and the linear scan agree bit for bit.
struct Nearest {
  SceneHit hit;
  double limit = kInfinity;

  void consider(std::uint32_t index, const SegmentGeometry& g, const Ray& ray,
                const RayOrigin& from) {
    SegmentHit h;
    if (!test_geometry(g, index == from.segment, from.t, ray, limit, &h)) return;
    if (h.distance < hit.distance || (h.distance == hit.distance && index < hit.segment)) {
      hit.segment = index;
      hit.t = h.t;
      hit.distance = h.distance;
      limit = std::nextafter(h.distance, kInfinity);
    }
  }
};

// Slab test with the inverse direction computed once per ray. An axis along which the ray does not
// move (a zero component, or one so small that its inverse overflows) is tested by containment
// instead, which avoids 0 * inf. Boxes are padded at build time by far more than the rounding of
// this test and of the segment tests, so that rounding cannot lose a hit the brute force finds.
struct SlabRay {
  Vec2 origin;
  Vec2 inverse;
  bool still_x;
  bool still_y;

  explicit SlabRay(const Ray& ray) : origin(ray.origin) {
    inverse = {1.0 / ray.direction.x, 1.0 / ray.direction.y};
    still_x = !std::isfinite(inverse.x);
    still_y = !std::isfinite(inverse.y);
  }

  // Whether the ray meets the box at some sigma in [0, max_distance]; the entry distance in *near.
  bool hits(const Box& box, double max_distance, double* near) const {
    double lo = 0.0;
    double hi = max_distance;
    if (still_x) {
      if (origin.x < box.lower.x || origin.x > box.upper.x) return false;
    } else {
      const double a = (box.lower.x - origin.x) * inverse.x;
      const double b = (box.upper.x - origin.x) * inverse.x;
      lo = std::max(lo, std::min(a, b));
      hi = std::min(hi, std::max(a, b));
    }
    if (still_y) {
      if (origin.y < box.lower.y || origin.y > box.upper.y) return false;
    } else {
      const double a = (box.lower.y - origin.y) * inverse.y;
      const double b = (box.upper.y - origin.y) * inverse.y;
      lo = std::max(lo, std::min(a, b));
      hi = std::min(hi, std::max(a, b));
    }
    *near = lo;
    return lo <= hi;
  }
};

}  // namespace

Box segment_box(const SegmentGeometry& g) {
  if (g.kind == SegmentKind::Line) {
    Box box;
    box.extend(g.shape.p[0]);
    box.extend(g.shape.p[3]);
    return box;
  }
  // The curve's own extent, not its control points' (a bulging cubic's hull box can be twice as
  // tall as the curve): fewer rays reach its test. Rounding of the extrema is a few ulps, far
  // inside the tree's padding.
  return tight_bounds(g.shape);
}


SegmentAccelerator::SegmentAccelerator(std::vector<SegmentGeometry> segments)
    : segments_(std::move(segments)) {
  has_cubics_ = std::any_of(segments_.begin(), segments_.end(),
                            [](const SegmentGeometry& g) { return g.kind == SegmentKind::Cubic; });
  if (segments_.size() <= kLinearScanLimit) return;

  const auto n = static_cast<std::uint32_t>(segments_.size());
  std::vector<Box> boxes(n);
  std::vector<Vec2> centers(n);
  Box scene;
  for (std::uint32_t i = 0; i < n; ++i) {
    boxes[i] = segment_box(segments_[i]);
    centers[i] = boxes[i].center();
    scene.extend(boxes[i]);
  }
  // Padding of every box: far above the rounding of the slab test and of the segment tests (a few
  // ulps of the coordinates), far below anything that costs culling.
  const double magnitude = std::max({std::abs(scene.lower.x), std::abs(scene.lower.y),
                                     std::abs(scene.upper.x), std::abs(scene.upper.y)});
  const double margin = 1e-10 * (magnitude + scene.diagonal());

  order_.resize(n);
  for (std::uint32_t i = 0; i < n; ++i) order_[i] = i;
  nodes_.reserve(2 * (n / kLeafSize + 1));
  build_node(0, n, 0, boxes, centers);
  for (Node& node : nodes_) {
    node.bounds.lower = node.bounds.lower - Vec2{margin, margin};
    node.bounds.upper = node.bounds.upper + Vec2{margin, margin};
  }
  ordered_.reserve(n);
  for (std::uint32_t i = 0; i < n; ++i) ordered_.push_back(segments_[order_[i]]);
}

// Surface area heuristic, in 2D: a random line meets a convex region with probability
// proportional to its perimeter, so a split into L and R costs perimeter(L) |L| + perimeter(R) |R|.
// Both axes are tried with the segments sorted by their box centres, and the cheapest cut is
// taken; leaves hold at most kLeafSize segments. The first child is stored right after its
// parent, the second's index is kept in the parent.
std::uint32_t SegmentAccelerator::build_node(std::uint32_t first, std::uint32_t count, int depth,
                                             std::vector<Box>& boxes, std::vector<Vec2>& centers) {
  const auto index = static_cast<std::uint32_t>(nodes_.size());
  nodes_.push_back({});
  Box bounds;
  for (std::uint32_t i = first; i < first + count; ++i) bounds.extend(boxes[order_[i]]);
  if (count <= kLeafSize) {
    nodes_[index] = Node{bounds, first, count};
    return index;
  }
  auto perimeter = [](const Box& box) { return 2.0 * (box.extent().x + box.extent().y); };
  auto begin = order_.begin() + first;
  auto end = begin + count;
  std::vector<double> right_cost(count);
  double best_cost = std::numeric_limits<double>::infinity();
  int best_axis = 0;
  std::uint32_t best_split = count / 2;
  for (int axis = 0; axis < 2; ++axis) {
    std::sort(begin, end, [&](std::uint32_t a, std::uint32_t b) {
      const double ca = axis == 0 ? centers[a].x : centers[a].y;
      const double cb = axis == 0 ? centers[b].x : centers[b].y;
      return ca < cb || (ca == cb && a < b);
    });
    Box right;
    for (std::uint32_t i = count; i-- > 1;) {
      right.extend(boxes[order_[first + i]]);
      right_cost[i] = perimeter(right) * (count - i);
    }
    Box left;
    for (std::uint32_t i = 1; i < count; ++i) {
      left.extend(boxes[order_[first + i - 1]]);
      const double cost = perimeter(left) * i + right_cost[i];
      if (cost < best_cost) {
        best_cost = cost;
        best_axis = axis;
        best_split = i;
      }
    }
  }
  if (best_axis == 0) {
    std::sort(begin, end, [&](std::uint32_t a, std::uint32_t b) {
      return centers[a].x < centers[b].x || (centers[a].x == centers[b].x && a < b);
    });
  }
  // Deep in the tree, halve instead, so the depth (and the traversal stack) stays bounded.
  if (depth >= kMaxSahDepth) best_split = count / 2;
  build_node(first, best_split, depth + 1, boxes, centers);
  const std::uint32_t second =
      build_node(first + best_split, count - best_split, depth + 1, boxes, centers);
  nodes_[index] = Node{bounds, second, 0};
  return index;
}

SceneHit SegmentAccelerator::closest_hit_brute_force(const Ray& ray, const RayOrigin& from) const {
  Nearest nearest;
  nearest.hit.distance = kInfinity;
  const auto n = static_cast<std::uint32_t>(segments_.size());
  for (std::uint32_t i = 0; i < n; ++i) nearest.consider(i, segments_[i], ray, from);
  if (nearest.hit.segment == kNoSegment) return SceneHit{};
  return nearest.hit;
}

// Depth-first traversal with an explicit stack: at an interior node both children are slab-tested
// against [0, best], the nearer is visited first and the farther pushed with its entry distance,
// which is checked again when it is popped (the best distance may have shrunk meanwhile).
SceneHit SegmentAccelerator::closest_hit(const Ray& ray, const RayOrigin& from) const {
  if (nodes_.empty()) return closest_hit_brute_force(ray, from);
  Nearest nearest;
  nearest.hit.distance = kInfinity;
  const SlabRay slab(ray);
  struct Pending {
    std::uint32_t node;
    double near;
  };
  Pending stack[kStackSize];
  int top = 0;
  double near = 0.0;
  if (!slab.hits(nodes_[0].bounds, kInfinity, &near)) return SceneHit{};
  std::uint32_t current = 0;
  for (;;) {
    const Node& node = nodes_[current];
    if (node.count > 0) {
      const std::uint32_t end = node.second_child_or_first + node.count;
      for (std::uint32_t i = node.second_child_or_first; i < end; ++i) {
        nearest.consider(order_[i], ordered_[i], ray, from);
      }
    } else {
      std::uint32_t a = current + 1;
      std::uint32_t b = node.second_child_or_first;
      double near_a = 0.0;
      double near_b = 0.0;
      const bool hit_a = slab.hits(nodes_[a].bounds, nearest.hit.distance, &near_a);
      const bool hit_b = slab.hits(nodes_[b].bounds, nearest.hit.distance, &near_b);
      if (hit_a && hit_b) {
        if (near_b < near_a) {
          std::swap(a, b);
          std::swap(near_a, near_b);
        }
        stack[top++] = {b, near_b};
        current = a;
        continue;
      }
      if (hit_a || hit_b) {
        current = hit_a ? a : b;
        continue;
      }
    }
    bool resumed = false;
    while (top > 0) {
      const Pending pending = stack[--top];
      if (pending.near <= nearest.hit.distance) {
        current = pending.node;
        resumed = true;
        break;
      }
    }
    if (!resumed) break;
  }
  if (nearest.hit.segment == kNoSegment) return SceneHit{};
  return nearest.hit;
}

}  // namespace flatland
