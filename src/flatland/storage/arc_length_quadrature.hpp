// The arc-length quadrature every integral over a curve's storage mesh is made with (the basis
// functions' lengths, the mass matrix, the emitted power per function, the local estimator's
// moments): internal to storage/.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include "flatland/base/quadrature.hpp"
#include "flatland/scene/scene.hpp"
#include "flatland/storage/spline_basis.hpp"

namespace flatland::storage_detail {

// Visits every quadrature point of the curve's storage mesh: four 8-point Gauss-Legendre panels
// per non-empty knot span of [u_begin, u_end) (each span lies in one segment), with the arc-length
// weight w = GL weight x |C'(u)| du and the basis functions alive there (values[j] for function
// index[j], j = 0..degree; distinct, as a periodic basis has at least degree + 1 functions), and
// the span k (function index[j] is function k - degree + j of the extended numbering, whose
// support starts at knots[k - degree + j]). Integrals of phi_k times smooth functions along arc
// length are sums over these points.
template <typename Visit>
void for_each_quadrature_point(const Scene& scene, const Curve& curve, const SplineBasis& basis, Visit visit) {
  constexpr int kPanels = 4;
  const std::vector<double>& knots = basis.knots();
  const int p = basis.degree();
  std::array<double, SplineBasis::kMaxDegree + 1> values{};
  std::array<std::size_t, SplineBasis::kMaxDegree + 1> index{};
  for (std::size_t k = basis.first_span(); k < basis.end_span(); ++k) {
    const double a = knots[k];
    const double b = knots[k + 1];
    if (!(b > a)) continue;
    const auto segment_index =
        static_cast<std::uint32_t>(std::min<double>(std::floor(0.5 * (a + b)), curve.segment_count - 1));
    const SceneSegment& segment = scene.segments[curve.first_segment + segment_index];
    for (int j = 0; j <= p; ++j)
      index[static_cast<std::size_t>(j)] = basis.index(k - static_cast<std::size_t>(p) + static_cast<std::size_t>(j));
    for (int panel = 0; panel < kPanels; ++panel) {
      const double pa = a + (b - a) * panel / kPanels;
      const double pb = a + (b - a) * (panel + 1) / kPanels;
      const double half = 0.5 * (pb - pa);
      for (std::size_t g = 0; g < gauss::kNodes8.size(); ++g) {
        const double u = 0.5 * (pa + pb) + half * gauss::kNodes8[g];
        const double weight =
            gauss::kWeights8[g] * half * length(derivative(segment.geometry.shape, u - segment_index));
        basis.evaluate_in_span(k, u, values.data());
        visit(u, weight, index, values, k);
      }
    }
  }
}

}  // namespace flatland::storage_detail
