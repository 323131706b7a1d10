// Nearest-hit queries for a plane: a grid over the space of lines.
//
// A line in the plane is an angle and an offset. The grid splits the directions into `angle_bins`
// bins (uniform in the diamond angle, a cheap monotone stand-in for the angle) and, per bin, the
// offsets across the scene into `offset_cells` cells. A cell lists every segment that some line of
// the cell may meet (its control hull's projection on the line's normal, bounded over the bin's
// directions), sorted by where it starts along the bin's directions. A ray finds its cell from its
// direction and origin with two dot products, skips the segments behind its origin by a binary
// search, and tests the rest in order until no later one can start before the best hit.
//
// A cell that would list more than `cell_limit` segments (a dense cluster, or a scene too large for
// the grid) lists none and is left to another caster: the grid's memory is bounded by
// angle_bins x offset_cells x (cell_limit entries of 12 bytes + 8 bytes), and a ray never scans a
// long list.
//
// The answer is the brute force's bit for bit (detail::Nearest decides, as in every caster): the
// bounds only choose which segments to test, and are padded by far more than their rounding.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "flatland/geometry/intersect.hpp"
#include "flatland/geometry/segments.hpp"

namespace flatland {

class LineSpaceCaster {
 public:
  struct Shape {
    int angle_bins = 64;
    int offset_cells = 128;
    int cell_limit = 64;
  };

  LineSpaceCaster() = default;
  LineSpaceCaster(std::span<const SegmentGeometry> segments, Shape shape);

  // Nearest hit with distance in (0, infinity), or segment == kNoSegment for a miss; ties at equal
  // distance go to the smaller index (as SegmentAccelerator::closest_hit). False, with *hit
  // untouched, when the ray's cell is left to another caster.
  bool closest_hit(const Ray& ray, const RayOrigin& from, SceneHit* hit) const;
  // The same, asking every segment where the grid does not answer; for tests.
  SceneHit closest_hit_or_scan(const Ray& ray, const RayOrigin& from) const;

  // The entries the grid holds (a segment counts once per cell it is listed in) and its bytes.
  // Whether the grid was built (a default one, or one of a scene without extent, answers no query).
  bool built() const { return !heads_.empty(); }
  std::size_t entries() const { return entries_.size(); }
  // The cells left to another caster (more than cell_limit segments), of angle_bins x offset_cells.
  std::size_t cells_left() const { return cells_left_; }
  std::size_t memory_bytes() const;
  Shape shape() const { return shape_; }

 private:
  struct Entry {
    float lower;  // the segment's extent along the bin's directions, relative to the centre,
    float upper;  // rounded outwards
    std::uint32_t segment;
  };

  SceneHit scan_all(const Ray& ray, const RayOrigin& from) const;

  Shape shape_;
  std::vector<SegmentGeometry> segments_;
  Vec2 centre_;
  double radius_ = 0.0;  // every control point lies within this of the centre
  double pad_ = 0.0;     // what every bound is widened by, far above its rounding
  double cell_width_ = 0.0;
  // Per (bin, cell), one more at the end: its first entry, and the largest upper - lower of its
  // entries (NaN for a cell left to another caster), side by side so that a ray reads its cell's
  // head, and the next cell's first entry, from one cache line.
  struct Head {
    std::uint32_t first;
    float reach;
  };
  std::vector<Head> heads_;
  std::size_t cells_left_ = 0;
  std::vector<Entry> entries_;
};

}  // namespace flatland
