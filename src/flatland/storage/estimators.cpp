#include "flatland/storage/estimators.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <vector>

#include "flatland/storage/arc_length_quadrature.hpp"

namespace flatland {

using storage_detail::for_each_quadrature_point;

void galerkin_estimate(const CurveStorage& storage, const double* deposits, double* coefficients, std::size_t stride) {
  const std::size_t n = storage.basis.size();
  // Forward substitution L y = d by rows, then back substitution L^T b = y by columns of L, both
  // in the output, so no call allocates a scratch vector of the storage's size (and faults its
  // pages in). Row k reads deposit k before writing coefficient k, so the two may be the same array.
  double* x = coefficients;
  for (std::size_t row = 0; row < n; ++row) {
    const std::size_t first = storage.mass_first[row];
    const double* l = storage.mass_cholesky.data() + storage.mass_offset[row];  // L_(row, first) ..
    double sum = deposits[row * stride];
    for (std::size_t col = first; col < row; ++col) sum -= l[col - first] * x[col * stride];
    x[row * stride] = sum / l[row - first];
  }
  for (std::size_t row = n; row-- > 0;) {
    const std::size_t first = storage.mass_first[row];
    const double* l = storage.mass_cholesky.data() + storage.mass_offset[row];
    const double value = x[row * stride] / l[row - first];
    x[row * stride] = value;
    for (std::size_t col = first; col < row; ++col) x[col * stride] -= l[col - first] * value;
  }
}

bool clamp_keeping_power(const CurveStorage& storage, double* coefficients, std::size_t stride, double power) {
  double kept = 0.0;
  const std::size_t n = storage.basis.size();
  for (std::size_t k = 0; k < n; ++k) {
    double& b = coefficients[k * stride];
    b = b > 0.0 ? b : 0.0;  // a NaN too
    kept += b * storage.basis_length[k];
  }
  const bool positive = kept > 0.0 && std::isfinite(kept);
  const double rescale = positive ? power / kept : 0.0;
  for (std::size_t k = 0; k < n; ++k) coefficients[k * stride] *= rescale;
  return positive;
}

namespace {

// Cholesky factorisation in place of a small symmetric positive definite matrix (row-major, n x n,
// lower triangle used). False when a pivot is not positive (relative to the diagonal's size).
bool cholesky_in_place(std::vector<double>& a, std::size_t n) {
  for (std::size_t j = 0; j < n; ++j) {
    const double diagonal = a[j * n + j];
    double sum = diagonal;
    for (std::size_t k = 0; k < j; ++k) sum -= a[j * n + k] * a[j * n + k];
    if (!(sum > 1e-13 * diagonal)) return false;
    a[j * n + j] = std::sqrt(sum);
    for (std::size_t i = j + 1; i < n; ++i) {
      double t = a[i * n + j];
      for (std::size_t k = 0; k < j; ++k) t -= a[i * n + k] * a[j * n + k];
      a[i * n + j] = t / a[j * n + j];
    }
  }
  return true;
}

// x := A^-1 x for the factor L of A = L L^T from cholesky_in_place.
void cholesky_solve(const std::vector<double>& l, std::size_t n, double* x) {
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t k = 0; k < i; ++k) x[i] -= l[i * n + k] * x[k];
    x[i] /= l[i * n + i];
  }
  for (std::size_t i = n; i-- > 0;) {
    for (std::size_t k = i + 1; k < n; ++k) x[i] -= l[k * n + i] * x[k];
    x[i] /= l[i * n + i];
  }
}

// The local window of one coefficient: functions of the extended numbering (e = j + lap n on a
// periodic basis) and their weights, with the weights' variance factor w^T G w.
struct LocalWindow {
  std::vector<std::ptrdiff_t> functions;  // increasing
  std::vector<double> weights;
  double variance = 0.0;
  int degree = -1;  // polynomial degree reproduced; -1: no window
};

// The windows and weights of the local estimator on one curve's storage (build_local_estimator):
// the basis's moments and Gram band, the breaks R(u) may have, and per coefficient the window of
// functions grown from it and its least-variance weights.
class LocalEstimatorBuilder {
 public:
  LocalEstimatorBuilder(const Scene& scene, const Curve& curve, const CurveStorage& storage, bool nodal_values);

  // The window of coefficient k: across the joints as well when that reproduces a higher degree
  // than stopping at them; the lumped estimate when there is nothing to stand on.
  LocalWindow window(std::size_t k);
  // Function e of the extended numbering: function e mod n, a whole number of laps away.
  std::size_t local(std::ptrdiff_t e) const { return static_cast<std::size_t>(e - lap_of(e) * count_); }

 private:
  void integrate_moments(const Scene& scene, const Curve& curve);
  void find_breaks(const CurveStorage& storage);
  std::ptrdiff_t lap_of(std::ptrdiff_t e) const { return e >= 0 ? e / count_ : -((-e + count_ - 1) / count_); }
  double start(std::ptrdiff_t e) const { return knots_[local(e)] + static_cast<double>(lap_of(e)) * period_; }
  double end(std::ptrdiff_t e) const { return knots_[local(e) + pu_ + 1] + static_cast<double>(lap_of(e)) * period_; }
  bool exists(std::ptrdiff_t e) const { return periodic_ || (e >= 0 && e < count_); }
  bool straddles(std::ptrdiff_t e) const;
  // Consecutive functions with supports that only touch are split by a C-1 node (p + 1 knots).
  bool separated(std::ptrdiff_t left, std::ptrdiff_t right) const { return end(left) <= start(right) + tolerance_; }
  bool usable(std::ptrdiff_t e) const { return exists(e) && !straddles(e); }
  std::vector<std::ptrdiff_t> grow(std::ptrdiff_t seed, bool leftwards, bool rightwards) const;
  std::array<double, 4> target(std::size_t k, double centre, double scale, std::size_t terms) const;
  LocalWindow solve(std::size_t k, std::vector<std::ptrdiff_t> functions) const;
  LocalWindow window_with_breaks(std::size_t k) const;

  const SplineBasis& basis_;
  const bool nodal_values_;
  const int p_;
  const std::size_t pu_;
  const std::size_t n_;
  const std::ptrdiff_t count_;
  const std::vector<double>& knots_;
  const bool periodic_;
  const double period_;
  const double tolerance_;
  const int wanted_degree_;
  const std::size_t half_;
  // Per function j: raw moments integral(phi_j (u - a_j)^r ds), r = 0..3, about the start a_j of
  // the support (the aliases a period away see the same numbers), and the band of the Gram matrix
  // integral(phi_j phi_(j+d) ds), d = 0..p, d counted round the loop on a periodic basis.
  std::vector<std::array<double, 4>> moment_;
  std::vector<std::array<double, SplineBasis::kMaxDegree + 1>> gram_;
  std::vector<double> breaks_;
  std::vector<double> hard_breaks_;
  bool across_ = false;  // whether joints (C1 nodes at whole u) are crossed
};

LocalEstimatorBuilder::LocalEstimatorBuilder(const Scene& scene, const Curve& curve, const CurveStorage& storage,
                                             bool nodal_values)
    : basis_(storage.basis),
      nodal_values_(nodal_values),
      p_(basis_.degree()),
      pu_(static_cast<std::size_t>(p_)),
      n_(basis_.size()),
      count_(static_cast<std::ptrdiff_t>(n_)),
      knots_(basis_.knots()),
      periodic_(basis_.is_periodic()),
      period_(basis_.u_end() - basis_.u_begin()),
      tolerance_(1e-12 * period_),
      wanted_degree_(nodal_values ? 3 : p_),
      half_(nodal_values ? 2 : pu_) {
  integrate_moments(scene, curve);
  find_breaks(storage);
}

void LocalEstimatorBuilder::integrate_moments(const Scene& scene, const Curve& curve) {
  moment_.assign(n_, std::array<double, 4>{});
  gram_.assign(n_, std::array<double, SplineBasis::kMaxDegree + 1>{});
  for_each_quadrature_point(scene, curve, basis_,
                            [&](double u, double weight, const auto& index, const auto& values, std::size_t span) {
                              for (std::size_t j = 0; j <= pu_; ++j) {
                                const double x = u - knots_[span - pu_ + j];
                                double term = weight * values[j];
                                for (double& m : moment_[index[j]]) {
                                  m += term;
                                  term *= x;
                                }
                                for (std::size_t i = j; i <= pu_; ++i)
                                  gram_[index[j]][i - j] += weight * values[j] * values[i];
                              }
                            });
}

// Where R(u) may stop being smooth: the C0 and C-1 nodes, and every joint between segments (R is
// smooth in arc length, but at a joint the parametrisation's speed changes its slope, so R(u) is
// only as smooth as the knots the spline has there; the ring of cubic arcs is C1 in u at its
// joints, not C2). A function whose support holds one strictly inside straddles it: its
// coefficient, the blossom of the spline's polynomial piece on any span of its support, is
// estimated from the pieces on either side.
//
// A mesh with about one element per segment has no function inside a segment, so no window stands
// on one side of every joint; the windows are then grown across the joints (`across_`), where R(u)
// is C1 and only its second derivative jumps, by the change of the speed's slope: far less error
// than the lumped estimate's, and far less than extrapolating from a window several functions away
// (whose weights run into the hundreds: 10-30 % errors on a ring of 32 arcs at 32 elements). The
// C0 and C-1 nodes stay breaks either way.
void LocalEstimatorBuilder::find_breaks(const CurveStorage& storage) {
  for (const MeshNode& node : storage.nodes) {
    if (node.continuity != Continuity::C1 || node.u == std::round(node.u)) breaks_.push_back(node.u);
    if (node.continuity != Continuity::C1) hard_breaks_.push_back(node.u);
  }
  if (periodic_) {
    breaks_.push_back(basis_.u_begin());
    if (storage.closing != Continuity::C1) hard_breaks_.push_back(basis_.u_begin());
  }
}

bool LocalEstimatorBuilder::straddles(std::ptrdiff_t e) const {
  const double a = start(e) + tolerance_;
  const double b = end(e) - tolerance_;
  for (double d : across_ ? hard_breaks_ : breaks_)
    for (double shift : {-period_, 0.0, period_}) {
      const double at = d + shift + static_cast<double>(lap_of(e)) * period_;
      if (at > a && at < b) return true;
    }
  return false;
}

// The window grown from `seed` one function at a time, alternating sides (the side with fewer
// first), never across a straddling function or a C-1 node, never holding a function twice.
std::vector<std::ptrdiff_t> LocalEstimatorBuilder::grow(std::ptrdiff_t seed, bool leftwards, bool rightwards) const {
  std::vector<std::ptrdiff_t> window;
  if (!usable(seed)) return window;
  window.push_back(seed);
  std::ptrdiff_t left = seed;
  std::ptrdiff_t right = seed;
  const std::size_t limit = std::min(2 * half_ + 1, n_);
  while (window.size() < limit) {
    const bool can_left = leftwards && usable(left - 1) && !separated(left - 1, left);
    const bool can_right = rightwards && usable(right + 1) && !separated(right, right + 1);
    if (!can_left && !can_right) break;
    if (can_left && (!can_right || seed - left <= right - seed)) {
      window.insert(window.begin(), --left);
    } else {
      window.push_back(++right);
    }
  }
  return window;
}

// x^0 .. x^3 by products: the same bits on every platform (a library's pow need not be correctly
// rounded, and libraries differ).
std::array<double, 4> powers(double x) { return {1.0, x, x * x, x * x * x}; }

// Target functional of x^m, x = (u - centre) / scale: the blossom of x^m at the interior knots of
// function k (the B-spline coefficient of x^m: the elementary symmetric polynomial over the
// binomial), or x^m at the hat's peak.
std::array<double, 4> LocalEstimatorBuilder::target(std::size_t k, double centre, double scale,
                                                    std::size_t terms) const {
  std::array<double, 4> target{};
  if (nodal_values_) {
    const std::array<double, 4> x = powers((knots_[k + 1] - centre) / scale);
    for (std::size_t m = 0; m < terms; ++m) target[m] = x[m];
  } else {
    std::array<double, 4> symmetric{1.0, 0.0, 0.0, 0.0};  // e_m of the knots so far
    for (std::size_t i = 1; i <= pu_; ++i) {
      const double x = (knots_[k + i] - centre) / scale;
      for (std::size_t m = i; m >= 1; --m) symmetric[m] += x * symmetric[m - 1];
    }
    for (std::size_t m = 0; m < terms; ++m) {
      double binomial = 1.0;
      for (std::size_t r = 1; r <= m; ++r)
        binomial = binomial * static_cast<double>(pu_ - r + 1) / static_cast<double>(r);
      target[m] = symmetric[m] / binomial;
    }
  }
  return target;
}

// Least-variance weights on a window for the target of function k (extended e = k).
LocalWindow LocalEstimatorBuilder::solve(std::size_t k, std::vector<std::ptrdiff_t> functions) const {
  LocalWindow result;
  const std::size_t size = functions.size();
  if (size == 0) return result;
  const int degree = std::min(wanted_degree_, static_cast<int>(size) - 1);
  const auto terms = static_cast<std::size_t>(degree) + 1;
  // Scaled coordinate x = (u - centre) / scale over the window's extent.
  const double lo = start(functions.front());
  const double hi = end(functions.back());
  const double centre = 0.5 * (lo + hi);
  const double scale = std::max(0.5 * (hi - lo), tolerance_);
  const std::array<double, 4> c = target(k, centre, scale, terms);
  // V_am = integral(phi_a x^m ds) from the raw moments by the binomial theorem.
  std::vector<double> v(size * terms);
  for (std::size_t a = 0; a < size; ++a) {
    const std::array<double, 4>& raw = moment_[local(functions[a])];
    const std::array<double, 4> offset = powers(start(functions[a]) - centre);
    const std::array<double, 4> scale_power = powers(scale);
    for (std::size_t m = 0; m < terms; ++m) {
      double sum = 0.0;
      double binomial = 1.0;  // C(m, r)
      for (std::size_t r = 0; r <= m; ++r) {
        sum += binomial * raw[r] * offset[m - r];
        binomial = binomial * static_cast<double>(m - r) / static_cast<double>(r + 1);
      }
      v[a * terms + m] = sum / scale_power[m];
    }
  }
  std::vector<double> g(size * size, 0.0);
  for (std::size_t a = 0; a < size; ++a)
    for (std::size_t b = a; b < size; ++b) {
      const std::ptrdiff_t gap = functions[b] - functions[a];
      if (gap <= p_) g[b * size + a] = g[a * size + b] = gram_[local(functions[a])][static_cast<std::size_t>(gap)];
    }
  if (!cholesky_in_place(g, size)) return result;
  // A = G^-1 V by columns, S = V^T A, then S y = c and w = A y; w^T G w = c . y.
  std::vector<double> a(size * terms);
  for (std::size_t m = 0; m < terms; ++m) {
    std::vector<double> column(size);
    for (std::size_t r = 0; r < size; ++r) column[r] = v[r * terms + m];
    cholesky_solve(g, size, column.data());
    for (std::size_t r = 0; r < size; ++r) a[r * terms + m] = column[r];
  }
  std::vector<double> s(terms * terms, 0.0);
  for (std::size_t i = 0; i < terms; ++i)
    for (std::size_t j = 0; j < terms; ++j)
      for (std::size_t r = 0; r < size; ++r) s[i * terms + j] += v[r * terms + i] * a[r * terms + j];
  std::array<double, 4> y = c;
  if (!cholesky_in_place(s, terms)) return result;
  cholesky_solve(s, terms, y.data());
  result.functions = std::move(functions);
  result.weights.assign(size, 0.0);
  for (std::size_t r = 0; r < size; ++r)
    for (std::size_t m = 0; m < terms; ++m) result.weights[r] += a[r * terms + m] * y[m];
  for (std::size_t m = 0; m < terms; ++m) result.variance += c[m] * y[m];
  result.degree = degree;
  return result;
}

// The window of function k with the current breaks. A straddling function's seeds are the nearest
// functions that do not straddle, at most p + 1 functions away (its support's neighbours); a seed
// further off would extrapolate over several elements.
LocalWindow LocalEstimatorBuilder::window_with_breaks(std::size_t k) const {
  const auto e = static_cast<std::ptrdiff_t>(k);
  if (!straddles(e)) return solve(k, grow(e, true, true));
  // Straddling a node: the value there from each side; the two sides' deposits are independent,
  // so inverse-variance weights give the combination of least variance.
  std::ptrdiff_t left_seed = e - 1;
  std::ptrdiff_t right_seed = e + 1;
  const auto reach = static_cast<std::ptrdiff_t>(pu_) + 1;
  while (e - left_seed < reach && exists(left_seed) && straddles(left_seed)) --left_seed;
  while (right_seed - e < reach && exists(right_seed) && straddles(right_seed)) ++right_seed;
  LocalWindow left = solve(k, grow(left_seed, true, false));
  LocalWindow right = solve(k, grow(right_seed, false, true));
  if (left.degree < 0 || right.degree < 0) return left.degree >= 0 ? left : right;
  LocalWindow window;
  const double lambda = right.variance / (left.variance + right.variance);
  window.functions = left.functions;
  window.functions.insert(window.functions.end(), right.functions.begin(), right.functions.end());
  for (double w : left.weights) window.weights.push_back(lambda * w);
  for (double w : right.weights) window.weights.push_back((1.0 - lambda) * w);
  window.degree = std::min(left.degree, right.degree);
  return window;
}

LocalWindow LocalEstimatorBuilder::window(std::size_t k) {
  across_ = false;
  LocalWindow window = window_with_breaks(k);
  if (window.degree < wanted_degree_) {
    // Too few functions between the joints: across them, if that reproduces more.
    across_ = true;
    LocalWindow wide = window_with_breaks(k);
    if (wide.degree > window.degree) window = std::move(wide);
  }
  return window;
}

}  // namespace

void build_local_estimator(const Scene& scene, const Curve& curve, CurveStorage& storage, bool nodal_values) {
  LocalEstimatorBuilder builder(scene, curve, storage, nodal_values);
  const std::size_t n = storage.basis.size();
  storage.local_first.assign(n + 1, 0);
  storage.local_index.clear();
  storage.local_weight.clear();
  storage.local_degree.assign(n, 0);
  for (std::size_t k = 0; k < n; ++k) {
    LocalWindow window = builder.window(k);
    if (window.degree < 0) {  // nothing to stand on: the lumped estimate
      window.functions = {static_cast<std::ptrdiff_t>(k)};
      window.weights = {1.0 / storage.basis_length[k]};
      window.degree = 0;
    }
    for (std::size_t r = 0; r < window.functions.size(); ++r) {
      storage.local_index.push_back(static_cast<std::uint32_t>(builder.local(window.functions[r])));
      storage.local_weight.push_back(window.weights[r]);
    }
    storage.local_first[k + 1] = storage.local_index.size();
    storage.local_degree[k] = static_cast<std::int8_t>(window.degree);
  }
}

void local_estimate(const CurveStorage& storage, const double* deposits, double* coefficients, std::size_t stride) {
  const std::size_t n = storage.basis.size();
  for (std::size_t k = 0; k < n; ++k) {
    double sum = 0.0;
    for (std::size_t i = storage.local_first[k]; i < storage.local_first[k + 1]; ++i)
      sum += storage.local_weight[i] * deposits[storage.local_index[i] * stride];
    coefficients[k * stride] = sum;
  }
}

}  // namespace flatland
