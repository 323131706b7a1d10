#include "flatland/storage/hermite.hpp"

#include "flatland/base/roots.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <sstream>
#include <string>

namespace flatland {

namespace {

std::string describe(const char* field, std::size_t i, double value) {
  std::ostringstream text;
  text.precision(17);
  text << field << "[" << i << "] = " << value;
  return text.str();
}

// Slopes from three consecutive nodes x0 < x1 < x2, widths a = x1 - x0, b = x2 - x1 and secants
// p (over [x0, x1]) and q (over [x1, x2]). The parabola through the three points is
//   P(x) = y0 + p (x - x0) + c (x - x0)(x - x1),  c = (q - p) / (a + b),
// so P'(x) = p + c ((x - x0) + (x - x1)) and, at the three nodes,
//   P'(x0) = ((2a + b) p - a q) / (a + b)   one-sided, from the right  (Fornberg; de Boor ch. IV)
//   P'(x1) = (b p + a q) / (a + b)          centred: the Bessel / parabolic estimate
//   P'(x2) = ((a + 2b) q - b p) / (a + b)   one-sided, from the left.
// Each is exact for quadratic data (and so for constant and linear data): with values and slopes
// exact, a cubic Hermite piece reproduces quadratics, and in general the slopes are O(h^2) and the
// reconstruction O(h^3) (de Boor, A Practical Guide to Splines, ch. IV).
double slope_at_start(double a, double b, double p, double q) { return ((2.0 * a + b) * p - a * q) / (a + b); }
double slope_centred(double a, double b, double p, double q) { return (b * p + a * q) / (a + b); }
double slope_at_end(double a, double b, double p, double q) { return ((a + 2.0 * b) * q - b * p) / (a + b); }

// Linear interpolation written so that it returns a exactly when a == b (constant data stay
// exactly constant) and never leaves [min(a,b), max(a,b)] under rounding: for b < a,
// fl(b - a) >= -a and x fl(b - a) >= fl(b - a) for x in [0,1], so the sum is >= fl(a - a) = 0 when
// a, b >= 0 (rounding is monotone).
double lerp(double a, double b, double x) { return a + x * (b - a); }

// de Casteljau's algorithm on Bernstein coefficients b_0..b_(N-1) at x in [0,1]: repeated lerps,
// so nonnegative coefficients give a nonnegative value, exactly, and equal ones give that value.
// With N = 4 it also returns the derivative d/dx = 3 (q1 - q0) from the last two points.
template <std::size_t N>
double de_casteljau(std::array<double, N> b, double x, double* derivative = nullptr) {
  for (std::size_t level = N - 1; level > 0; --level) {
    if (level == 1 && derivative) *derivative = static_cast<double>(N - 1) * (b[1] - b[0]);
    for (std::size_t k = 0; k < level; ++k) b[k] = lerp(b[k], b[k + 1], x);
  }
  return b[0];
}

}  // namespace

Status check_hermite_input(const HermiteInput& input) {
  const std::size_t count = input.u.size();
  const auto fail = [](const std::string& what) -> Status { return Error{"hermite reconstruction: " + what}; };
  if (count < 2) return fail("u has " + std::to_string(count) + " nodes; at least 2 (the two curve ends) are needed");
  if (input.left.size() != count || input.right.size() != count || input.continuity.size() != count)
    return fail("u, left, right and continuity need one entry per node; they have " + std::to_string(count) + ", " +
                std::to_string(input.left.size()) + ", " + std::to_string(input.right.size()) + " and " +
                std::to_string(input.continuity.size()));
  for (std::size_t i = 0; i < count; ++i) {
    if (!std::isfinite(input.u[i])) return fail(describe("u", i, input.u[i]) + " is not finite");
    if (i > 0 && !(input.u[i] > input.u[i - 1]))
      return fail(describe("u", i, input.u[i]) + " does not exceed " + describe("u", i - 1, input.u[i - 1]) +
                  "; nodes must increase strictly");
    // left[0] and right[n] are never read.
    if (i > 0 && !std::isfinite(input.left[i])) return fail(describe("left", i, input.left[i]) + " is not finite");
    if (i + 1 < count && !std::isfinite(input.right[i]))
      return fail(describe("right", i, input.right[i]) + " is not finite");
  }
  return ok_status();
}

namespace {

// The data of a Hermite reconstruction, piece by piece (piece i spans [u_i, u_(i+1)]): widths,
// end values, secants and end slopes, brought from the input to the filtered slopes in steps.
struct HermitePieces {
  explicit HermitePieces(const HermiteInput& input)
      : input_(input),
        n(input.u.size() - 1),
        periodic_(input.periodic),
        closing_joined_(periodic_ && input.continuity[0] != Continuity::Jump),
        h(n),
        f0(n),
        f1(n),
        secant(n),
        d0(n),
        d1(n) {
    for (std::size_t i = 0; i < n; ++i) {
      h[i] = input.u[i + 1] - input.u[i];
      f0[i] = value_from_right(i);
      f1[i] = value_from_left(i + 1);
      secant[i] = (f1[i] - f0[i]) / h[i];
    }
  }

  void initial_slopes();
  void keep_positive();
  void keep_monotone();

  // Neighbouring pieces; on a periodic input piece n - 1 is followed by piece 0 (node n is node 0).
  std::size_t before(std::size_t i) const { return i == 0 ? n - 1 : i - 1; }
  std::size_t after(std::size_t i) const { return i + 1 == n ? 0 : i + 1; }
  // A node whose slope is shared by its two pieces.
  bool smooth(std::size_t node) const {
    if (periodic_) return input_.continuity[node == n ? 0 : node] == Continuity::C1;
    return node > 0 && node < n && input_.continuity[node] == Continuity::C1;
  }
  // Values: negative inputs (a noisy estimate, a Galerkin solve) are clamped to zero first, so the
  // positivity filter has nonnegative data to work with. At C0 and C1 nodes one value is used on
  // both sides (the mean, should left and right differ); at a jump each side keeps its own. At the
  // closing node of a periodic input both sides are one value unless it is a jump.
  double value_from_right(std::size_t node) const {  // the start value of piece `node`
    const double right = std::max(input_.right[node], 0.0);
    if (node == 0) return closing_joined_ ? 0.5 * (std::max(input_.left[n], 0.0) + right) : right;
    if (input_.continuity[node] == Continuity::Jump) return right;
    return 0.5 * (std::max(input_.left[node], 0.0) + right);
  }
  double value_from_left(std::size_t node) const {  // the end value of piece `node - 1`
    const double left = std::max(input_.left[node], 0.0);
    if (node == n) return closing_joined_ ? 0.5 * (left + std::max(input_.right[0], 0.0)) : left;
    if (input_.continuity[node] == Continuity::Jump) return left;
    return 0.5 * (left + std::max(input_.right[node], 0.0));
  }

  const HermiteInput& input_;
  const std::size_t n;  // pieces
  const bool periodic_;
  const bool closing_joined_;
  std::vector<double> h, f0, f1, secant, d0, d1;
};

// Slopes before filtering. A piece's start slope: centred at a C1 node; otherwise (curve start, C0
// or jump) one-sided from the data on the right, over this piece and the next if the next node is
// C1 (the data there are one smooth function), else the piece's own secant. The end slope mirrors
// it. Both sides of a C1 node evaluate the same expression, so they agree exactly.
void HermitePieces::initial_slopes() {
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t b = before(i);
    const std::size_t a = after(i);
    if (smooth(i))
      d0[i] = slope_centred(h[b], h[i], secant[b], secant[i]);
    else if (smooth(i + 1))
      d0[i] = slope_at_start(h[i], h[a], secant[i], secant[a]);
    else
      d0[i] = secant[i];
    if (smooth(i + 1))
      d1[i] = slope_centred(h[i], h[a], secant[i], secant[a]);
    else if (smooth(i))
      d1[i] = slope_at_end(h[b], h[i], secant[b], secant[i]);
    else
      d1[i] = secant[i];
  }
}

// Positivity (Dougherty, Edelman, Hyman, Math. Comp. 52, 1989). In x = (u - u0) / h the piece's
// Bernstein coefficients are f0, f0 + h d0 / 3, f1 - h d1 / 3, f1; if all four are >= 0 so is the
// cubic (Bernstein polynomials are >= 0 on [0,1]). With f0, f1 >= 0 that asks
//   d0 >= -3 f0 / h  at a piece's start,   d1 <= 3 f1 / h  at its end.
// At a C1 node with value f between pieces of widths h_(i-1) and h_i the shared slope must meet
// both: -3 f / h_i <= d <= 3 f / h_(i-1), an interval containing 0, so clamping keeps C1 and only
// ever moves a slope towards zero. For smooth data bounded away from zero the bounds (~1/h) stop
// binding as h shrinks and the O(h^3) accuracy is kept; where the data touch zero the clamped
// slopes cost accuracy (1 + sin u converges at about second order instead of third).
void HermitePieces::keep_positive() {
  for (std::size_t i = 0; i < n; ++i) {
    const double lower = -3.0 * f0[i] / h[i];
    const double upper = 3.0 * f1[i] / h[i];
    if (smooth(i)) {
      d0[i] = std::clamp(d0[i], lower, 3.0 * f0[i] / h[before(i)]);
      d1[before(i)] = d0[i];
    } else {
      d0[i] = std::max(d0[i], lower);
    }
    if (!smooth(i + 1)) d1[i] = std::min(d1[i], upper);
  }
}

// Fritsch-Carlson (SIAM J. Numer. Anal. 17, 1980), on request. With alpha = d0 / secant and
// beta = d1 / secant a piece is monotone if alpha, beta >= 0 and alpha^2 + beta^2 <= 9 (a
// sufficient region, star-shaped about the origin). A C1 node between secants of different sign
// (or a zero one) is an extremum of the data: slope 0. Then per piece: a flat secant gets flat
// slopes, a slope against the secant becomes 0, and a pair outside the circle is scaled by
// 3 / sqrt(alpha^2 + beta^2). Every step only shrinks slopes towards zero, so pieces already
// treated (and the positivity bounds) stay satisfied when a shared slope shrinks later.
void HermitePieces::keep_monotone() {
  for (std::size_t node = periodic_ ? 0 : 1; node < n; ++node)
    if (smooth(node) && !(secant[before(node)] * secant[node] > 0.0)) d0[node] = d1[before(node)] = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    if (secant[i] == 0.0) {
      d0[i] = d1[i] = 0.0;
    } else {
      if (d0[i] / secant[i] < 0.0) d0[i] = 0.0;
      if (d1[i] / secant[i] < 0.0) d1[i] = 0.0;
      const double alpha = d0[i] / secant[i];
      const double beta = d1[i] / secant[i];
      const double radius2 = alpha * alpha + beta * beta;
      if (radius2 > 9.0) {
        const double tau = 3.0 / std::sqrt(radius2);
        d0[i] *= tau;
        d1[i] *= tau;
      }
    }
    if (smooth(i)) d1[before(i)] = d0[i];
    if (smooth(i + 1)) d0[after(i)] = d1[i];
  }
}

}  // namespace

HermiteReconstruction::HermiteReconstruction(const HermiteInput& input) {
  assert(check_hermite_input(input).ok());
  HermitePieces data(input);
  data.initial_slopes();
  data.keep_positive();
  if (input.monotone) data.keep_monotone();

  // Bernstein form in x = (u - u0) / h of the Hermite cubic with p(0) = f0, p(1) = f1,
  // p'(0) = h d0, p'(1) = h d1: coefficients f0, f0 + h d0 / 3, f1 - h d1 / 3, f1. The filter made
  // the inner two >= 0 up to one rounding of h d / 3, which is clamped. The piece's integral is
  // h / 4 times their sum, which is h (f0 + f1) / 2 + h^2 (d0 - d1) / 12.
  const std::size_t n = data.n;
  pieces_.resize(n);
  bernstein_.resize(n);
  piece_integral_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const double h = data.h[i], f0 = data.f0[i], f1 = data.f1[i], d0 = data.d0[i], d1 = data.d1[i];
    pieces_[i] = {input.u[i], h, f0, f1, d0, d1};
    const double b1 = std::max(f0 + h * d0 / 3.0, 0.0);
    const double b2 = std::max(f1 - h * d1 / 3.0, 0.0);
    bernstein_[i] = {f0, b1, b2, f1};
    piece_integral_[i] = h * (((f0 + b1) + (b2 + f1)) / 4.0);
  }
  distribution_.assign(piece_integral_);
}

std::size_t HermiteReconstruction::find_piece(double u) const {
  // The last piece starting at or before u (piece 0 for u before the first node).
  const auto it = std::partition_point(pieces_.begin() + 1, pieces_.end(),
                                       [u](const HermitePiece& piece) { return piece.u0 <= u; });
  return static_cast<std::size_t>(it - pieces_.begin()) - 1;
}

double HermiteReconstruction::evaluate(double u) const {
  const std::size_t i = find_piece(u);
  const double x = std::clamp((u - pieces_[i].u0) / pieces_[i].width, 0.0, 1.0);
  return de_casteljau(bernstein_[i], x);
}

void HermiteReconstruction::evaluate_increasing(std::span<const double> u, double* out) const {
  std::size_t i = 0;  // the last piece starting at or before u, as find_piece
  for (std::size_t k = 0; k < u.size(); ++k) {
    while (i + 1 < pieces_.size() && pieces_[i + 1].u0 <= u[k]) ++i;
    const double x = std::clamp((u[k] - pieces_[i].u0) / pieces_[i].width, 0.0, 1.0);
    out[k] = de_casteljau(bernstein_[i], x);
  }
}

double HermiteReconstruction::derivative(double u) const {
  const std::size_t i = find_piece(u);
  const double x = std::clamp((u - pieces_[i].u0) / pieces_[i].width, 0.0, 1.0);
  double slope = 0.0;
  de_casteljau(bernstein_[i], x, &slope);
  return slope / pieces_[i].width;
}

double HermiteReconstruction::sample(double u1, double u2) const {
  if (distribution_.empty()) return u_begin() + u1 * (u_end() - u_begin());
  const std::size_t i = distribution_.sample(u1);
  const auto& b = bernstein_[i];
  // Solve G(x) = u2 G(1) on [0,1] for the piece's CDF up to a factor, G(x) = integral of p from 0
  // to x, G(1) = (b0 + b1 + b2 + b3) / 4. Newton on the power forms p = c0 + c1 x + c2 x^2 + c3 x^3
  // and G = x (c0 + x (c1 / 2 + x (c2 / 3 + x c3 / 4))) (Horner: a third of de Casteljau's work),
  // from the root for the straight density through the end values b0 and b3,
  // x = 2 v / (b0 + sqrt(b0^2 + 2 (b3 - b0) v)) with v = u2 (b0 + b3) / 2. A step leaving the
  // bracket [lo, hi], or a vanishing density, bisects; it stops once G is within rounding of the
  // goal (G is nondecreasing, p >= 0 by the Bernstein coefficients).
  const double c0 = b[0];
  const double c1 = 3.0 * (b[1] - b[0]);
  const double c2 = 3.0 * ((b[0] + b[2]) - 2.0 * b[1]);
  const double c3 = (b[3] - b[0]) + 3.0 * (b[1] - b[2]);
  auto cdf = [&](double t) { return t * (c0 + t * (c1 / 2.0 + t * (c2 / 3.0 + t * (c3 / 4.0)))); };
  auto density = [&](double t) { return c0 + t * (c1 + t * (c2 + t * c3)); };
  const double total = ((b[0] + b[1]) + (b[2] + b[3])) / 4.0;
  const double goal = u2 * total;
  const double v = u2 * 0.5 * (b[0] + b[3]);
  const double denominator = b[0] + std::sqrt(std::max(0.0, b[0] * b[0] + 2.0 * (b[3] - b[0]) * v));
  const double start = denominator > 0.0 ? std::clamp(2.0 * v / denominator, 0.0, 1.0) : u2;
  const double x =
      newton_bisection([&](double t) { return cdf(t) - goal; }, density, start, 0.0, 1.0, 100, 4e-16 * total,
                       [](double at, double next, double low, double high) -> std::optional<double> {
                         if (std::fabs(next - at) <= 1e-15 || high - low <= 1e-15) return next;
                         return std::nullopt;
                       });
  const HermitePiece& piece = pieces_[i];
  return piece.u0 + std::clamp(x, 0.0, 1.0) * piece.width;
}

double HermiteReconstruction::pdf(double u) const {
  if (!(u >= u_begin() && u <= u_end())) return 0.0;
  if (distribution_.empty()) return 1.0 / (u_end() - u_begin());
  return evaluate(u) / integral();
}

}  // namespace flatland
