// Nearest-hit queries: a BVH over the segments' boxes (binary, collapsed into nodes of four), or a
// linear scan.
#include "flatland/geometry/accelerator.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

#include "flatland/geometry/nearest.hpp"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace flatland {
namespace {

using detail::Nearest;

constexpr double kInfinity = std::numeric_limits<double>::infinity();
constexpr std::uint32_t kLeafSize = 2;       // measured against 1 and 4 with the wide tree (docs/performance.md)
constexpr std::size_t kLinearScanLimit = 8;  // up to this many segments a scan beats the tree
constexpr int kMaxSahDepth = 32;             // below it median splits: depth <= 32 + log2(n) + 1
constexpr int kStackSize = 72;

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

// Pops stacked nodes until one whose entry distance is within `bound`, which becomes `node`;
// false when none is left.
template <typename Pending, typename Distance>
bool resume(const Pending* stack, int& top, Distance bound, std::uint32_t& node) {
  while (top > 0) {
    const Pending& pending = stack[--top];
    if (pending.near <= bound) {
      node = pending.node;
      return true;
    }
  }
  return false;
}

}  // namespace

// The build's lists (build_node).
struct SegmentAccelerator::Build {
  std::vector<Box> boxes;
  std::array<std::vector<std::uint32_t>, 2> by;  // segment indices by centre x, by centre y
  std::vector<double> right_cost;                // per node position, reused
  std::vector<std::uint32_t> moved;              // the right part of a stable split
  std::vector<std::uint8_t> left;                // per segment: in the left child
};

SegmentAccelerator::SegmentAccelerator(std::vector<SegmentGeometry> segments, Queries queries)
    : segments_(std::move(segments)) {
  has_cubics_ = std::any_of(segments_.begin(), segments_.end(),
                            [](const SegmentGeometry& g) { return g.kind == SegmentKind::Cubic; });
  boxes_.reserve(segments_.size());
  for (const SegmentGeometry& segment : segments_) boxes_.push_back(segment_box(segment));
  if (segments_.size() <= kLinearScanLimit) return;
  if (queries == Queries::Rays && segments_.size() <= kLineSpaceLimit) {
    line_space_ = LineSpaceCaster(segments_, LineSpaceCaster::Shape{});
  }

  const auto n = static_cast<std::uint32_t>(segments_.size());
  std::vector<Box> boxes = boxes_;
  std::vector<Vec2> centers(n);
  Box scene;
  for (std::uint32_t i = 0; i < n; ++i) {
    centers[i] = boxes[i].center();
    scene.extend(boxes[i]);
  }
  // Padding of every box: far above the rounding of the slab test and of the segment tests (a few
  // ulps of the coordinates), far below anything that costs culling.
  const double magnitude =
      std::max({std::abs(scene.lower.x), std::abs(scene.lower.y), std::abs(scene.upper.x), std::abs(scene.upper.y)});
  const double margin = 1e-10 * (magnitude + scene.diagonal());

  Build build;
  for (int axis = 0; axis < 2; ++axis) {
    std::vector<std::uint32_t>& sorted = build.by[static_cast<std::size_t>(axis)];
    sorted.resize(n);
    for (std::uint32_t i = 0; i < n; ++i) sorted[i] = i;
    std::sort(sorted.begin(), sorted.end(), [&](std::uint32_t a, std::uint32_t b) {
      const double ca = axis == 0 ? centers[a].x : centers[a].y;
      const double cb = axis == 0 ? centers[b].x : centers[b].y;
      return ca < cb || (ca == cb && a < b);
    });
  }
  build.boxes = std::move(boxes);
  build.right_cost.resize(n);
  build.left.resize(n);
  build.moved.reserve(n);
  order_.resize(n);
  nodes_.reserve(2 * (n / kLeafSize + 1));
  build_node(0, n, 0, 0, build);
  for (Node& node : nodes_) {
    node.bounds.lower = node.bounds.lower - Vec2{margin, margin};
    node.bounds.upper = node.bounds.upper + Vec2{margin, margin};
  }
  ordered_.reserve(n);
  for (std::uint32_t i = 0; i < n; ++i) ordered_.push_back(segments_[order_[i]]);

  // The wide tree, relative to the scene's centre. Float rounding of a relative coordinate is
  // 6e-8 of its size: the boxes get 1e-6 of the scene's extent more, and are rounded outwards.
  // Rays whose origin lies farther than 4 extents from the centre (whose own rounding would be
  // larger) take the binary tree, in doubles.
  wide_centre_ = scene.center();
  const double extent = std::max({scene.extent().x, scene.extent().y, margin});
  wide_reach_ = 4.0 * extent;
  wide_.reserve(nodes_.size() / 2 + 1);
  collapse(0, 1e-6 * extent);
}

// The wide node for binary node `binary` (interior): its children, and while there are fewer
// than four, the interior child with the largest box replaced by its two children.
std::uint32_t SegmentAccelerator::collapse(std::uint32_t binary, double pad) {
  const auto index = static_cast<std::uint32_t>(wide_.size());
  wide_.emplace_back();
  std::uint32_t slots[4];
  int used = 0;
  if (nodes_[binary].count > 0) {
    slots[used++] = binary;  // a root that is a leaf
  } else {
    slots[used++] = binary + 1;
    slots[used++] = nodes_[binary].second_child_or_first;
    while (used < 4) {
      int widest = -1;
      double widest_size = -1.0;
      for (int k = 0; k < used; ++k) {
        const Node& node = nodes_[slots[k]];
        if (node.count > 0) continue;
        const double size = node.bounds.extent().x + node.bounds.extent().y;
        if (size > widest_size) {
          widest_size = size;
          widest = k;
        }
      }
      if (widest < 0) break;
      const std::uint32_t opened = slots[widest];
      slots[widest] = opened + 1;
      slots[used++] = nodes_[opened].second_child_or_first;
    }
  }
  auto down = [](double x) {
    const auto f = static_cast<float>(x);
    return static_cast<double>(f) > x ? std::nextafter(f, -INFINITY) : f;
  };
  auto up = [](double x) {
    const auto f = static_cast<float>(x);
    return static_cast<double>(f) < x ? std::nextafter(f, INFINITY) : f;
  };
  wide_[index].used = static_cast<std::uint32_t>(used);
  for (int k = 0; k < 4; ++k) {
    WideNode& node = wide_[index];
    if (k >= used) {
      node.lower_x[k] = node.lower_y[k] = INFINITY;
      node.upper_x[k] = node.upper_y[k] = -INFINITY;
      node.child[k] = 0;
      node.count[k] = 0;
      continue;
    }
    const Node& child = nodes_[slots[k]];
    node.lower_x[k] = down(child.bounds.lower.x - wide_centre_.x - pad);
    node.lower_y[k] = down(child.bounds.lower.y - wide_centre_.y - pad);
    node.upper_x[k] = up(child.bounds.upper.x - wide_centre_.x + pad);
    node.upper_y[k] = up(child.bounds.upper.y - wide_centre_.y + pad);
    if (child.count > 0) {
      node.child[k] = child.second_child_or_first;
      node.count[k] = child.count;
    } else {
      const std::uint32_t wide_child = collapse(slots[k], pad);
      wide_[index].child[k] = wide_child;  // collapse may have moved wide_
      wide_[index].count[k] = 0;
    }
  }
  return index;
}

// Surface area heuristic, in 2D: a random line meets a convex region with probability
// proportional to its perimeter, so a split into L and R costs perimeter(L) |L| + perimeter(R) |R|.
// Both axes are tried with the segments sorted by their box centres (ties by index: a total
// order), and the cheapest cut is taken; leaves hold at most kLeafSize segments. The first child
// is stored right after its parent, the second's index is kept in the parent.
//
// The segments are sorted along each axis once: a node's range of `by[0]` and of `by[1]` holds
// its segments in x and in y order. The chosen axis's list is already cut into the children's
// ranges; the other is split stably by membership, which keeps both children's lists sorted. So
// the build is O(n log n), where sorting both axes at every node would be O(n log^2 n), and the
// tree is the same. A leaf keeps its parent's chosen order.

std::uint32_t SegmentAccelerator::build_node(std::uint32_t first, std::uint32_t count, int depth, int parent_axis,
                                             Build& build) {
  const auto index = static_cast<std::uint32_t>(nodes_.size());
  nodes_.push_back({});
  const std::vector<Box>& boxes = build.boxes;
  Box bounds;
  for (std::uint32_t i = first; i < first + count; ++i) bounds.extend(boxes[build.by[0][i]]);
  if (count <= kLeafSize) {
    const std::vector<std::uint32_t>& order = build.by[static_cast<std::size_t>(parent_axis)];
    std::copy(order.begin() + first, order.begin() + first + count, order_.begin() + first);
    nodes_[index] = Node{bounds, first, count};
    return index;
  }
  auto perimeter = [](const Box& box) { return 2.0 * (box.extent().x + box.extent().y); };
  double* right_cost = build.right_cost.data() + first;
  double best_cost = std::numeric_limits<double>::infinity();
  int best_axis = 0;
  std::uint32_t best_split = count / 2;
  for (int axis = 0; axis < 2; ++axis) {
    const std::uint32_t* sorted = build.by[static_cast<std::size_t>(axis)].data() + first;
    Box right;
    for (std::uint32_t i = count; i-- > 1;) {
      right.extend(boxes[sorted[i]]);
      right_cost[i] = perimeter(right) * (count - i);
    }
    Box left;
    for (std::uint32_t i = 1; i < count; ++i) {
      left.extend(boxes[sorted[i - 1]]);
      const double cost = perimeter(left) * i + right_cost[i];
      if (cost < best_cost) {
        best_cost = cost;
        best_axis = axis;
        best_split = i;
      }
    }
  }
  // Deep in the tree, halve instead, so the depth (and the traversal stack) stays bounded.
  if (depth >= kMaxSahDepth) best_split = count / 2;
  // The other axis's list, split stably into the left child's segments and the right's.
  const std::uint32_t* chosen = build.by[static_cast<std::size_t>(best_axis)].data() + first;
  for (std::uint32_t i = 0; i < count; ++i) build.left[chosen[i]] = i < best_split;
  std::uint32_t* other = build.by[static_cast<std::size_t>(1 - best_axis)].data() + first;
  build.moved.clear();
  std::uint32_t kept = 0;
  for (std::uint32_t i = 0; i < count; ++i) {
    if (build.left[other[i]]) {
      other[kept++] = other[i];
    } else {
      build.moved.push_back(other[i]);
    }
  }
  std::copy(build.moved.begin(), build.moved.end(), other + kept);
  build_node(first, best_split, depth + 1, best_axis, build);
  const std::uint32_t second = build_node(first + best_split, count - best_split, depth + 1, best_axis, build);
  nodes_[index] = Node{bounds, second, 0};
  return index;
}

SceneHit SegmentAccelerator::closest_hit_brute_force(const Ray& ray, const RayOrigin& from) const {
  Nearest nearest;
  const auto n = static_cast<std::uint32_t>(segments_.size());
  for (std::uint32_t i = 0; i < n; ++i) nearest.consider(i, segments_[i], ray, from);
  return nearest.answer();
}

// The grid over the space of lines where it is built and the ray's cell holds its segments (it
// gives the tree's answer bit for bit), the tree otherwise.
SceneHit SegmentAccelerator::closest_hit(const Ray& ray, const RayOrigin& from) const {
  if (nodes_.empty()) return closest_hit_brute_force(ray, from);
  SceneHit hit;
  if (line_space_.closest_hit(ray, from, &hit)) return hit;  // false where it is not built
  return closest_hit_tree(ray, from);
}

// Depth-first over the wide tree: a node slab-tests its four boxes at once (floats, relative to
// the centre; an axis the ray does not move along gets a large finite inverse, so a box either
// contains the origin's coordinate or lies at an enormous distance, never 0 x infinity), visits
// the boxes it meets nearest first and stacks the others with their entry distances, which are
// checked again when popped. A box is entered when its entry is at most the best distance so far
// (plus its rounding): the same segments as the binary walk may skip are skipped, no others.
SceneHit SegmentAccelerator::closest_hit_tree(const Ray& ray, const RayOrigin& from) const {
  if (nodes_.empty()) return closest_hit_brute_force(ray, from);
  const Vec2 relative = ray.origin - wide_centre_;
  if (!(std::fabs(relative.x) <= wide_reach_ && std::fabs(relative.y) <= wide_reach_))
    return closest_hit_binary(ray, from);
  Nearest nearest;
  const float ox = static_cast<float>(relative.x);
  const float oy = static_cast<float>(relative.y);
  auto inverse = [](double d) {
    const double i = 1.0 / d;
    return std::isfinite(i) && std::fabs(i) < 1e30 ? static_cast<float>(i) : (d < 0.0 ? -1e30f : 1e30f);
  };
  const float ix = inverse(ray.direction.x);
  const float iy = inverse(ray.direction.y);
  // The best distance as a float bound, rounded up (and slightly more, for the float slab test).
  auto float_bound = [&nearest] {
    return nearest.hit.distance == kInfinity ? INFINITY : static_cast<float>(nearest.hit.distance) * 1.000001f;
  };
  struct Pending {
    std::uint32_t node;
    float near;
  };
  // A wide level stacks at most 3 more nodes than it pops, over at most 32 + log2(n) + 1 levels.
  Pending stack[3 * (kMaxSahDepth + 33) + 4];
  int top = 0;
  std::uint32_t current = 0;
  for (;;) {
    const WideNode& node = wide_[current];
    const float best = float_bound();
    alignas(16) float near[4];
    bool hit[4];
#if defined(__SSE2__)
    {
      const __m128 a_x = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(node.lower_x), _mm_set1_ps(ox)), _mm_set1_ps(ix));
      const __m128 b_x = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(node.upper_x), _mm_set1_ps(ox)), _mm_set1_ps(ix));
      const __m128 a_y = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(node.lower_y), _mm_set1_ps(oy)), _mm_set1_ps(iy));
      const __m128 b_y = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(node.upper_y), _mm_set1_ps(oy)), _mm_set1_ps(iy));
      const __m128 lo = _mm_max_ps(_mm_max_ps(_mm_min_ps(a_x, b_x), _mm_min_ps(a_y, b_y)), _mm_setzero_ps());
      const __m128 hi = _mm_min_ps(_mm_max_ps(a_x, b_x), _mm_max_ps(a_y, b_y));
      const int mask = _mm_movemask_ps(_mm_and_ps(_mm_cmple_ps(lo, hi), _mm_cmple_ps(lo, _mm_set1_ps(best)))) &
                       ((1 << node.used) - 1);
      _mm_store_ps(near, lo);
      for (int k = 0; k < 4; ++k) hit[k] = (mask >> k) & 1;
    }
#else
    for (int k = 0; k < 4; ++k) {
      const float ax = (node.lower_x[k] - ox) * ix;
      const float bx = (node.upper_x[k] - ox) * ix;
      const float ay = (node.lower_y[k] - oy) * iy;
      const float by = (node.upper_y[k] - oy) * iy;
      const float lo = std::max(std::max(std::min(ax, bx), std::min(ay, by)), 0.0f);
      const float hi = std::min(std::max(ax, bx), std::max(ay, by));
      near[k] = lo;
      hit[k] = static_cast<std::uint32_t>(k) < node.used && lo <= hi && lo <= best;
    }
#endif
    // The boxes met, nearest first (at most four: insertion).
    int order[4];
    int met = 0;
    for (int k = 0; k < 4; ++k) {
      if (!hit[k]) continue;
      int at = met++;
      while (at > 0 && near[order[at - 1]] > near[k]) {
        order[at] = order[at - 1];
        --at;
      }
      order[at] = k;
    }
    // Leaves now, nearest first; wide children onto the stack, farthest deepest.
    for (int m = met; m-- > 0;) {
      const int k = order[m];
      if (node.count[k] == 0) stack[top++] = {node.child[k], near[k]};
    }
    for (int m = 0; m < met; ++m) {
      const int k = order[m];
      if (node.count[k] == 0) continue;
      const std::uint32_t end = node.child[k] + node.count[k];
      for (std::uint32_t i = node.child[k]; i < end; ++i) nearest.consider(order_[i], ordered_[i], ray, from);
    }
    if (!resume(stack, top, float_bound(), current)) break;
  }
  return nearest.answer();
}

// Depth-first traversal with an explicit stack: at an interior node both children are slab-tested
// against [0, best], the nearer is visited first and the farther pushed with its entry distance,
// which is checked again when it is popped (the best distance may have shrunk meanwhile).
SceneHit SegmentAccelerator::closest_hit_binary(const Ray& ray, const RayOrigin& from) const {
  Nearest nearest;
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
    if (!resume(stack, top, nearest.hit.distance, current)) break;
  }
  return nearest.answer();
}

}  // namespace flatland
