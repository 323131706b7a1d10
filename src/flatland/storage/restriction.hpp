// Nested storage meshes: a coarse basis as combinations of a finer one (knot insertion), so that
// deposits made once on the finest mesh give every coarser level exactly.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "flatland/storage/spline_basis.hpp"

namespace flatland {

// Between nested bases (every knot of `coarse` is a knot of `fine` with at least its
// multiplicity): phi_coarse_i = sum_j R_ij phi_fine_j, with R >= 0 (knot insertion). Deposits
// restrict, p_coarse = R p_fine, because a photon's weights phi(hit) do; coefficients prolong,
// b_fine = R^T b_coarse, giving the same function. Stored by coarse rows.
struct Restriction {
  std::size_t fine_size = 0;
  std::vector<std::size_t> first;  // row i: entries [first[i], first[i + 1])
  std::vector<std::uint32_t> column;
  std::vector<double> weight;
};
// R by collocation: on each fine span the coarse functions alive there are polynomials, and the
// fine functions alive there interpolate them at degree + 1 points. Entries below 1e-14 are
// dropped (exact zeros up to rounding).
Restriction restriction_between(const SplineBasis& coarse, const SplineBasis& fine);
// The fine side is read or written with `stride` (an interleaved channel), the coarse side is
// contiguous.
void restrict_deposits(const Restriction& r, const double* fine, std::size_t stride, double* coarse);
void prolong_coefficients(const Restriction& r, const double* coarse, double* fine, std::size_t stride);

}  // namespace flatland
