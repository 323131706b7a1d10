// Drawing a place from one storage basis function: the density of reconstructed photon origins is
// a sum of basis functions, each drawn by inversion (or, for random numbers, as a sum over a
// simplex).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "flatland/storage/spline_basis.hpp"

namespace flatland {

// Samples u with density phi_k(u) / integral(phi_k du) for any basis function k: a piece (a
// non-empty knot span of the support) by its mass, then the inverse of the piece's CDF, a
// polynomial one degree higher than phi_k, by Newton's method safeguarded by bisection.
class BasisSampler {
 public:
  BasisSampler() = default;
  explicit BasisSampler(const SplineBasis& basis);

  // u1 chooses the piece, u2 the place inside it (both uniform in [0,1)). On a periodic basis u is
  // wrapped into [u_begin, u_end).
  double sample(std::size_t k, double u1, double u2) const;
  // The same density from degree + 1 uniforms in [0,1), without inverting a CDF: the B-spline on
  // knots t_0 <= .. <= t_(p+1), over its integral, is the density of sum lambda_i t_i for lambda
  // uniform on the p + 1 simplex (Curry and Schoenberg), and the spacings of p + 1 sorted uniforms
  // are such a lambda (docs/method.md, "Drawing from a basis function"). A few operations instead
  // of a Newton loop, but it maps the unit cube onto the support less smoothly than the inversion,
  // so quasi-Monte Carlo points keep sample().
  double sample_simplex(std::size_t k, const std::array<double, 4>& uniforms) const;
  int degree() const { return degree_; }
  // Asks the memory system for what drawing function k will read: its pieces (`inversion`, for
  // sample()) or its knots (sample_simplex()). No effect on any result.
  void prefetch(std::size_t k, bool inversion) const;
  // The density phi_k(u) / integral(phi_k du).
  double pdf(std::size_t k, double u) const;
  // integral(phi_k du) over the support.
  double mass(std::size_t k) const;

 private:
  struct Piece {
    double u0 = 0.0;
    double width = 0.0;
    std::array<double, 4> power{};  // phi_k(u0 + x width) = sum_i power[i] x^i, x in [0,1]
    // The piece's CDF in x (unnormalised) at x = j / kTable: brackets the inversion so that one
    // or two Newton steps from a linear interpolation finish it.
    std::array<double, 9> table{};
  };
  static constexpr int kTable = 8;
  double wrap(double u) const;  // into [u_begin, u_end) on a periodic basis
  bool periodic_ = false;
  int degree_ = 0;
  double u_begin_ = 0.0;
  double u_end_ = 1.0;
  std::vector<double> knots_;               // the basis's (function k on knots_[k] .. knots_[k + degree + 1])
  std::vector<std::uint32_t> first_piece_;  // pieces of k: [first_piece_[k], first_piece_[k+1])
  std::vector<Piece> pieces_;
  // Per piece, the mass of its function's pieces up to and including it: apart from the pieces,
  // so that choosing one reads a cache line or two, not one per piece.
  std::vector<double> cumulative_;
};

}  // namespace flatland
