// A second cubic reconstruction (`--basis hermite`), closer to the text of "Cubic Monte Carlo
// Radiosity": nodal values along a curve parameter u (for the solver, the coefficients of a linear
// B-spline, with a double knot and so two values at a C-1 node) are interpolated by piecewise cubic
// Hermite pieces whose slopes come from neighbouring secants, with the continuity selected per node:
//   C1    one value and one slope shared by both pieces (three-point / Bessel estimate);
//   C0    one value, a slope on each side estimated only from the data on that side;
//   Jump  (C-1) a value and a one-sided slope on each side: the two pieces are independent.
// The slopes are then filtered so that every piece stays nonnegative (Dougherty, Edelman and Hyman
// 1989), and on request also monotone on monotone data (Fritsch and Carlson 1980).
// Accuracy: slopes from three nodes are exact for quadratics, so the error is O(h^3) for smooth
// data wherever a C0 or jump node has at least two pieces on each side. A piece between two
// non-C1 nodes has only its own two values: both slopes are its secant and it is the chord (O(h^2)).
#pragma once

#include <array>
#include <cstddef>
#include <span>
#include <vector>

#include "flatland/base/discrete_distribution.hpp"
#include "flatland/base/status.hpp"
#include "flatland/scene/scene.hpp"

namespace flatland {

struct HermiteInput {
  std::vector<double> u;      // nodes u_0 < u_1 < ... < u_n, both curve ends included, n >= 1
  std::vector<double> left;   // value at node i seen from the left (left[0] unused)
  std::vector<double> right;  // value at node i seen from the right (right[n] unused)
  // Per node; the two ends are ignored. At C0 and C1 nodes left and right should agree (a single
  // hat coefficient); if they do not, their mean is used.
  std::vector<Continuity> continuity;
  // Also apply the Fritsch-Carlson limiter: each piece is monotone wherever its data are, and a C1
  // node between secants of opposite sign (a local extremum of the data) gets a zero slope. Off by
  // default: it flattens the reconstruction at every extremum and costs accuracy there.
  bool monotone = false;
  // A closed curve: node n is node 0 again (u_n = u_0 + the period), continuity[0] is the closing
  // point's, and the pieces on both sides of it are neighbours (two-sided slopes there). Unless
  // it is a jump, the value there is the mean of left[n] and right[0].
  bool periodic = false;
};

// Sizes agree, nodes are finite and strictly increasing, values are finite (not NaN or infinite);
// the message names the first offending field and index. Negative values are accepted: the
// reconstruction clamps them to zero (a Monte Carlo estimate or a Galerkin solve may dip below).
Status check_hermite_input(const HermiteInput& input);

// One cubic piece on [u0, u0 + width], for output and plotting: its end values and end slopes
// (in u). Its Bernstein coefficients in x = (u - u0) / width are
//   start_value, start_value + width start_slope / 3, end_value - width end_slope / 3, end_value,
// nonnegative by construction (the positivity filter; up to one rounding of width slope / 3,
// which the evaluation clamps).
struct HermitePiece {
  double u0 = 0.0;
  double width = 0.0;
  double start_value = 0.0;
  double end_value = 0.0;
  double start_slope = 0.0;
  double end_slope = 0.0;
};

class HermiteReconstruction {
 public:
  HermiteReconstruction() = default;
  // Requires check_hermite_input(input).ok() (asserted in debug builds).
  explicit HermiteReconstruction(const HermiteInput& input);

  std::size_t pieces() const { return pieces_.size(); }
  const HermitePiece& piece(std::size_t i) const { return pieces_[i]; }
  double u_begin() const { return pieces_.front().u0; }
  double u_end() const { return pieces_.back().u0 + pieces_.back().width; }

  // The reconstruction at u, clamped into [u_begin, u_end]. At an interior node the right piece's
  // value, at the last node the last piece's. Never negative, also under rounding (evaluated from
  // nonnegative Bernstein coefficients), and exactly constant on constant data.
  double evaluate(double u) const;
  // evaluate at every u of an increasing sequence (out[i] at u[i]), walking the pieces in order.
  void evaluate_increasing(std::span<const double> u, double* out) const;
  // d/du of the reconstruction, with the same choice of piece as evaluate.
  double derivative(double u) const;

  // Integral over [u_begin, u_end] in u (in the curve parameter: no arc-length Jacobian), and per
  // piece: width (f0 + f1) / 2 + width^2 (d0 - d1) / 12 (exact for the cubic).
  double integral() const { return distribution_.total(); }
  double piece_integral(std::size_t i) const { return piece_integral_[i]; }

  // u with density evaluate(u) / integral(): u1 chooses a piece by its integral, u2 the place
  // inside it by inverting the piece's CDF (both uniform in [0,1)). With no mass at all (every
  // value zero) u is uniform on [u_begin, u_end], so a caller never sees NaN.
  double sample(double u1, double u2) const;
  // The density of sample: evaluate(u) / integral() inside [u_begin, u_end], else 0.
  double pdf(double u) const;

 private:
  std::size_t find_piece(double u) const;

  std::vector<HermitePiece> pieces_;
  std::vector<std::array<double, 4>> bernstein_;  // piece i in x = (u - u0) / width in [0,1]
  std::vector<double> piece_integral_;
  DiscreteDistribution distribution_;  // over piece_integral_
};

}  // namespace flatland
