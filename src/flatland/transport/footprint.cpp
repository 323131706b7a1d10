#include "flatland/transport/footprint.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <string>

#include "flatland/base/portable_math.hpp"
#include "flatland/base/quadrature.hpp"
#include "flatland/base/roots.hpp"
#include "flatland/base/text.hpp"

namespace flatland {
namespace {

// Gauss-Legendre rules on [-1, 1]. Three points integrate polynomials of degree 5 exactly, which
// covers a line's integrand for the polynomial profiles (profile piece of degree <= 2 times a
// basis function of degree <= 3); eight points (degree 15) serve everything else.
using gauss::kNodes3;
using gauss::kNodes8;
using gauss::kWeights3;
using gauss::kWeights8;

using Matrix8 = std::array<std::array<double, 8>, 8>;

// Spectral integration on a cubic's panel: with the speed known at the 8 Gauss nodes, the arc
// length from the panel's start to node g is integral_{-1}^{x_g} of the speed's interpolating
// polynomial = sum_j S[g][j] speed_j, where S[g][j] = integral_{-1}^{x_g} l_j(y) dy and l_j is the
// Lagrange polynomial of node j (degree 7). Each S[g][j] is computed with the 8-point rule mapped
// onto [-1, x_g], exact for degree 7. So s(u) at the nodes costs no evaluations beyond the speeds
// the quadrature needs anyway, and is exact when the speed is a polynomial of degree <= 7.
constexpr Matrix8 make_integration_matrix() {
  Matrix8 s{};
  for (std::size_t g = 0; g < 8; ++g) {
    const double half = 0.5 * (kNodes8[g] + 1.0);
    for (std::size_t j = 0; j < 8; ++j) {
      double sum = 0.0;
      for (std::size_t m = 0; m < 8; ++m) {
        const double y = -1.0 + half * (kNodes8[m] + 1.0);
        double lagrange = 1.0;
        for (std::size_t i = 0; i < 8; ++i)
          if (i != j) lagrange *= (y - kNodes8[i]) / (kNodes8[j] - kNodes8[i]);
        sum += kWeights8[m] * lagrange;
      }
      s[g][j] = half * sum;
    }
  }
  return s;
}
constexpr Matrix8 kIntegrate8 = make_integration_matrix();

// Longest panel (in the curve parameter) of a cubic's quadrature: as the basis module's lengths,
// four panels per segment at most, so the speed |C'| is resolved whatever the footprint's size.
constexpr double kMaxCubicPanel = 0.25;

// The segment (of `count`) holding the knot span [ua, ub]; joints are knots, so a non-empty span
// lies within one segment (an empty one is given the segment starting at ua).
std::uint32_t segment_of_span(double ua, double ub, std::uint32_t count) {
  return static_cast<std::uint32_t>(std::min<double>(std::floor(ub > ua ? 0.5 * (ua + ub) : ua), count - 1));
}

// Chebyshev series on [-1, 1], f(y) = sum_k c_k T_k(y), for the span table's partial spans.
//
// Point i of the n Chebyshev-Lobatto points (n >= 2), cos(pi i / (n - 1)): from 1 down to -1.
double lobatto_point(std::size_t i, std::size_t n) {
  return portable::cos(std::numbers::pi * static_cast<double>(i) / static_cast<double>(n - 1));
}

// The coefficients of the polynomial of degree n - 1 through values f[i] at the n Lobatto points
// (the discrete cosine transform of type I).
void chebyshev_fit(const double* f, std::size_t n, double* c) {
  const std::size_t m = n - 1;
  for (std::size_t k = 0; k < n; ++k) {
    double sum = 0.5 * (f[0] + (k % 2 == 0 ? f[m] : -f[m]));
    for (std::size_t i = 1; i < m; ++i) {
      const std::size_t angle = (k * i) % (2 * m);  // cos(pi k i / m), reduced exactly
      sum += f[i] * portable::cos(std::numbers::pi * static_cast<double>(angle) / static_cast<double>(m));
    }
    c[k] = (k == 0 || k == m ? 1.0 : 2.0) * sum / static_cast<double>(m);
  }
}

// f(y) by Clenshaw's recurrence.
double chebyshev_value(const double* c, std::size_t n, double y) {
  double b1 = 0.0;
  double b2 = 0.0;
  for (std::size_t k = n; k-- > 1;) {
    const double b = 2.0 * y * b1 - b2 + c[k];
    b2 = b1;
    b1 = b;
  }
  return y * b1 - b2 + c[0];
}

// y f(y): y T_0 = T_1 and y T_k = (T_(k+1) + T_(k-1)) / 2; `c` grows by one term.
void chebyshev_times_y(std::vector<double>& c) {
  std::vector<double> d(c.size() + 1, 0.0);
  for (std::size_t k = 0; k < c.size(); ++k) {
    if (k == 0) {
      d[1] += c[0];
    } else {
      d[k + 1] += 0.5 * c[k];
      d[k - 1] += 0.5 * c[k];
    }
  }
  c = std::move(d);
}

// The antiderivative that vanishes at -1: C_1 = c_0 - c_2 / 2, C_k = (c_(k-1) - c_(k+1)) / (2k),
// and C_0 such that sum C_k (-1)^k = 0; one term more than `c`.
std::vector<double> chebyshev_integral(const std::vector<double>& c) {
  const std::size_t n = c.size();
  auto at = [&](std::size_t k) { return k < n ? c[k] : 0.0; };
  std::vector<double> integral(n + 1, 0.0);
  for (std::size_t k = 1; k <= n; ++k)
    integral[k] = k == 1 ? at(0) - 0.5 * at(2) : (at(k - 1) - at(k + 1)) / (2.0 * static_cast<double>(k));
  double at_minus_one = 0.0;
  for (std::size_t k = n + 1; k-- > 1;) at_minus_one += k % 2 == 0 ? integral[k] : -integral[k];
  integral[0] = -at_minus_one;
  return integral;
}

// Fits g(y) on [-1, 1] (`count` functions at once: g(y, values) writes them) with 7, 9, 11, 13,
// 17, 25 or 33 Lobatto points, the fewest for which every function's last two coefficients are at most
// `tolerance` and its interpolant matches it within 4 tolerance half-way between the points
// (each size's fit is simply computed afresh). Returns the number of
// points, 0 when even 33 do not do; `coefficients` holds count x n values, function-major.
template <class Function>
std::size_t chebyshev_fit_checked(Function&& g, std::size_t count, double tolerance,
                                  std::vector<double>& coefficients) {
  std::vector<double> values;
  std::vector<double> at(count);
  for (const std::size_t n : {std::size_t{7}, std::size_t{9}, std::size_t{11}, std::size_t{13}, std::size_t{17},
                              std::size_t{25}, std::size_t{33}}) {
    values.assign(count * n, 0.0);
    for (std::size_t i = 0; i < n; ++i) {
      g(lobatto_point(i, n), at.data());
      for (std::size_t f = 0; f < count; ++f) values[f * n + i] = at[f];
    }
    coefficients.assign(count * n, 0.0);
    bool good = true;
    for (std::size_t f = 0; f < count && good; ++f) {
      double* c = coefficients.data() + f * n;
      chebyshev_fit(values.data() + f * n, n, c);
      good = std::fabs(c[n - 1]) <= tolerance && std::fabs(c[n - 2]) <= tolerance;
    }
    for (std::size_t i = 0; i + 1 < n && good; ++i) {
      const double y = portable::cos(std::numbers::pi * (static_cast<double>(i) + 0.5) / static_cast<double>(n - 1));
      g(y, at.data());
      for (std::size_t f = 0; f < count && good; ++f)
        good = std::fabs(chebyshev_value(coefficients.data() + f * n, n, y) - at[f]) <= 4.0 * tolerance;
    }
    if (good) return n;
  }
  return 0;
}

// Divides the weights appended after `begin` by their sum, drops zeros, and hands the rounding
// residual 1 - sum to the largest weight, so the sum is 1 to the last bit or two. False when
// there is nothing (positive and finite) to normalise.
bool normalise_appended(std::vector<FootprintWeight>& out, std::size_t begin) {
  double total = 0.0;
  for (std::size_t i = begin; i < out.size(); ++i) total += out[i].weight;
  if (!(total > 0.0) || !std::isfinite(total)) return false;
  const double inverse = 1.0 / total;
  std::size_t kept = begin;
  std::size_t largest = begin;
  double largest_weight = 0.0;  // kept in a register, not reloaded through `largest`
  double sum = 0.0;
  for (std::size_t i = begin; i < out.size(); ++i) {
    if (!(out[i].weight > 0.0)) continue;
    const double weight = out[i].weight * inverse;
    out[kept] = {out[i].coefficient, weight};
    sum += weight;
    if (weight > largest_weight) {
      largest_weight = weight;
      largest = kept;
    }
    ++kept;
  }
  out.resize(kept);
  out[largest].weight += 1.0 - sum;
  return true;
}

// The point deposit phi_k(u): the limit of the footprint as a -> 0.
void deposit_point(const SplineBasis& basis, double u, std::vector<FootprintWeight>& out) {
  const std::size_t begin = out.size();
  std::array<double, SplineBasis::kMaxDegree + 1> phi{};
  const std::size_t first = basis.evaluate(u, phi.data());
  for (int r = 0; r <= basis.degree(); ++r) {
    const auto j = static_cast<std::size_t>(r);
    if (phi[j] > 0.0) out.push_back({basis.index(first + j), phi[j]});
  }
  const bool ok = normalise_appended(out, begin);
  assert(ok);  // B-splines sum to one at every u
  (void)ok;
}

// Accumulates weight * phi_k(u) into the contiguous run of coefficients appended after `begin`,
// which starts at the first function of the first span visited. Spans come in increasing order,
// so the run only grows at its end.
//
// The functions are evaluated by the Cox-de Boor recursion of SplineBasis::evaluate (Piegl and
// Tiller, A2.2) without its search for the span, which the caller knows. The recursion's
// denominators right[r+1] + left[j-r] = knots[span+r+1] - knots[span+1-j+r] do not depend on u, so
// their reciprocals are taken once per span: the nodes of a span then cost no division.
class Accumulator {
 public:
  Accumulator(const SplineBasis& basis, std::vector<FootprintWeight>& out)
      : knots_(basis.knots().data()),
        degree_(static_cast<std::size_t>(basis.degree())),
        out_(out),
        begin_(out.size()) {}

  // Enter the knot span [knots[span], knots[span+1]] (non-empty, not before the previous one).
  void enter_span(std::size_t span) {
    const std::size_t first = span - degree_;
    if (out_.size() == begin_) base_ = first;
    assert(first >= base_);
    span_ = span;
    const std::size_t needed = begin_ + (first - base_) + degree_ + 1;
    while (out_.size() < needed) out_.push_back({base_ + (out_.size() - begin_), 0.0});
    offset_ = begin_ + (first - base_);
    inverses_ready_ = false;
  }

  // The current span whole, with the profile c0 + c1 y + c2 y^2 (FootprintTable's moments).
  void add_moments(const double* moments, std::size_t stride, double c0, double c1, double c2) {
    FootprintWeight* run = out_.data() + offset_;
    for (std::size_t r = 0; r <= degree_; ++r)
      run[r].weight += c0 * moments[r] + c1 * moments[stride + r] + c2 * moments[2 * stride + r];
  }

  // The current span's part [ya, yb] in its arc-length coordinate, with the profile
  // c[0] + c[1] y + c[2] y^2 (c[j] for j < powers), from FootprintTable's running moments
  // (`terms` per (j, r), laid out [term][j][r]): w_r += sum_j c_j (K_j,r(yb) - K_j,r(ya)).
  // The differences D_k = T_k(yb) - T_k(ya) come from their own recurrence,
  // D_(k+1) = 2 yb D_k + 2 (yb - ya) T_k(ya) - D_(k-1), so they keep their relative accuracy
  // however short the part is (subtracting the two values would leave only rounding).
  void add_running(const double* series, std::size_t terms, std::size_t powers, double ya, double yb,
                   const std::array<double, 3>& c) {
    static_assert(SplineBasis::kMaxDegree == 3);
    switch (degree_) {
      case 0: return add_running<1>(series, terms, powers, ya, yb, c);
      case 1: return add_running<2>(series, terms, powers, ya, yb, c);
      case 2: return add_running<3>(series, terms, powers, ya, yb, c);
      default: return add_running<4>(series, terms, powers, ya, yb, c);
    }
  }

  // u inside the current span.
  void add(double u, double weight) {
    if (!inverses_ready_) {
      for (std::size_t j = 1; j <= degree_; ++j)
        for (std::size_t r = 0; r < j; ++r) inverse_[j][r] = 1.0 / (knots_[span_ + r + 1] - knots_[span_ + 1 - j + r]);
      inverses_ready_ = true;
    }
    std::array<double, SplineBasis::kMaxDegree + 1> phi{};
    std::array<double, SplineBasis::kMaxDegree + 1> left{};
    std::array<double, SplineBasis::kMaxDegree + 1> right{};
    phi[0] = 1.0;
    for (std::size_t j = 1; j <= degree_; ++j) {
      left[j] = u - knots_[span_ + 1 - j];
      right[j] = knots_[span_ + j] - u;
      double saved = 0.0;
      for (std::size_t r = 0; r < j; ++r) {
        const double temp = phi[r] * inverse_[j][r];
        phi[r] = saved + right[r + 1] * temp;
        saved = left[j - r] * temp;
      }
      phi[j] = saved;
    }
    FootprintWeight* run = out_.data() + offset_;
    for (std::size_t r = 0; r <= degree_; ++r) run[r].weight += weight * phi[r];
  }

  std::size_t begin() const { return begin_; }

 private:
  // add_running for a basis of Stride = degree + 1 functions per span: the sums stay in registers.
  template <std::size_t Stride>
  void add_running(const double* series, std::size_t terms, std::size_t powers, double ya, double yb,
                   const std::array<double, 3>& c) {
    const double delta = yb - ya;
    double d_previous = 0.0;  // D_0
    double d = delta;         // D_1
    double t_previous = 1.0;  // T_0(ya)
    double t = ya;            // T_1(ya)
    std::array<double, Stride> sum{};
    const std::size_t block = powers * Stride;
    for (std::size_t k = 1; k < terms; ++k) {  // D_0 = 0: the constant terms cancel
      const double* row = series + k * block;
      for (std::size_t j = 0; j < powers; ++j) {
        const double factor = c[j] * d;
        for (std::size_t r = 0; r < Stride; ++r) sum[r] += factor * row[j * Stride + r];
      }
      const double d_next = 2.0 * yb * d + 2.0 * delta * t - d_previous;
      const double t_next = 2.0 * ya * t - t_previous;
      d_previous = d;
      d = d_next;
      t_previous = t;
      t = t_next;
    }
    FootprintWeight* run = out_.data() + offset_;
    for (std::size_t r = 0; r < Stride; ++r) run[r].weight += sum[r];
  }

  const double* knots_;
  std::size_t degree_;
  std::vector<FootprintWeight>& out_;
  std::size_t begin_;
  std::size_t base_ = 0;
  std::size_t span_ = 0;
  std::size_t offset_ = 0;
  bool inverses_ready_ = false;
  std::array<std::array<double, SplineBasis::kMaxDegree>, SplineBasis::kMaxDegree + 1> inverse_{};
};

}  // namespace

double footprint_half_length(double width, double cos_incidence) {
  return width / (2.0 * std::fmax(std::fabs(cos_incidence), kGrazingCosine));
}

int profile_powers(RayProfile profile) {
  switch (profile) {
    case RayProfile::Box: return 1;
    case RayProfile::Tent: return 2;
    case RayProfile::Epanechnikov: return 3;
    default: return 0;
  }
}

FootprintTable::FootprintTable(const Scene& scene, const Curve& curve, const SplineBasis& basis, int powers)
    : first_(basis.first_span()),
      stride_(static_cast<std::size_t>(basis.degree()) + 1),
      powers_(std::clamp(powers, 1, 3)) {
  // Raw moments A_j = integral z^j phi_r ds with z the arc length from the span's start, then
  // shifted to y = z / h - 1: M_0 = A_0, M_1 = A_1 / h - A_0, M_2 = A_2 / h^2 - 2 A_1 / h + A_0.
  // A span lies within one segment (joints are knots). On a cubic, z at the Gauss nodes comes from
  // the speeds by spectral integration (kIntegrate8) on panels of at most 1/16 in u.
  const std::vector<double>& knots = basis.knots();
  const std::size_t spans = basis.end_span() - first_;
  length_.assign(spans, 0.0);
  moments_.assign(spans * 3 * stride_, 0.0);
  std::array<double, SplineBasis::kMaxDegree + 1> phi{};
  for (std::size_t k = first_; k < basis.end_span(); ++k) {
    const double ua = knots[k];
    const double ub = knots[k + 1];
    if (!(ub > ua)) continue;
    const std::uint32_t j = segment_of_span(ua, ub, curve.segment_count);
    const SceneSegment& segment = scene.segments[curve.first_segment + j];
    const bool line = segment.geometry.kind == SegmentKind::Line;
    const int panels = line ? 1 : std::max(4, static_cast<int>(std::ceil((ub - ua) * 16.0)));
    const double width = (ub - ua) / panels;
    const double half = 0.5 * width;
    std::array<std::array<double, SplineBasis::kMaxDegree + 1>, 3> raw{};
    double z_panel = 0.0;
    for (int panel = 0; panel < panels; ++panel) {
      const double mid = ua + (panel + 0.5) * width;
      std::array<double, 8> speed{};
      for (std::size_t g = 0; g < 8; ++g)
        speed[g] =
            line ? segment.length : flatland::length(derivative(segment.geometry.shape, mid + half * kNodes8[g] - j));
      double panel_length = 0.0;
      for (std::size_t g = 0; g < 8; ++g) {
        double partial = 0.0;
        for (std::size_t m = 0; m < 8; ++m) partial += kIntegrate8[g][m] * speed[m];
        const double z = line ? half * (1.0 + kNodes8[g]) * segment.length : z_panel + half * partial;
        const double u = mid + half * kNodes8[g];
        basis.evaluate_in_span(k, u, phi.data());
        const double w = kWeights8[g] * half * speed[g];
        for (std::size_t r = 0; r < stride_; ++r) {
          raw[0][r] += w * phi[r];
          raw[1][r] += w * z * phi[r];
          raw[2][r] += w * z * z * phi[r];
        }
        panel_length += kWeights8[g] * speed[g];
      }
      z_panel += half * panel_length;
    }
    const double total = line ? (ub - ua) * segment.length : z_panel;
    length_[k - first_] = total;
    if (!(total > 0.0)) continue;
    const double inverse_h = 2.0 / total;
    double* m = moments_.data() + (k - first_) * 3 * stride_;
    for (std::size_t r = 0; r < stride_; ++r) {
      m[r] = raw[0][r];
      m[stride_ + r] = raw[1][r] * inverse_h - raw[0][r];
      m[2 * stride_ + r] = (raw[2][r] * inverse_h - 2.0 * raw[1][r]) * inverse_h + raw[0][r];
    }
  }
  build_series(scene, curve, basis);
}

void FootprintTable::build_series(const Scene& scene, const Curve& curve, const SplineBasis& basis) {
  // Span starts in arc length, from each segment's start (joints are knots: a span lies within
  // one segment), and per non-empty span the running moments' series (see the header).
  const std::vector<double>& knots = basis.knots();
  const std::size_t spans = basis.end_span() - first_;
  const std::size_t powers = static_cast<std::size_t>(powers_);
  const std::size_t block = powers * stride_;
  start_.assign(spans + 1, curve.length);
  series_.assign(spans, Series{});
  std::vector<double> g;        // phi_r(u(y)) fits, function-major
  std::vector<double> sigma;    // s(v) - s0 fit
  std::vector<double> running;  // one (j, r) series while it is built
  smooth_joints_.assign(curve.segment_count, false);
  for (std::uint32_t joint = 0; joint < curve.joint_count(); ++joint)
    smooth_joints_[joint] = is_tangent_continuous(scene, curve, joint);
  std::array<double, SplineBasis::kMaxDegree + 1> phi{};
  for (std::size_t k = first_; k < basis.end_span(); ++k) {
    const double ua = knots[k];
    const double ub = knots[k + 1];
    const std::uint32_t j = segment_of_span(ua, ub, curve.segment_count);
    const SceneSegment& segment = scene.segments[curve.first_segment + j];
    const bool line = segment.geometry.kind == SegmentKind::Line;
    // Arc lengths within the segment (exact), so that rounding is relative to the segment's
    // length, not the curve's.
    auto arc = [&](double u) {
      const double t = std::clamp(u - j, 0.0, 1.0);
      if (t == 0.0) return 0.0;
      return line ? t * segment.length : segment.arc_length.length_at(segment.geometry.shape, t);
    };
    const double z0 = arc(ua);
    start_[k - first_] = curve.segment_start[j] + z0;
    if (!(ub > ua)) continue;
    const double z1 = arc(ub);
    const double mid = 0.5 * (z0 + z1);
    const double h = 0.5 * (z1 - z0);
    if (!(h > 0.0)) continue;
    // u at y in [-1, 1] (s = mid + h y within the segment), within the span.
    auto u_at = [&](double y) {
      if (line) return std::clamp(ua + 0.5 * (y + 1.0) * (ub - ua), ua, ub);
      return std::clamp(j + segment.arc_length.parameter_at(segment.geometry.shape, mid + h * y), ua, ub);
    };
    auto basis_at = [&](double y, double* values) {
      basis.evaluate_in_span(k, u_at(y), phi.data());
      for (std::size_t r = 0; r < stride_; ++r) values[r] = phi[r];
    };
    std::size_t n = 0;
    std::size_t n_length = 0;
    if (line) {
      // phi_r(u(y)) is a polynomial of degree <= 3: four Lobatto points fit it exactly.
      n = 4;
      g.assign(stride_ * n, 0.0);
      std::vector<double> values(stride_ * n);
      for (std::size_t i = 0; i < n; ++i) {
        basis.evaluate_in_span(k, u_at(lobatto_point(i, n)), phi.data());
        for (std::size_t r = 0; r < stride_; ++r) values[r * n + i] = phi[r];
      }
      for (std::size_t r = 0; r < stride_; ++r) chebyshev_fit(values.data() + r * n, n, g.data() + r * n);
    } else {
      // The inversion s -> u is accurate to about 1e-15 of the segment's length, which is
      // 1e-15 L / h in y: the tolerance follows it on short spans.
      n = chebyshev_fit_checked(basis_at, stride_, 1e-14 * std::fmax(1.0, segment.length / (2.0 * h)), g);
      if (n == 0) continue;  // no series: quadrature on this span
      const double u_mid = 0.5 * (ua + ub);
      const double half_u = 0.5 * (ub - ua);
      n_length = chebyshev_fit_checked([&](double v, double* value) { value[0] = arc(u_mid + half_u * v) - z0; }, 1,
                                       1e-14 * segment.length, sigma);
      if (n_length == 0) continue;
    }
    // K_j,r = h * integral of y^j g_r from -1: terms n + powers for every j (zeros beyond).
    const std::size_t terms = n + powers;
    Series& series = series_[k - first_];
    series.offset = coefficients_.size();
    series.terms = static_cast<std::uint32_t>(terms);
    series.length_terms = static_cast<std::uint32_t>(n_length);
    series.u_mid = 0.5 * (ua + ub);
    series.inverse_half_u = 2.0 / (ub - ua);
    coefficients_.resize(series.offset + terms * block + n_length, 0.0);
    double* out = coefficients_.data() + series.offset;
    for (std::size_t r = 0; r < stride_; ++r) {
      running.assign(g.begin() + static_cast<std::ptrdiff_t>(r * n),
                     g.begin() + static_cast<std::ptrdiff_t>((r + 1) * n));
      for (std::size_t p = 0; p < powers; ++p) {
        if (p > 0) chebyshev_times_y(running);
        const std::vector<double> integral = chebyshev_integral(running);
        for (std::size_t t = 0; t < integral.size() && t < terms; ++t)
          out[t * block + p * stride_ + r] = h * integral[t];
      }
    }
    std::copy(sigma.begin(), sigma.begin() + static_cast<std::ptrdiff_t>(n_length), out + terms * block);
  }
  // An empty span starts where the next one does; the last entry stays the curve's length; and
  // no start lies past the next (an arc length within a segment can exceed the segment's length
  // by a rounding), so the starts are sorted for span_at.
  for (std::size_t k = spans; k-- > 0;) {
    if (!(knots[first_ + k + 1] > knots[first_ + k])) start_[k] = start_[k + 1];
    start_[k] = std::fmin(start_[k], start_[k + 1]);
  }
}

std::size_t FootprintTable::span_at(double s) const {
  // The last span whose start is <= s; among equal starts the last, the non-empty one.
  const auto it = std::upper_bound(start_.begin(), start_.end() - 1, s);
  const std::size_t k = it == start_.begin() ? 0 : static_cast<std::size_t>(it - start_.begin()) - 1;
  return first_ + k;
}

double FootprintTable::arc_length_in_span(std::size_t span, double u) const {
  const Series& series = series_[span - first_];
  if (series.length_terms == 0) return std::numeric_limits<double>::quiet_NaN();
  const double v = std::clamp((u - series.u_mid) * series.inverse_half_u, -1.0, 1.0);
  const double* sigma = coefficients_.data() + series.offset + series.terms * powers_ * stride_;
  return start_[span - first_] + chebyshev_value(sigma, series.length_terms, v);
}

namespace {

// Where a footprint may spread along the receiver: [x0, x1] in arc-length offsets from the hit,
// and whether the run of tangent-continuous segments (or a wall) cut it short at either end, so
// that the cut-off mass is reflected back about that end.
struct FootprintRun {
  double x0 = 0.0;
  double x1 = 0.0;
  bool cut_low = false;
  bool cut_high = false;
  bool flat = false;  // a closed smooth curve the footprint would wrap round many times
};

// One footprint deposit (footprint_weights): the hit and the curve it lies on, and the steps of
// its integration, each a method. Offsets x = s - s_hit run along the receiver's arc length; the
// spread is k(x / a) / a on [-a, a].
class FootprintSpread {
 public:
  FootprintSpread(const Scene& scene, const Curve& curve, const SplineBasis& basis, double u_hit, double a,
                  RayProfile profile, std::vector<FootprintWeight>& out, const FootprintTable* table)
      : curve_(curve),
        basis_(basis),
        knots_(basis.knots()),
        segments_(scene.segments.data() + curve.first_segment),
        start_(curve.segment_start),
        count_(curve.segment_count),
        total_(curve.length),
        a_(a),
        profile_(profile),
        polynomial_profile_(is_polynomial(profile)),
        u_hit_(u_hit),
        hit_(std::min(static_cast<std::uint32_t>(u_hit), curve.segment_count - 1)),
        out_(out),
        begin_(out.size()) {
    // A table serves the polynomial profiles whose powers of y it keeps: the walk then goes by arc
    // length (integrate_piece_by_arc); any other footprint walks in u with quadrature.
    use_table_ =
        polynomial_profile_ && table != nullptr && !table->empty() && table->powers() >= profile_powers(profile);
    table_ = use_table_ ? table : nullptr;
    assert(table == nullptr || table->empty() || table->matches(basis));
    const double t_hit = u_hit - hit_;
    into_hit_ = std::numeric_limits<double>::quiet_NaN();
    if (use_table_) {
      hit_span_ = basis.find_span(u_hit);
      // On a cubic the span's s(u) series gives the hit's arc length without quadrature.
      if (segments_[hit_].geometry.kind != SegmentKind::Line)
        into_hit_ =
            std::clamp(table_->arc_length_in_span(hit_span_, u_hit) - start_[hit_], 0.0, segments_[hit_].length);
    }
    if (std::isnan(into_hit_)) into_hit_ = length_in(hit_, t_hit);
    s_hit_ = start_[hit_] + into_hit_;
    hit_is_line_ = segments_[hit_].geometry.kind == SegmentKind::Line;
  }

  FootprintRun run(const Scene& scene, std::span<const double> walls);
  // Integrates the image of the spread centred at offset c over [xa, xb], cut into laps of the
  // curve: pieces end where s_hit + x crosses a multiple of the length (only on a closed run).
  void integrate_image(double xa, double xb, double c);
  // Merges the pieces' weights and normalises them (a point deposit when nothing was spread).
  void finish();
  void set_flat(bool flat) { inverse_a_ = flat ? 0.0 : 1.0 / a_; }

 private:
  // Arc length within segment j at parameter t, and its inverse: closed form on lines.
  double length_in(std::uint32_t j, double t) const {
    const SceneSegment& segment = segments_[j];
    return segment.geometry.kind == SegmentKind::Line ? t * segment.length
                                                      : segment.arc_length.length_at(segment.geometry.shape, t);
  }
  double parameter_in(std::uint32_t j, double s) const {
    const SceneSegment& segment = segments_[j];
    return segment.geometry.kind == SegmentKind::Line ? std::clamp(s / segment.length, 0.0, 1.0)
                                                      : segment.arc_length.parameter_at(segment.geometry.shape, s);
  }
  double u_at(double x, bool at_end, double n) const;
  int profile_panels(double x_width) const;
  std::array<double, 3> profile_in_y(double x_mid, double beta, bool below) const;
  void integrate_part(Accumulator& accumulate, std::uint32_t j, double ua, double ub, double& delta_a) const;
  void integrate_piece(double xa, double xb, double c, double n);
  void integrate_piece_by_arc(double xa, double xb, double c, double n);
  void integrate_span_part(Accumulator& accumulate, std::size_t span, double pa, double pb, double s0, double s1,
                           double s_centre) const;

  const Curve& curve_;
  const SplineBasis& basis_;
  const std::vector<double>& knots_;
  const SceneSegment* segments_;
  const std::vector<double>& start_;
  const std::uint32_t count_;
  const double total_;
  const double a_;
  const RayProfile profile_;
  const bool polynomial_profile_;
  const double u_hit_;
  const std::uint32_t hit_;
  std::vector<FootprintWeight>& out_;
  const std::size_t begin_;
  bool use_table_ = false;
  const FootprintTable* table_ = nullptr;
  std::size_t hit_span_ = 0;  // with a table: the knot span holding u_hit (the one that starts there)
  double into_hit_ = 0.0;     // from the hit segment's start
  double s_hit_ = 0.0;
  bool hit_is_line_ = false;
  double inverse_a_ = 0.0;  // 0 for a flat spread
  bool several_ = false;    // more than one piece appended: merge before normalising
};

FootprintRun FootprintSpread::run(const Scene& scene, std::span<const double> walls) {
  // The run, walking over smooth joints (the closing one too, on a closed curve) while the
  // footprint reaches past them. `before` and `after` are the run's lengths on each side of the
  // hit; infinite when the walk comes all the way round.
  auto smooth = [&](std::uint32_t joint) {
    return use_table_ ? table_->smooth_joint(joint) : is_tangent_continuous(scene, curve_, joint);
  };
  double before = into_hit_;
  double after = segments_[hit_].length - into_hit_;
  bool endless = false;
  {
    std::uint32_t j = hit_;
    std::uint32_t steps = 0;
    while (before < a_) {
      const bool wraps = j == 0;
      if (wraps && !curve_.closed) break;
      const std::uint32_t previous = wraps ? count_ - 1 : j - 1;
      if (!smooth(previous)) break;
      if (++steps > count_) {
        endless = true;
        break;
      }
      j = previous;
      before += segments_[j].length;
    }
    j = hit_;
    steps = 0;
    while (!endless && after < a_) {
      const bool wraps = j + 1 == count_;
      if (wraps && !curve_.closed) break;
      if (!smooth(j)) break;
      if (++steps > count_) {
        endless = true;
        break;
      }
      j = wraps ? 0 : j + 1;
      after += segments_[j].length;
    }
  }
  // Walls (contacts: another curve stands on this one there) end the run like corners.
  if (!walls.empty()) {
    if (endless) {
      before = after = std::numeric_limits<double>::infinity();
      endless = false;
    }
    for (const double wall : walls) {
      double below = s_hit_ - wall;  // arc length from the wall up to the hit
      if (curve_.closed) {
        below -= std::floor(below / total_) * total_;
        before = std::fmin(before, below);
        after = std::fmin(after, total_ - below);
      } else if (below >= 0.0) {
        before = std::fmin(before, below);
      } else {
        after = std::fmin(after, -below);
      }
    }
  }
  // A closed smooth curve that the footprint would wrap round more than 64 times gets a flat
  // spread (its periodic sum is flat to 2 %), one lap each way.
  FootprintRun run;
  run.flat = endless && a_ > 32.0 * total_;
  const double reach = run.flat ? 0.5 * total_ : a_;
  run.x0 = endless ? -reach : std::fmax(-before, -a_);
  run.x1 = endless ? reach : std::fmin(after, a_);
  run.cut_low = !endless && before < a_;
  run.cut_high = !endless && after < a_;
  return run;
}

// u at offset x from the hit, in lap n of the curve (s = s_hit + x - n length, within the curve);
// `at_end` picks the end of the previous segment (or of the curve) for a point on a joint. On the
// hit segment of a line u is u_hit + x / L directly, which keeps tiny footprints accurate.
double FootprintSpread::u_at(double x, bool at_end, double n) const {
  if (n == 0.0 && hit_is_line_ && x >= -into_hit_ && x <= segments_[hit_].length - into_hit_)
    return std::clamp(u_hit_ + x / segments_[hit_].length, static_cast<double>(hit_), hit_ + 1.0);
  const double s = std::clamp(s_hit_ + x - n * total_, 0.0, total_);
  const auto it = std::upper_bound(start_.begin(), start_.begin() + count_, s);
  auto j = static_cast<std::uint32_t>(std::max<std::ptrdiff_t>(0, (it - start_.begin()) - 1));
  if (at_end && j > 0 && s == start_[j]) --j;  // the end of the previous segment
  return j + parameter_in(j, s - start_[j]);
}

// The Gaussian changes fastest: its panels span at most half the footprint (x-width 1/2), where
// eight points reach about 1e-14 (a whole half, x-width 1, would give about 1e-9).
int FootprintSpread::profile_panels(double x_width) const {
  return profile_ == RayProfile::Gauss ? std::max(1, static_cast<int>(std::ceil(2.0 * x_width))) : 1;
}

// The polynomial profile in a span's arc-length coordinate y, where the offset from the image's
// centre over a is x_mid + beta y, on the side of the centre `below` says: c0 + c1 y + c2 y^2.
std::array<double, 3> FootprintSpread::profile_in_y(double x_mid, double beta, bool below) const {
  if (profile_ == RayProfile::Tent) {  // 1 - |x|
    const double sign = below ? -1.0 : 1.0;
    return {1.0 - sign * x_mid, -sign * beta, 0.0};
  }
  if (profile_ == RayProfile::Epanechnikov)  // 3/4 (1 - x^2)
    return {0.75 * (1.0 - x_mid * x_mid), -1.5 * x_mid * beta, -0.75 * beta * beta};
  return {0.5, 0.0, 0.0};
}

// Integrates the part [ua, ub] of segment j (within one knot span, which the accumulator has
// entered, on one side of the centre) by Gauss-Legendre panels; delta_a, the part's start's offset
// from the image's centre, advances to its end.
void FootprintSpread::integrate_part(Accumulator& accumulate, std::uint32_t j, double ua, double ub,
                                     double& delta_a) const {
  const SceneSegment& segment = segments_[j];
  const double jd = j;
  if (segment.geometry.kind == SegmentKind::Line) {
    // Constant speed L: delta(u) = delta_a + (u - ua) L exactly.
    const double speed = segment.length;
    const int panels = polynomial_profile_ ? 1 : profile_panels((ub - ua) * speed * inverse_a_);
    const double width = (ub - ua) / panels;
    const double half = 0.5 * width;
    for (int panel = 0; panel < panels; ++panel) {
      const double pa = ua + panel * width;
      const double mid = pa + half;
      const double delta_pa = delta_a + panel * width * speed;
      auto node = [&](double x, double w) {
        const double delta = delta_pa + half * (1.0 + x) * speed;
        const double offset = std::clamp(delta * inverse_a_, -1.0, 1.0);
        accumulate.add(mid + half * x, w * half * speed * profile_density_inside(profile_, offset));
      };
      if (polynomial_profile_) {
        for (std::size_t g = 0; g < 3; ++g) node(kNodes3[g], kWeights3[g]);
      } else {
        for (std::size_t g = 0; g < 8; ++g) node(kNodes8[g], kWeights8[g]);
      }
    }
    delta_a += (ub - ua) * speed;
    return;
  }
  const Cubic& shape = segment.geometry.shape;
  // speed_bound >= |C'|, so the Gaussian's panels are at most half a footprint wide.
  const int panels = std::max(profile_panels((ub - ua) * segment.speed_bound * inverse_a_),
                              static_cast<int>(std::ceil((ub - ua) / kMaxCubicPanel)));
  const double width = (ub - ua) / panels;
  const double half = 0.5 * width;
  for (int panel = 0; panel < panels; ++panel) {
    const double mid = ua + (panel + 0.5) * width;
    std::array<double, 8> speed{};
    for (std::size_t g = 0; g < 8; ++g) speed[g] = length(derivative(shape, mid + half * kNodes8[g] - jd));
    double panel_length = 0.0;
    for (std::size_t g = 0; g < 8; ++g) {
      double partial = 0.0;
      for (std::size_t m = 0; m < 8; ++m) partial += kIntegrate8[g][m] * speed[m];
      const double delta = delta_a + half * partial;
      const double offset = std::clamp(delta * inverse_a_, -1.0, 1.0);
      accumulate.add(mid + half * kNodes8[g],
                     kWeights8[g] * half * speed[g] * profile_density_inside(profile_, offset));
      panel_length += kWeights8[g] * speed[g];
    }
    delta_a += half * panel_length;
  }
}

// Integrates the image centred at c over the piece of offsets [xa, xb] that lies within lap n of
// the curve, from u0 to u1, part by part: each part ends at the next knot, joint, centre or u1.
void FootprintSpread::integrate_piece(double xa, double xb, double c, double n) {
  double u0 = u_at(xa, false, n);
  double u1 = u_at(xb, true, n);
  const bool has_centre = c > xa && c < xb;
  const double u_centre = has_centre ? (c == 0.0 && n == 0.0 ? u_hit_ : u_at(c, false, n)) : -1.0;
  if (has_centre) {
    u0 = std::fmin(u0, u_centre);
    u1 = std::fmax(u1, u_centre);
  }
  if (!(u1 > u0)) return;
  if (out_.size() > begin_) several_ = true;
  Accumulator accumulate(basis_, out_);
  auto next_knot = std::upper_bound(knots_.begin(), knots_.end(), u0);
  double ua = u0;
  double delta_a = xa - c;
  while (ua < u1) {
    double ub = u1;
    if (next_knot != knots_.end()) ub = std::min(ub, *next_knot);
    ub = std::min(ub, std::floor(ua) + 1.0);
    if (has_centre && ua < u_centre) ub = std::min(ub, u_centre);
    const std::uint32_t j = std::min(static_cast<std::uint32_t>(ua), count_ - 1);
    // The knot span holding the part: knots[span] <= ua < ub <= knots[span + 1] = *next_knot
    // (clamped to the spans that cover [u_begin, u_end)).
    const std::size_t span =
        std::clamp(static_cast<std::size_t>(next_knot - knots_.begin()), basis_.first_span() + 1, basis_.end_span()) -
        1;
    accumulate.enter_span(span);
    integrate_part(accumulate, j, ua, ub, delta_a);
    if (has_centre && ub == u_centre) delta_a = 0.0;
    ua = ub;
    while (next_knot != knots_.end() && *next_knot <= ua) ++next_knot;
  }
}

// A part [pa, pb] of span `span` (arc lengths [s0, s1]) by the table's running moments, or, for a
// span with no series (near a cusp) or one the footprint is far shorter than, by quadrature in u
// between the inverted ends of the part.
void FootprintSpread::integrate_span_part(Accumulator& accumulate, std::size_t span, double pa, double pb, double s0,
                                          double s1, double s_centre) const {
  std::size_t terms = 0;
  const double* series = table_->running(span, terms);
  // In the span's coordinate the tent and Epanechnikov pieces have coefficients up to (1 + beta)^2
  // with beta = h / a, which cancel to the profile's O(1) values: with a footprint far shorter
  // than the span that cancellation would eat the digits, so beyond beta = 16 (errors then below
  // 300 roundings) such parts take the quadrature. The box is a constant and needs no such care.
  const bool conditioned = profile_ == RayProfile::Box || 0.5 * (s1 - s0) * inverse_a_ <= 16.0;
  if (series != nullptr && conditioned) {
    const double mid = 0.5 * (s0 + s1);
    const double inverse_h = 2.0 / (s1 - s0);
    const double ya = std::clamp((pa - mid) * inverse_h, -1.0, 1.0);
    const double yb = std::clamp((pb - mid) * inverse_h, -1.0, 1.0);
    const std::array<double, 3> coefficients =
        profile_in_y((mid - s_centre) * inverse_a_, 0.5 * (s1 - s0) * inverse_a_, 0.5 * (pa + pb) < s_centre);
    accumulate.add_running(series, terms, static_cast<std::size_t>(table_->powers()), ya, yb, coefficients);
    return;
  }
  const double u_begin = knots_[span];
  const double u_end = knots_[span + 1];
  const std::uint32_t j = segment_of_span(u_begin, u_end, count_);
  const double ua = std::clamp(j + parameter_in(j, pa - start_[j]), u_begin, u_end);
  const double ub = std::clamp(j + parameter_in(j, pb - start_[j]), u_begin, u_end);
  double delta_a = pa - s_centre;
  if (ub > ua) integrate_part(accumulate, j, ua, ub, delta_a);
}

// The same by arc length, with the table: the piece is [sa, sb] = s_hit - n length + [xa, xb],
// walked span by span from the span holding sa. Whole spans take the moments, parts of spans the
// running moments' differences.
void FootprintSpread::integrate_piece_by_arc(double xa, double xb, double c, double n) {
  const double lap = s_hit_ - n * total_;
  const double sa = std::clamp(lap + xa, 0.0, total_);
  const double sb = std::clamp(lap + xb, 0.0, total_);
  if (!(sb > sa)) return;
  if (out_.size() > begin_) several_ = true;
  Accumulator accumulate(basis_, out_);
  const double s_centre = lap + c;
  // Parts no longer than a few roundings of the curve's arc length are slivers made by rounding
  // s_hit + x (one just across a corner, say), not footprint: they are left out, and a footprint
  // made of nothing else deposits at the point.
  const double resolution = 4.0 * std::numeric_limits<double>::epsilon() * total_;
  // The span holding sa: near the hit's for the hit's own lap, else by bisection.
  std::size_t first_span = hit_span_;
  if (n == 0.0 && std::fabs(sa - s_hit_) <= 4.0 * table_->length(hit_span_)) {
    while (first_span > basis_.first_span() && table_->start(first_span) > sa) --first_span;
    while (first_span + 1 < basis_.end_span() && table_->start(first_span + 1) <= sa) ++first_span;
  } else {
    first_span = table_->span_at(sa);
  }
  for (std::size_t span = first_span; span < basis_.end_span(); ++span) {
    const double s0 = table_->start(span);
    if (!(s0 < sb)) break;
    const double s1 = table_->start(span + 1);
    const double pa = std::fmax(sa, s0);
    const double pb = std::fmin(sb, s1);
    if (!(pb - pa > resolution)) continue;
    accumulate.enter_span(span);
    // The tent and Epanechnikov profiles change their polynomial at the centre; the box's is the
    // same on both sides, so where the span has its series the part holding the centre is one part
    // (the quadrature of a span without one, near a cusp, keeps its two halves).
    const bool one_part = profile_ == RayProfile::Box && table_->has_series(span);
    if (s_centre > pa && s_centre < pb && !one_part) {
      integrate_span_part(accumulate, span, pa, s_centre, s0, s1, s_centre);
      integrate_span_part(accumulate, span, s_centre, pb, s0, s1, s_centre);
    } else if (pa == s0 && pb == s1) {
      const double span_length = table_->length(span);
      const double x_mid = (s0 + 0.5 * span_length - s_centre) * inverse_a_;
      const std::array<double, 3> coefficients = profile_in_y(x_mid, 0.5 * span_length * inverse_a_, x_mid < 0.0);
      accumulate.add_moments(table_->moments(span), table_->stride(), coefficients[0], coefficients[1],
                             coefficients[2]);
    } else {
      integrate_span_part(accumulate, span, pa, pb, s0, s1, s_centre);
    }
  }
}

void FootprintSpread::integrate_image(double xa, double xb, double c) {
  if (!(xb > xa)) return;
  auto piece = [&](double a0, double a1, double n) {
    if (use_table_) {
      integrate_piece_by_arc(a0, a1, c, n);
    } else {
      integrate_piece(a0, a1, c, n);
    }
  };
  if (!curve_.closed) return piece(xa, xb, 0.0);
  while (xa < xb) {
    double n = std::floor((s_hit_ + xa) / total_);
    double lap_end = (n + 1.0) * total_ - s_hit_;
    if (!(lap_end > xa)) {  // xa rounded onto the lap's end: it starts the next lap
      n += 1.0;
      lap_end += total_;
    }
    const double xe = std::fmin(xb, lap_end);
    piece(xa, xe, n);
    xa = xe;
  }
}

void FootprintSpread::finish() {
  // Wrapped indices on a periodic basis, and pieces naming the same coefficient, are merged.
  // (One piece on a periodic basis is an increasing run: only one that passes the last index
  // wraps.)
  if (several_ || (basis_.is_periodic() && out_.size() > begin_ && out_.back().coefficient >= basis_.size())) {
    for (std::size_t i = begin_; i < out_.size(); ++i) out_[i].coefficient = basis_.index(out_[i].coefficient);
    std::sort(out_.begin() + static_cast<std::ptrdiff_t>(begin_), out_.end(),
              [](const FootprintWeight& p, const FootprintWeight& q) { return p.coefficient < q.coefficient; });
    std::size_t kept = begin_;
    for (std::size_t i = begin_; i < out_.size(); ++i) {
      if (kept > begin_ && out_[kept - 1].coefficient == out_[i].coefficient) {
        out_[kept - 1].weight += out_[i].weight;
      } else {
        out_[kept++] = out_[i];
      }
    }
    out_.resize(kept);
  }
  if (!normalise_appended(out_, begin_)) {
    out_.resize(begin_);
    deposit_point(basis_, u_hit_, out_);
  }
}

}  // namespace

void footprint_weights(const Scene& scene, const Curve& curve, const SplineBasis& basis, double u_hit,
                       double half_length, RayProfile profile, std::vector<FootprintWeight>& out,
                       std::span<const double> walls, const FootprintTable* table) {
  // The run is the stretch of tangent-continuous segments around the hit, [X0, X1] in x; on a
  // closed curve it may continue across the closing point (x then runs past the curve's length
  // and wraps), and a closed curve that is smooth all round has no ends at all. What would fall
  // beyond an end of the run is reflected about that end (the image k((x - 2 X0) / a) on
  // [X0, 2 X0 + a], likewise at X1): every image point lies at the same distance from the end as
  // the mass it replaces, so energy is exact and a uniform incident flux gives a uniform deposit
  // up to the end (renormalising instead piles the cut-off mass up near it: ln 2 of the truth at
  // the end for a box). A run shorter than the footprint would need images of images; the one
  // reflection at each end is then renormalised.
  //
  // Each image interval is cut where it wraps into pieces that lie within the curve, and on each
  // piece, in the curve parameter u (ds = |C'(u)| du),
  //   w_k += integral k((x(u) - c) / a) phi_k(u) |C'(u)| du,  c the image's centre,
  // split where the integrand is not smooth: knots (phi_k), segment joints (|C'|), and the centre
  // (the tent's kink). Each part gets Gauss-Legendre panels. x is carried from part to part:
  // exactly linear on lines, integrated spectrally on cubics (kIntegrate8), and reset to c at the
  // centre. The constant 1/a is dropped: the weights are normalised at the end.
  assert(curve.segment_count > 0 && std::isfinite(u_hit));
  // fmax/fmin also send a NaN to the curve's start instead of into an index.
  u_hit = std::fmin(std::fmax(u_hit, 0.0), static_cast<double>(curve.segment_count));
  if (!(half_length > 0.0)) {
    deposit_point(basis, u_hit, out);
    return;
  }
  FootprintSpread spread(scene, curve, basis, u_hit, half_length, profile, out, table);
  const FootprintRun run = spread.run(scene, walls);
  spread.set_flat(run.flat);
  const double a = half_length;
  spread.integrate_image(run.x0, run.x1, 0.0);
  if (run.cut_low) spread.integrate_image(run.x0, std::fmin(2.0 * run.x0 + a, run.x1), 2.0 * run.x0);
  if (run.cut_high) spread.integrate_image(std::fmax(2.0 * run.x1 - a, run.x0), run.x1, 2.0 * run.x1);
  spread.finish();
}

}  // namespace flatland
