#include "flatland/storage/curve_storage.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>

#include "flatland/storage/arc_length_quadrature.hpp"

namespace flatland {

using storage_detail::for_each_quadrature_point;

int segment_elements(int elements, double segment_length, double curve_length) {
  return std::max(1, static_cast<int>(std::lround(elements * segment_length / curve_length)));
}

namespace {

// The storage nodes of a curve for about `wanted` elements. The fixed nodes (joints, and the extra
// nodes: events, contacts) cut each segment into regions; each region is split into elements of
// equal arc length, as many as keep them no longer than the segment's (below), times
// 2^subdivisions. Returns the closing continuity (Jump on an open curve).
//
// Splitting regions rather than the segment keeps every element between half and all of the
// segment's element length at its level, unless it is a whole region shorter than that: an extra
// node merged into a mesh split evenly over the segment could land a hair from an element
// boundary and leave a sliver (an event 0.0009 from a boundary of elements 0.0156 long on the
// round-occluder floor), whose short secants steer the Hermite reconstruction's slopes and whose
// short supports catch few photons. A region's count doubles with each subdivision (or stays the
// same while a short region waits), and s = start + length j / pieces is the same double for
// (j, pieces) and (2 j, 2 pieces), so the meshes nest. A segment without extra nodes is one
// region, split exactly as an even split of the segment.
Continuity place_nodes(const Scene& scene, const Curve& curve, int wanted, int subdivisions, bool smooth_joints,
                       std::span<const MeshNode> extra, std::vector<MeshNode>& nodes) {
  const std::uint32_t segment_count = curve.segment_count;
  Continuity closing = !curve.closed ? Continuity::Jump : smooth_joints ? Continuity::C1 : curve.joints.back();
  // The fixed nodes: joints, then the extra nodes merged in (one within 1e-9 of a fixed node
  // lowers its continuity; one at the closing point of a closed curve lowers the closing joint's).
  std::vector<MeshNode> fixed;
  for (std::uint32_t i = 1; i < segment_count; ++i)
    fixed.push_back({static_cast<double>(i), smooth_joints ? Continuity::C1 : curve.joints[i - 1]});
  for (const MeshNode& node : extra) {
    if (curve.closed && (std::fabs(node.u) <= 1e-9 || std::fabs(node.u - segment_count) <= 1e-9)) {
      closing = std::min(closing, node.continuity);
      continue;
    }
    if (!(node.u > 0.0 && node.u < segment_count)) continue;
    const auto at =
        std::lower_bound(fixed.begin(), fixed.end(), node.u, [](const MeshNode& a, double u) { return a.u < u; });
    auto merge = [&](std::vector<MeshNode>::iterator existing) {
      if (existing == fixed.end() || std::fabs(existing->u - node.u) > 1e-9) return false;
      existing->continuity = std::min(existing->continuity, node.continuity);
      return true;
    };
    if (merge(at) || (at != fixed.begin() && merge(at - 1))) continue;
    fixed.insert(at, node);
  }
  // Each region between consecutive fixed nodes (and the curve's ends), split evenly in arc length.
  nodes.clear();
  std::size_t next_fixed = 0;
  for (std::uint32_t i = 0; i < segment_count; ++i) {
    const SceneSegment& segment = scene.segments[curve.first_segment + i];
    const Cubic& shape = segment.geometry.shape;
    const double segment_pieces = segment_elements(wanted, segment.length, curve.length);
    const double element = segment.length / segment_pieces;  // at subdivision 0
    if (i > 0) nodes.push_back(fixed[next_fixed++]);         // the joint
    double region_start = 0.0;                               // arc length from the segment's start
    for (;;) {
      const bool inside = next_fixed < fixed.size() && fixed[next_fixed].u < i + 1.0;
      const double region_end = inside ? std::clamp(segment.arc_length.length_at(shape, fixed[next_fixed].u - i),
                                                    region_start, segment.length)
                                       : segment.length;
      const double region = region_end - region_start;
      // As many elements as keep them no longer than the segment's (its share of the segment's
      // elements, rounded up), and the levels that pass before a region shorter than half an
      // element is split at all: its elements are then between half and all of the level's
      // element length, never a sliver of it. (The tolerances keep a region that is the whole
      // segment at exactly the segment's elements.)
      const int share = std::max(1, static_cast<int>(std::ceil(segment_pieces * region / segment.length - 1e-9)));
      int delay = 0;
      while (delay < subdivisions && region / share * std::ldexp(1.0, delay + 1) <= element * (1.0 + 1e-9)) ++delay;
      const int pieces = share << (subdivisions - delay);
      for (int j = 1; j < pieces; ++j) {
        const double s = region_start + region * j / pieces;
        nodes.push_back({i + segment.arc_length.parameter_at(shape, s), Continuity::C1});
      }
      if (!inside) break;
      nodes.push_back(fixed[next_fixed++]);
      region_start = region_end;
    }
  }
  return closing;
}

}  // namespace

double longest_element(const Scene& scene, const Curve& curve, int elements, bool smooth_joints,
                       std::span<const MeshNode> extra, int subdivisions) {
  std::vector<MeshNode> nodes;
  place_nodes(scene, curve, std::max(elements, 1), subdivisions, smooth_joints, extra, nodes);
  double longest = 0.0;
  double previous = 0.0;
  for (const MeshNode& node : nodes) {
    const double s = arc_length_at(scene, curve, node.u);
    longest = std::max(longest, s - previous);
    previous = s;
  }
  return std::max(longest, curve.length - previous);
}

CurveStorage build_curve_storage(const Scene& scene, const Curve& curve, BasisKind kind, int elements,
                                 bool smooth_joints, std::span<const MeshNode> extra, int subdivisions) {
  CurveStorage storage;
  const std::uint32_t segment_count = curve.segment_count;
  const int degree = degree_of(kind);
  const int wanted = std::max(elements, 1);
  storage.closing = place_nodes(scene, curve, wanted, subdivisions, smooth_joints, extra, storage.nodes);
  if (storage.closing == Continuity::Jump) {
    storage.basis = SplineBasis(degree, 0.0, static_cast<double>(segment_count), storage.nodes);
  } else {
    // Periodic: K knots in the period (with multiplicity). At least 2 degree + 2 of them keep
    // every function distinct from its neighbours around the loop (a function never meets its
    // own other end, and the mass matrix keeps its envelope): refine until there are.
    auto knots_in_period = [&] {
      int count = SplineBasis::multiplicity(degree, storage.closing);
      for (const MeshNode& node : storage.nodes) count += SplineBasis::multiplicity(degree, node.continuity);
      return count;
    };
    while (knots_in_period() < 2 * degree + 2) {
      ++subdivisions;
      storage.closing = place_nodes(scene, curve, wanted, subdivisions, smooth_joints, extra, storage.nodes);
    }
    storage.basis =
        SplineBasis::periodic(degree, 0.0, static_cast<double>(segment_count), storage.nodes, storage.closing);
  }

  // Integrals of phi_k |C'(u)| du and the mass matrix, in one pass of the quadrature: four
  // 8-point Gauss-Legendre panels per span integrate the polynomial-times-speed products to far
  // below Monte Carlo noise. The mass matrix is kept in envelope storage (row k from column
  // mass_first[k]), then factored in place: L has the same envelope as M. B-splines more than p
  // apart have disjoint supports, so a clamped basis is banded; on a periodic one the functions
  // straddling the closing point (the first p) meet the last p, whose rows then reach back to
  // column 0.
  const int p = storage.basis.degree();
  const std::size_t n = storage.basis.size();
  const auto pu = static_cast<std::size_t>(p);
  storage.mass_first.assign(n, 0);
  storage.mass_offset.assign(n + 1, 0);
  for (std::size_t row = 0; row < n; ++row) {
    const bool wraps = storage.basis.is_periodic() && row + pu >= n;
    storage.mass_first[row] = wraps || row < pu ? 0 : row - pu;
    storage.mass_offset[row + 1] = storage.mass_offset[row] + (row - storage.mass_first[row] + 1);
  }
  std::vector<double>& envelope = storage.mass_cholesky;
  envelope.assign(storage.mass_offset[n], 0.0);
  auto entry = [&](std::size_t row, std::size_t col) -> double& {  // mass_first[row] <= col <= row
    return envelope[storage.mass_offset[row] + col - storage.mass_first[row]];
  };
  storage.basis_length.assign(n, 0.0);
  for_each_quadrature_point(scene, curve, storage.basis,
                            [&](double, double weight, const auto& index, const auto& values, std::size_t) {
                              for (std::size_t j = 0; j <= pu; ++j)
                                storage.basis_length[index[j]] += weight * values[j];
                              for (std::size_t i = 0; i <= pu; ++i)
                                for (std::size_t j = 0; j <= pu; ++j)
                                  if (index[j] <= index[i]) entry(index[i], index[j]) += weight * values[i] * values[j];
                            });
  storage.sampler = BasisSampler(storage.basis);
  // Envelope Cholesky: L_kk = sqrt(M_kk - sum L_kj^2), L_ik = (M_ik - sum L_ij L_kj) / L_kk, the
  // sums over the columns both rows hold.
  for (std::size_t row = 0; row < n; ++row) {
    for (std::size_t col = storage.mass_first[row]; col <= row; ++col) {
      double sum = entry(row, col);
      const std::size_t inner = std::max(storage.mass_first[row], storage.mass_first[col]);
      for (std::size_t j = inner; j < col; ++j) sum -= entry(row, j) * entry(col, j);
      entry(row, col) = col == row ? std::sqrt(std::max(sum, 0.0)) : sum / entry(col, col);
    }
  }
  // Speed bound over each basis function's support: on each segment it touches, the bound over
  // the part it touches (on a periodic basis the support may reach a period before or after
  // [0, segment_count)). A bound local to a fine mesh's short support is nearly the speed itself,
  // so the origins' rejection on speed seldom draws again.
  storage.speed_bound.assign(n, 0.0);
  const std::vector<double>& knots = storage.basis.knots();
  const double period = static_cast<double>(segment_count);
  // Only the segments under a support (a few, with one more on each side against rounding), not
  // all of the curve's, which would be quadratic in the segments of a long curve.
  const auto near = [&](double at) { return static_cast<std::uint32_t>(std::clamp(at, 0.0, period)); };
  for (std::size_t k = 0; k < n; ++k) {
    const double begin = knots[k];
    const double end = knots[k + pu + 1];
    for (const double shift : {0.0, -period, period}) {
      if (shift != 0.0 && !storage.basis.is_periodic()) continue;
      for (std::uint32_t i = near(std::floor(begin - shift) - 1.0); i < near(std::ceil(end - shift) + 1.0); ++i)
        if (i + 1.0 + shift > begin && i + shift < end) {
          const SceneSegment& segment = scene.segments[curve.first_segment + i];
          const double t0 = std::clamp(begin - i - shift, 0.0, 1.0);
          const double t1 = std::clamp(end - i - shift, 0.0, 1.0);
          // Both are upper bounds there; over a long part the segment's may be the lower.
          const double bound = segment.geometry.kind == SegmentKind::Line
                                   ? segment.speed_bound
                                   : std::min(segment.speed_bound, speed_bound(segment.geometry.shape, t0, t1));
          storage.speed_bound[k] = std::max(storage.speed_bound[k], bound);
        }
    }
  }
  return storage;
}

std::vector<double> project_emittance_profile(const Scene& scene, const Curve& curve, const CurveStorage& storage) {
  if (curve.emittance_profile.empty()) return storage.basis_length;
  // The same quadrature as basis_length, with the profile (a cubic in t) in the integrand.
  std::vector<double> result(storage.basis.size(), 0.0);
  for_each_quadrature_point(scene, curve, storage.basis,
                            [&](double u, double weight, const auto& index, const auto& values, std::size_t) {
                              const double emitted = weight * emittance_factor(curve, u);
                              for (std::size_t j = 0; j <= static_cast<std::size_t>(storage.basis.degree()); ++j)
                                result[index[j]] += emitted * values[j];
                            });
  return result;
}

}  // namespace flatland
