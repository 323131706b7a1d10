// Nearest-hit queries against all segments of a scene: a bounding volume hierarchy over the
// segments' boxes (built binary, walked as nodes of four with one SIMD slab test each), with a
// linear scan for scenes too small to profit; for scenes of up to kLineSpaceLimit segments a grid
// over the space of lines (line_space.hpp) answers first, and the tree takes the rays of its
// overfull cells.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "flatland/geometry/bezier.hpp"
#include "flatland/geometry/intersect.hpp"
#include "flatland/geometry/line_space.hpp"
#include "flatland/geometry/segments.hpp"

namespace flatland {

class SegmentAccelerator {
 public:
  // Up to this many segments the line-space grid is built (beyond it its cells grow too full to
  // beat the tree: docs/performance.md, "A caster made for the plane").
  static constexpr std::size_t kLineSpaceLimit = 512;

  // What the accelerator will be asked: nearest hits (the grid is built where it helps), or only
  // which segments overlap a box (the tree alone).
  enum class Queries { Rays, Overlaps };

  SegmentAccelerator() = default;
  explicit SegmentAccelerator(std::vector<SegmentGeometry> segments, Queries queries = Queries::Rays);

  // Nearest hit with distance in (0, infinity), or segment == kNoSegment for a miss. Of hits at
  // the same distance (a ray through a joint) the smaller segment index wins, so the answer does
  // not depend on the order of the search and equals closest_hit_brute_force bit for bit.
  SceneHit closest_hit(const Ray& ray, const RayOrigin& from) const;
  // The same answer from the tree alone (the grid not asked); for tests and benchmarks.
  SceneHit closest_hit_tree(const Ray& ray, const RayOrigin& from) const;
  // The same answer by testing every segment; for tests and tiny scenes.
  SceneHit closest_hit_brute_force(const Ray& ray, const RayOrigin& from) const;

  // Calls visit(i) for every segment i whose box (segment_box) overlaps `box`, in no particular
  // order: the tree's second query, "which segments are near here" (contacts).
  template <class Visit>
  void for_each_overlapping(const Box& box, const Visit& visit) const {
    if (nodes_.empty()) {
      for (std::uint32_t i = 0; i < boxes_.size(); ++i)
        if (boxes_[i].overlaps(box)) visit(i);
      return;
    }
    std::uint32_t stack[128];  // the build's depth stays below 64
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const std::uint32_t index = stack[--top];
      const Node& node = nodes_[index];
      if (!node.bounds.overlaps(box)) continue;
      if (node.count > 0) {
        for (std::uint32_t k = node.second_child_or_first; k < node.second_child_or_first + node.count; ++k)
          if (boxes_[order_[k]].overlaps(box)) visit(order_[k]);
      } else {
        stack[top++] = index + 1;
        stack[top++] = node.second_child_or_first;
      }
    }
  }

  std::span<const SegmentGeometry> segments() const { return segments_; }
  bool uses_hierarchy() const { return !nodes_.empty(); }
  bool uses_line_space() const { return line_space_.built(); }
  bool has_cubics() const { return has_cubics_; }

 private:
  struct Node {
    Box bounds;
    // Interior: children at index+1 and second_child; leaf: first/count into order_.
    std::uint32_t second_child_or_first = 0;
    std::uint32_t count = 0;  // 0 for interior nodes
  };

  struct Build;  // the build's per-segment lists (accelerator.cpp)
  std::uint32_t build_node(std::uint32_t first, std::uint32_t count, int depth, int parent_axis, Build& build);

  // The tree the queries walk: the binary tree collapsed into nodes of up to four children, whose
  // boxes are floats relative to `wide_centre_` (padded by far more than float rounding) in
  // structure-of-arrays form, so that one node tests its four boxes together. A child is another
  // wide node or a leaf, a range of ordered_; an unused slot has an empty box.
  struct WideNode {
    alignas(16) float lower_x[4];
    float lower_y[4];
    float upper_x[4];
    float upper_y[4];
    std::uint32_t child[4];  // wide node index, or first index into ordered_ for a leaf
    std::uint32_t count[4];  // segments of a leaf; 0 for a wide node or an unused slot
    std::uint32_t used = 0;  // slots 0 .. used - 1 hold children
  };
  std::uint32_t collapse(std::uint32_t binary, double pad);
  SceneHit closest_hit_binary(const Ray& ray, const RayOrigin& from) const;
  std::vector<WideNode> wide_;
  Vec2 wide_centre_;
  double wide_reach_ = 0.0;  // rays from farther than this from the centre use the binary tree

  std::vector<SegmentGeometry> segments_;  // in the caller's order (indices of SceneHit)
  std::vector<Box> boxes_;                 // segment_box of each, in the same order
  std::vector<std::uint32_t> order_;       // leaf order -> index into segments_
  std::vector<SegmentGeometry> ordered_;   // segments_[order_[i]], so leaves read memory linearly
  std::vector<Node> nodes_;
  bool has_cubics_ = false;
  LineSpaceCaster line_space_;
};

}  // namespace flatland
