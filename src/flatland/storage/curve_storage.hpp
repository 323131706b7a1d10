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
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "flatland/scene/scene.hpp"

namespace flatland {

// Hermite stores nodal values in a linear B-spline basis (hats; a double knot at a C-1 node keeps
// separate values on each side) and reconstructs a piecewise cubic Hermite interpolant from them
// (src/flatland/storage/hermite.hpp): the paper's "cubic through the control points" read literally.
enum class BasisKind { Constant, Linear, Cubic, Hermite };

const char* to_string(BasisKind kind);
// "constant", "linear", "cubic" or "hermite"; nullopt for anything else.
std::optional<BasisKind> basis_from_string(std::string_view name);
inline int degree_of(BasisKind kind) {
  return kind == BasisKind::Constant ? 0 : kind == BasisKind::Cubic ? 3 : 1;
}

// A node of the storage mesh: an interior breakpoint in u and the continuity wanted there.
struct MeshNode {
  double u = 0.0;
  Continuity continuity = Continuity::C1;
};

// u moved by whole periods into [begin, end) (begin for a NaN or a value that rounds onto end).
double wrap_into_period(double u, double begin, double end);

class SplineBasis {
 public:
  static constexpr int kMaxDegree = 3;

  SplineBasis() = default;
  // Breakpoints run from u_begin to u_end; `nodes` are the interior ones, increasing. The basis is
  // clamped at both ends (degree + 1 knots there): the curve's ends are C-1.
  SplineBasis(int degree, double u_begin, double u_end, std::span<const MeshNode> nodes);
  // A periodic basis on [u_begin, u_end) for a closed curve: u_end is u_begin again, with the
  // continuity `closing` there (not Jump: that is the clamped basis). With K knots in a period
  // (the closing knot and the nodes, counted with multiplicity) there are K functions; those of
  // the first `degree` spans straddle the closing point. Needs K >= degree + 1.
  static SplineBasis periodic(int degree, double u_begin, double u_end,
                              std::span<const MeshNode> nodes, Continuity closing);

  int degree() const { return degree_; }
  std::size_t size() const { return size_; }
  bool is_periodic() const { return periodic_; }
  // The knot vector. Clamped: size() + degree + 1 knots. Periodic: the knots of one period
  // extended by `degree` knots on each side (shifted by the period), size() + 2 degree + 1 knots;
  // function k is supported on [knots[k], knots[k + degree + 1]], wrapped into [u_begin, u_end).
  const std::vector<double>& knots() const { return knots_; }
  double u_begin() const { return knots_[static_cast<std::size_t>(degree_)]; }
  double u_end() const { return knots_[end_span()]; }
  // The spans (indices into knots()) that cover [u_begin, u_end): [first_span(), end_span()).
  std::size_t first_span() const { return static_cast<std::size_t>(degree_); }
  std::size_t end_span() const { return periodic_ ? size_ + static_cast<std::size_t>(degree_) : size_; }
  // The index of function first + j (j <= degree) as returned by evaluate: wraps on a periodic
  // basis.
  std::size_t index(std::size_t i) const { return i >= size_ ? i - size_ : i; }
  // u wrapped into [u_begin, u_end) on a periodic basis, clamped on a clamped one.
  double wrap(double u) const;

  // The degree+1 basis functions that may be nonzero at u (clamped into [u_begin, u_end], or
  // wrapped on a periodic basis): writes phi_first(u) .. phi_(first+degree)(u) into values and
  // returns first; function first + j is index(first + j).
  std::size_t evaluate(double u, double* values) const;
  // The same in a given span (knots[span] <= u <= knots[span + 1], u not wrapped, and
  // span >= degree: the recursion reads `degree` knots on each side): the functions
  // span - degree .. span of the extended numbering (index() maps them to the basis).
  void evaluate_in_span(std::size_t span, double u, double* values) const;

  // The multiplicity a node of the given continuity gets in a spline of this degree.
  static int multiplicity(int degree, Continuity continuity);

  // The span holding u (u in [u_begin, u_end], not wrapped): the last non-empty span with
  // knots[span] <= u, the last span for u = u_end.
  std::size_t find_span(double u) const;

 private:
  // find_span's index: per unit interval of u from u_begin, 2 cells per span in it, each holding
  // the span at the cell's lower edge, so a lookup scans a span or two instead of bisecting.
  void build_span_grid();

  int degree_ = 0;
  std::size_t size_ = 0;
  bool periodic_ = false;
  std::vector<double> knots_;
  std::vector<std::uint32_t> unit_cells_;  // per unit interval, its first cell (+ the end)
  std::vector<std::uint32_t> cell_spans_;  // per cell, the span holding its lower edge
};

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
  std::vector<double> knots_;  // the basis's (function k on knots_[k] .. knots_[k + degree + 1])
  std::vector<std::uint32_t> first_piece_;  // pieces of k: [first_piece_[k], first_piece_[k+1])
  std::vector<Piece> pieces_;
  // Per piece, the mass of its function's pieces up to and including it: apart from the pieces,
  // so that choosing one reads a cache line or two, not one per piece.
  std::vector<double> cumulative_;
};

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
std::vector<double> project_emittance_profile(const Scene& scene, const Curve& curve,
                                              const CurveStorage& storage);

// Estimators turn deposited powers p_k (sum over photons of power x phi_k(hit), so that
// E[p_k] = integral(phi_k R ds) for the received power per unit length R) into coefficients b_k of
// R = sum_k b_k phi_k. `stride` is the distance between consecutive coefficients of one channel
// (the channel count of an interleaved layout). docs/method.md compares them.
//
// The Galerkin (L2) estimate: the spline whose moments against every phi_k equal the deposits,
// M b = p. It reproduces every function of the spline space, so its bias is O(h^(p+1)) up to the
// curve's ends and its discontinuity nodes, and sum_k b_k integral(phi_k ds) = sum_k p_k exactly
// (the functions sum to one). It can dip below zero next to sharp features and by noise; it is not
// clamped (see clamp_keeping_power).
void galerkin_estimate(const CurveStorage& storage, const double* deposits, double* coefficients,
                       std::size_t stride);

// The local quasi-interpolant (DESIGN: dual functionals): b_k = sum_j w_kj p_j over the 2w + 1
// deposits nearest to k (w = degree + 1; Hermite: 3) inside k's region between discontinuity
// nodes (C0 and C-1 nodes, the curve's ends), with the weights of least variance, for photons of
// locally uniform density, among those that are exact when R is a polynomial of degree q on the
// region: min w^T G w subject to V^T w = c, G the local Gram matrix, V_jm = integral(phi_j x^m ds)
// and c_m the target functional of x^m. With `nodal_values` false the target is the B-spline
// coefficient (the blossom of x^m at the function's interior knots, q = degree): the
// reconstruction's bias is O(h^(q+1)) everywhere, at the cost of a banded sparse product. With
// `nodal_values` true (hat functions only: Hermite storage) the target is R at the hat's peak with
// q = 3, the nodal values a cubic Hermite interpolant wants. A function that straddles a C0 node
// is estimated from each side and the two combined by inverse variance; one-sided windows near
// ends and nodes keep the window's size where the region allows, and a region too short for q + 1
// functions lowers q there.
void build_local_estimator(const Scene& scene, const Curve& curve, CurveStorage& storage,
                           bool nodal_values);
void local_estimate(const CurveStorage& storage, const double* deposits, double* coefficients,
                    std::size_t stride);

// Negative coefficients set to zero and the rest scaled so that sum_k b_k integral(phi_k ds) equals
// `power`: a nonnegative density holding a given power (the photon origins' sampling density).
// False, with every coefficient zero, when nothing positive is left to scale.
bool clamp_keeping_power(const CurveStorage& storage, double* coefficients, std::size_t stride,
                         double power);

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
CurveStorage build_curve_storage(const Scene& scene, const Curve& curve, BasisKind kind,
                                 int elements, bool smooth_joints = false,
                                 std::span<const MeshNode> extra = {}, int subdivisions = 0);

// The arc length of the longest element build_curve_storage makes with these arguments.
double longest_element(const Scene& scene, const Curve& curve, int elements, bool smooth_joints,
                       std::span<const MeshNode> extra, int subdivisions);

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
