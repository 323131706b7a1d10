// Where light lives across a scene: every curve's storage (its finest mesh and, with automatic
// storage, the coarser levels nested in it), the layout of the coefficients (a block of the
// curve's basis for each side that emits or reflects), and the estimators that turn power
// deposited on the finest mesh into coefficients at each curve's chosen level.
//
// Layout: coefficient k of block b (b = curve * 2 + side) is entry block_offset + k; with C
// channels its value for channel c is at (block_offset + k) * C + c in every per-coefficient
// vector of the solver (received, unshot, reflected).
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "flatland/base/status.hpp"
#include "flatland/base/workers.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/storage/curve_storage.hpp"
#include "flatland/storage/estimators.hpp"
#include "flatland/storage/hermite.hpp"
#include "flatland/storage/restriction.hpp"
#include "flatland/transport/settings.hpp"

namespace flatland {

// How fine each curve's storage is built: its finest level has `elements` << level elements (at
// least one a segment), with automatic storage every coarser level below it too.
struct StoragePlan {
  int elements = 1;          // of the coarsest level (the only one on a fixed mesh)
  int finest_level = 0;      // the most any curve gets
  std::vector<double> room;  // automatic storage: elements each curve's finest level may have
  bool automatic = false;    // settings.elements == kAutoElements
};

class SceneStorage {
 public:
  static constexpr std::uint32_t kNoBlock = 0xffffffffu;

  SceneStorage() = default;
  // Every curve's storage, built on `pool`'s workers (each curve by one, so the result does not
  // depend on the thread count), with `events[c]` as extra nodes of curve c. `settings.estimator`
  // is resolved (not Auto). Returns kSolverCancelled's error once `cancel` is set.
  static Result<SceneStorage> build(const Scene& scene, const SolverSettings& settings, const StoragePlan& plan,
                                    const std::vector<std::vector<MeshNode>>& events, WorkerPool& pool,
                                    const std::atomic<bool>* cancel);

  int channels() const { return channels_; }
  std::size_t coefficient_count() const { return coefficient_count_; }
  // The first coefficient of a curve's side, or kNoBlock for a side that neither emits nor reflects.
  std::uint32_t block_offset(std::uint32_t curve, Side side) const {
    return block_offset_[curve * 2 + static_cast<std::uint32_t>(side)];
  }
  std::size_t block_count() const { return block_offset_.size(); }
  std::uint32_t block_offset(std::uint32_t block) const { return block_offset_[block]; }
  const Spectrum& block_reflectivity(std::uint32_t block) const { return block_reflectivity_[block]; }
  // Whether the side reflects nothing in any channel (it only absorbs).
  bool block_black(std::uint32_t block) const { return block_black_[block] != 0; }
  // The block of a coefficient.
  std::uint32_t coefficient_block(std::size_t k) const { return coefficient_block_[k]; }
  const std::vector<std::uint32_t>& coefficient_blocks() const { return coefficient_block_; }
  const std::vector<std::uint32_t>& block_offsets() const { return block_offset_; }

  // A curve's finest storage, which every deposit lands on.
  const CurveStorage& finest(std::uint32_t curve) const { return storage_[curve]; }
  // A curve's storage at a level (0 the coarsest; level_count(curve) - 1 the finest).
  const CurveStorage& at_level(std::uint32_t curve, int level) const;
  int level_count(std::uint32_t curve) const { return static_cast<int>(levels_[curve].size()) + 1; }
  int finest_level(std::uint32_t curve) const { return static_cast<int>(levels_[curve].size()); }
  // The level each curve's estimates are made at (the finest on a fixed mesh).
  int chosen_level(std::uint32_t curve) const { return chosen_level_[curve]; }
  const std::vector<int>& chosen_levels() const { return chosen_level_; }
  void set_chosen_levels(const std::vector<int>& levels) { chosen_level_ = levels; }
  // Elements (non-empty knot spans) of a curve's mesh at its chosen level, and at any level.
  int elements_in_use(std::uint32_t curve) const;
  int level_elements(std::uint32_t curve, int level) const;
  // The nearest level to `level` in direction `step` (-1 coarser, +1 finer) whose mesh differs
  // from it: at least kDistinctLevelRatio times as many elements, or as few; -1 when none does. A
  // curve cut by many nodes into regions shorter than an element keeps those regions whole over
  // several levels, so consecutive levels can be the same mesh: their difference says nothing
  // about either's discretisation error.
  static constexpr double kDistinctLevelRatio = 1.5;
  int distinct_level(std::uint32_t curve, int level, int step) const;
  // Storage nodes below C1 (value or slope jumps) over all curves' finest meshes.
  std::size_t discontinuity_nodes() const;
  // Runs of whole curves holding at least kChunkCoefficients coefficients between them (the last
  // may hold fewer): curves [chunks[i], chunks[i + 1]), the pieces in which per-round work over
  // the storage is shared among threads.
  static constexpr std::size_t kChunkCoefficients = 8192;
  const std::vector<std::uint32_t>& curve_chunks() const { return curve_chunks_; }

  // Whether the side at block `offset` of `curve` holds a nonzero value in `values`.
  bool holds_power(const std::vector<double>& values, std::uint32_t curve, std::uint32_t offset) const;
  // Per-unit-length coefficients of `power` (per coefficient and channel, finest layout) by the
  // estimator, at each curve's chosen level, prolonged into the finest basis.
  void estimate(const std::vector<double>& power, std::vector<double>& coefficients) const;
  // The same with curve c at level levels[c] instead of its chosen one.
  void estimate(const std::vector<double>& power, std::vector<double>& coefficients,
                const std::vector<int>& levels) const;
  // The same for one curve's sides (coefficients already sized, and zero there).
  void estimate_curve(std::uint32_t curve, const std::vector<double>& power, std::vector<double>& coefficients) const;
  // One curve side's channel (`power[k * stride]`, finest layout) estimated at a level, in that
  // level's own basis (not prolonged).
  std::vector<double> estimate_in_level(std::uint32_t curve, int level, const double* power, std::size_t stride) const;
  // One curve side's channel at a level, prolonged into the finest basis (`coefficients[k * stride]`).
  void estimate_at_level(std::uint32_t curve, int level, const double* power, double* coefficients,
                         std::size_t stride) const;
  // The Hermite interpolant, in arc length, of the nodal values of a curve's hat basis at a level
  // (`values[k]`, that level's coefficients); C-1 nodes (double knots) keep their two values.
  HermiteReconstruction hermite_of(std::uint32_t curve, int level, const double* values) const;
  // Arc length from the start of the curve to curve parameter u.
  double arc_length_at(std::uint32_t curve, double u) const;

  // Automatic storage: each curve's level with the least estimated error, from the power received
  // by all photons and by the odd-numbered half of them (docs/storage-mesh.md, automatic storage).
  // `variance_factor` multiplies the variance the halves' difference shows (1: independent
  // halves; less for halves stratified against each other, Solver::sum_odd_parts).
  void choose_levels(const std::vector<double>& received, const std::vector<double>& half,
                     double variance_factor = 1.0);

 private:
  // choose_levels' steps: a curve's reflected power from all photons and from each half, and the
  // level of least estimated error for it.
  struct ReflectedPower;
  ReflectedPower reflected_power(std::uint32_t curve, const std::vector<double>& received,
                                 const std::vector<double>& half) const;
  int best_level(std::uint32_t curve, const ReflectedPower& reflected, double variance_factor) const;

  struct Level {
    CurveStorage storage;
    Restriction restriction;  // from the finest level
  };
  void estimate_on(const CurveStorage& storage, const double* power, double* coefficients, std::size_t stride) const;
  // The blocks of every curve side that emits or reflects, in curve order, front before back, and
  // the runs of curves that share per-round work.
  void lay_out_blocks(const Scene& scene);

  const Scene* scene_ = nullptr;
  BasisKind basis_ = BasisKind::Cubic;
  Estimator estimator_ = Estimator::Galerkin;
  int channels_ = 1;
  std::vector<CurveStorage> storage_;       // the finest level of each curve
  std::vector<std::vector<Level>> levels_;  // each curve's coarser levels, coarse to fine
  std::vector<int> chosen_level_;           // levels_[c].size() for the finest
  std::vector<std::uint32_t> block_offset_;
  std::vector<Spectrum> block_reflectivity_;
  std::vector<std::uint8_t> block_black_;
  std::vector<std::uint32_t> coefficient_block_;
  std::size_t coefficient_count_ = 0;
  std::vector<std::uint32_t> curve_chunks_;
};

}  // namespace flatland
