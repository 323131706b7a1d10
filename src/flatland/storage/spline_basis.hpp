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
inline int degree_of(BasisKind kind) { return kind == BasisKind::Constant ? 0 : kind == BasisKind::Cubic ? 3 : 1; }

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
  static SplineBasis periodic(int degree, double u_begin, double u_end, std::span<const MeshNode> nodes,
                              Continuity closing);

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

}  // namespace flatland
