// Where illumination lives: along each curve, a spline of degree p (0 constant, 1 linear, 3 cubic)
// in the curve parameter u = segment index + t, written in a B-spline basis {phi_k}.
//
// The knot multiplicity at a node encodes the continuity chosen there: multiplicity m gives
// C^(p-m), so for cubics m = 2 is C1, 3 is C0 and 4 is C-1 (a value jump); a linear spline is C0
// at single knots and jumps at double ones; a constant spline jumps everywhere. B-splines are
// nonnegative and sum to one, so deposits weighted by phi_k(u) conserve energy exactly and
// nonnegative coefficients give a nonnegative function.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "flatland/scene.hpp"

namespace flatland {

// Hermite stores nodal values in a linear B-spline basis (hats; a double knot at a C-1 node keeps
// separate values on each side) and reconstructs a piecewise cubic Hermite interpolant from them
// (src/flatland/hermite.hpp): the paper's "cubic through the control points" read literally.
enum class BasisKind { Constant, Linear, Cubic, Hermite };

const char* to_string(BasisKind kind);
inline int degree_of(BasisKind kind) {
  return kind == BasisKind::Constant ? 0 : kind == BasisKind::Cubic ? 3 : 1;
}

// A node of the storage mesh: an interior breakpoint in u and the continuity wanted there.
struct MeshNode {
  double u = 0.0;
  Continuity continuity = Continuity::C1;
};

class SplineBasis {
 public:
  static constexpr int kMaxDegree = 3;

  SplineBasis() = default;
  // Breakpoints run from u_begin to u_end; `nodes` are the interior ones, increasing.
  SplineBasis(int degree, double u_begin, double u_end, std::span<const MeshNode> nodes);

  int degree() const { return degree_; }
  std::size_t size() const { return size_; }
  const std::vector<double>& knots() const { return knots_; }
  double u_begin() const { return knots_.front(); }
  double u_end() const { return knots_.back(); }

  // The degree+1 basis functions that may be nonzero at u (clamped into [u_begin, u_end]):
  // writes phi_first(u) .. phi_(first+degree)(u) into values and returns first.
  std::size_t evaluate(double u, double* values) const;

  // The multiplicity a node of the given continuity gets in a spline of this degree.
  static int multiplicity(int degree, Continuity continuity);

 private:
  std::size_t find_span(double u) const;

  int degree_ = 0;
  std::size_t size_ = 0;
  std::vector<double> knots_;
};

// Samples u with density phi_k(u) / integral(phi_k du) for any basis function k: a piece (a
// non-empty knot span of the support) by its mass, then the inverse of the piece's CDF, a
// polynomial one degree higher than phi_k, by Newton's method safeguarded by bisection.
class BasisSampler {
 public:
  BasisSampler() = default;
  explicit BasisSampler(const SplineBasis& basis);

  // u1 chooses the piece, u2 the place inside it (both uniform in [0,1)).
  double sample(std::size_t k, double u1, double u2) const;
  // The density phi_k(u) / integral(phi_k du).
  double pdf(std::size_t k, double u) const;
  // integral(phi_k du) over the support.
  double mass(std::size_t k) const;

 private:
  struct Piece {
    double u0 = 0.0;
    double width = 0.0;
    double cumulative = 0.0;  // mass of this basis function's pieces up to and including this one
    std::array<double, 4> power{};  // phi_k(u0 + x width) = sum_i power[i] x^i, x in [0,1]
    // The piece's CDF in x (unnormalised) at x = j / kTable: brackets the inversion so that one
    // or two Newton steps from a linear interpolation finish it.
    std::array<double, 9> table{};
  };
  static constexpr int kTable = 8;
  std::vector<std::uint32_t> first_piece_;  // pieces of k: [first_piece_[k], first_piece_[k+1])
  std::vector<Piece> pieces_;
};

// The storage mesh of one curve: its basis and the integrals of each basis function over arc
// length (the lumped "areas" that turn deposited power into power per unit length).
struct CurveStorage {
  SplineBasis basis;
  std::vector<double> basis_length;  // integral of phi_k ds over the curve
  std::vector<MeshNode> nodes;       // interior nodes (joints and element boundaries)
  BasisSampler sampler;              // u with density phi_k(u) in the curve parameter
  std::vector<double> speed_bound;   // >= |C'(u)| over the support of phi_k
  // Cholesky factor of the mass matrix M_kl = integral(phi_k phi_l ds), banded with half-width
  // `degree`: row k holds L_(k, k-degree) .. L_(k, k) in band[k * (degree + 1) ...].
  std::vector<double> mass_cholesky;
};

// integral(phi_k(u) E(u) ds) for every k, with E the curve's emittance profile factor (one
// without a profile, which gives basis_length): the emitted power each basis function starts with.
std::vector<double> project_emittance_profile(const Scene& scene, const Curve& curve,
                                              const CurveStorage& storage);

// The Galerkin (L2) estimate from deposited powers p_k: the spline whose moments against every
// phi_k equal the deposits, M b = p. Exact for functions in the space and conservative, but it can
// go negative near sharp features: negative coefficients are clamped to zero and the rest scaled so
// that sum_k b_k integral(phi_k ds) still equals sum_k p_k. `stride` is the distance between
// consecutive coefficients of one channel (the channel count of an interleaved layout).
void galerkin_estimate(const CurveStorage& storage, const double* deposits, double* coefficients,
                       std::size_t stride);

// About `elements` elements per curve, shared among its segments in proportion to their arc
// length (at least one each) and of equal arc length within a segment. Joints take the curve's
// joint continuity (or `smooth_joints`: all C1, the no-discontinuity baseline); element
// boundaries inside a segment are C1 (the most a piecewise cubic with selected discontinuities
// offers). `extra` nodes (increasing u, inside the curve) are added with their own continuity; one
// that falls on an existing node within 1e-9 of the curve parameter lowers that node's continuity
// instead.
CurveStorage build_curve_storage(const Scene& scene, const Curve& curve, BasisKind kind,
                                 int elements, bool smooth_joints = false,
                                 std::span<const MeshNode> extra = {});

}  // namespace flatland
