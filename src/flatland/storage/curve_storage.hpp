// The storage mesh of a curve: where illumination lives along it (its spline basis, the nodes
// where the illumination may jump or kink), the integrals that turn deposits into power per unit
// length, and the mass matrix and local weights the estimators use (estimators.hpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "flatland/scene/scene.hpp"
#include "flatland/storage/basis_sampler.hpp"
#include "flatland/storage/spline_basis.hpp"

namespace flatland {

// The storage mesh of one curve: its basis and the integrals of each basis function over arc
// length (the lumped "areas" that turn deposited power into power per unit length).
struct CurveStorage {
  SplineBasis basis;
  std::vector<double> basis_length;  // integral of phi_k ds over the curve
  std::vector<MeshNode> nodes;       // interior nodes (joints and element boundaries)
  BasisSampler sampler;              // u with density phi_k(u) in the curve parameter
  std::vector<double> speed_bound;   // >= |C'(u)| over the support of phi_k
  // A closed curve's storage is periodic (basis.is_periodic()) unless its closing joint is a jump;
  // `closing` is the continuity at the closing point (Jump on open curves).
  Continuity closing = Continuity::Jump;
  // Cholesky factor L of the mass matrix M_kl = integral(phi_k phi_l ds) in envelope storage: row
  // k holds L_(k, mass_first[k]) .. L_(k, k) from mass_cholesky[mass_offset[k]]. Banded with
  // half-width `degree` on a clamped basis; on a periodic one the last `degree` rows also reach
  // back to column 0 (the functions that straddle the closing point), and so does L.
  std::vector<double> mass_cholesky;
  std::vector<std::size_t> mass_first;
  std::vector<std::size_t> mass_offset;
  // The local estimator (build_local_estimator; empty until built): coefficient k is
  // sum of local_weight[i] p_(local_index[i]) for i in [local_first[k], local_first[k + 1]).
  std::vector<std::size_t> local_first;
  std::vector<std::uint32_t> local_index;
  std::vector<double> local_weight;
  // The polynomial degree the local estimator reproduces on each coefficient (lower than asked
  // only where a region between discontinuity nodes holds too few basis functions).
  std::vector<std::int8_t> local_degree;
};

// integral(phi_k(u) E(u) ds) for every k, with E the curve's emittance profile factor (one
// without a profile, which gives basis_length): the emitted power each basis function starts with.
std::vector<double> project_emittance_profile(const Scene& scene, const Curve& curve, const CurveStorage& storage);

// How many elements build_curve_storage gives a segment of arc length `segment_length` on a curve
// of length `curve_length` for `elements` per curve, before the 2^subdivisions split: its share of
// `elements` by arc length, rounded, at least one (the segment's element length is its length
// over this; regions between extra nodes round their own share up, see below).
int segment_elements(int elements, double segment_length, double curve_length);

// About `elements` elements per curve, shared among its segments in proportion to their arc
// length (at least one each). A closed curve whose closing joint is not a jump gets a periodic
// basis, with enough elements that no function overlaps itself around the loop (at least
// 2 degree + 2 knots in the period). Joints take the curve's joint continuity (or
// `smooth_joints`: all C1, the no-discontinuity baseline); element boundaries inside a segment are
// C1 (the most a piecewise cubic with selected discontinuities offers). `extra` nodes (increasing
// u, inside the curve) are added with their own continuity; one that falls on a joint or another
// extra node within 1e-9 of the curve parameter lowers that node's continuity instead (on a closed
// curve, one at u = 0 or u = segment_count lowers the closing joint's). The joints and extra nodes
// cut each segment into regions, each split into elements of equal arc length no longer than the
// segment's (without extra nodes: the segment split evenly).
// `subdivisions` splits every element into 2^subdivisions of equal arc length (a region shorter
// than half the segment's elements at that split stays whole until they are as short as it is):
// storages of one curve built with the same elements and extra nodes and increasing subdivisions
// nest (each coarse basis function is a combination of fine ones; see Restriction).
CurveStorage build_curve_storage(const Scene& scene, const Curve& curve, BasisKind kind, int elements,
                                 bool smooth_joints = false, std::span<const MeshNode> extra = {},
                                 int subdivisions = 0);

// The arc length of the longest element build_curve_storage makes with these arguments.
double longest_element(const Scene& scene, const Curve& curve, int elements, bool smooth_joints,
                       std::span<const MeshNode> extra, int subdivisions);

}  // namespace flatland
