// The light in the plane as a field: the fluence of the photons' flights over a grid of square
// cells. In 2D the fluence at a point is the power-weighted length of flight per unit area, so a
// cell's value is sum over flights (power x length of the flight inside the cell) / cell area,
// each flight's length inside the cell found exactly (a grid traversal of the straight legs). A
// record of the first k photons of a run of n stands for all n (each flight weighted n / k): the
// field estimates the light of the whole solve, converging as more is recorded, instead of
// growing whiter as a sum of equally bright lines does. The viewer and `flatland render` tone map it
// (docs/viewer.md, "Light as a field").
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "flatland/base/status.hpp"
#include "flatland/base/vec2.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/transport/photon_shooter.hpp"
#include "flatland/transport/settings.hpp"

namespace flatland {

// Keeps the first n flights of a solver's record; with walks, a walk that goes on past them has its
// last kept hop marked cut, as the solver marks a record that reached its limit.
void truncate_record(std::vector<PhotonPath>& record, std::size_t n, Transport transport);

class LightField {
 public:
  LightField() = default;
  // A grid over `box` (which must have a positive extent), its longer side `resolution` cells
  // (1 .. 4096), cells square; 1 or 3 channels.
  static Result<LightField> create(const Box& box, int resolution, int channels);
  // The grid for a scene: its bounds padded by 5 % of its size on every side (where the viewer
  // draws escaping light to), the scene's channels.
  static Result<LightField> for_scene(const Scene& scene, int resolution);

  // Adds power x weight x (length inside each cell) / cell area along the straight leg a -> b; the
  // part outside the grid's box adds nothing.
  void add_leg(Vec2 a, Vec2 b, const Spectrum& power, double weight);
  // A flight: origin -> via... -> end, each leg with the flight's power; a flight that escaped
  // goes on from its last point in its direction (end - last point) to the grid's edge.
  void add_flight(const PhotonPath& path, double weight);
  // A solver's record of the first photons of `shot` photons it shot in one step (one round):
  // every flight weighted shot / k, with k the photons whose flights the record holds whole
  // (shooting: every path is a photon; walks: a path with bounce 0 starts a walk, and a walk the
  // record cut short is left out with its photon). Returns k (0: nothing added).
  std::size_t add_record(const std::vector<PhotonPath>& record, std::uint64_t shot, Transport transport);
  // The whole photons among the first `count` flights of `flights` (as add_record counts them; with
  // walks, one that goes on past them is left out) with weight 1, photons() unchanged: a record
  // built piece by piece, to be added with its weight once its photons are known. Returns the
  // photons added.
  std::size_t add_flights(const std::vector<PhotonPath>& flights, std::size_t count, Transport transport);
  // Adds weight x `other` (a field on the same grid) to every cell, and `photons` to photons().
  void add(const LightField& other, double weight, double photons);

  int width() const { return width_; }
  int height() const { return height_; }
  int channels() const { return channels_; }
  const Box& box() const { return box_; }  // the grid's box: width x cell, height x cell from lower
  double cell() const { return cell_; }    // a cell's side
  // Fluence per cell: values()[(row * width + column) * channels + channel], row 0 at box().lower.y.
  const std::vector<double>& values() const { return values_; }
  // Photons the field stands for (the sum of add_record's `shot` over records it used).
  double photons() const { return photons_; }

  // The q-quantile (0 < q <= 1) of the cells' luminance (the channels' mean) over the cells with
  // any light; 0 when no cell has any.
  double quantile(double q) const;

  void clear();

 private:
  Box box_;
  double cell_ = 0.0;
  int width_ = 0;
  int height_ = 0;
  int channels_ = 1;
  std::vector<double> values_;
  double photons_ = 0.0;
};

}  // namespace flatland
