#include "flatland/storage/basis_sampler.hpp"

#include "flatland/base/roots.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>

namespace flatland {

BasisSampler::BasisSampler(const SplineBasis& basis) {
  // phi_k on each span is a polynomial of degree <= 3 in x = (u - u0) / width; interpolating it at
  // four interior points recovers it exactly (up to rounding), also at spans that end in a jump.
  constexpr std::array<double, 4> kNodes = {0.125, 0.375, 0.625, 0.875};
  const std::vector<double>& knots = basis.knots();
  const int p = basis.degree();
  const auto pu = static_cast<std::size_t>(p);
  first_piece_.assign(basis.size() + 1, 0);
  periodic_ = basis.is_periodic();
  degree_ = p;
  knots_ = knots;
  u_begin_ = basis.u_begin();
  u_end_ = basis.u_end();

  // The power form solves the 4x4 Vandermonde system of the nodes, the same matrix for every
  // piece: its elimination (partial pivoting) is done once here, and each piece's values go
  // through the same row exchanges and the same multipliers.
  std::array<std::array<double, 4>, 4> matrix{};
  for (std::size_t row = 0; row < 4; ++row) {
    double power = 1.0;
    for (std::size_t col = 0; col < 4; ++col, power *= kNodes[row]) matrix[row][col] = power;
  }
  std::array<std::size_t, 4> pivots{};
  std::array<std::array<double, 4>, 4> factors{};  // factors[col][row], row > col
  for (std::size_t col = 0; col < 4; ++col) {
    std::size_t pivot = col;
    for (std::size_t row = col + 1; row < 4; ++row)
      if (std::fabs(matrix[row][col]) > std::fabs(matrix[pivot][col])) pivot = row;
    pivots[col] = pivot;
    std::swap(matrix[col], matrix[pivot]);
    for (std::size_t row = col + 1; row < 4; ++row) {
      const double factor = matrix[row][col] / matrix[col][col];
      factors[col][row] = factor;
      for (std::size_t c = col; c < 4; ++c) matrix[row][c] -= factor * matrix[col][c];
    }
  }

  // The values of every function alive on a span at the four nodes, once per span (each span
  // carries p + 1 functions). On a periodic basis the first p spans (before u_begin) are
  // evaluated a period later, as span + K, where the recursion has the p knots it reads on the left.
  const std::size_t spans = basis.size() + pu;
  // Scratch kept by each thread: a scene of many short curves builds a sampler per curve.
  thread_local std::vector<std::array<std::array<double, SplineBasis::kMaxDegree + 1>, 4>> at_nodes;
  at_nodes.resize(spans);
  for (std::size_t span = 0; span < spans; ++span) {
    const double u0 = knots[span];
    const double width = knots[span + 1] - u0;
    if (!(width > 0.0)) continue;
    for (std::size_t row = 0; row < 4; ++row) {
      const double x = kNodes[row];
      if (span < pu)
        basis.evaluate_in_span(span + basis.size(), u0 + x * width + (basis.u_end() - basis.u_begin()),
                               at_nodes[span][row].data());
      else
        basis.evaluate_in_span(span, u0 + x * width, at_nodes[span][row].data());
    }
  }

  std::size_t count = 0;  // the pieces, to allocate them once
  for (std::size_t k = 0; k < basis.size(); ++k)
    for (std::size_t span = k; span <= k + pu; ++span) count += knots[span + 1] > knots[span] ? 1 : 0;
  pieces_.reserve(count);
  cumulative_.reserve(count);
  for (std::size_t k = 0; k < basis.size(); ++k) {
    first_piece_[k] = static_cast<std::uint32_t>(pieces_.size());
    double cumulative = 0.0;
    for (std::size_t span = k; span <= k + pu; ++span) {
      const double u0 = knots[span];
      const double width = knots[span + 1] - u0;
      if (!(width > 0.0)) continue;
      // Function k is function k - (span - p) of this span (spans k .. k + p carry it).
      std::array<double, 4> rhs{};
      for (std::size_t row = 0; row < 4; ++row) rhs[row] = at_nodes[span][row][k + pu - span];
      for (std::size_t col = 0; col < 4; ++col) {
        std::swap(rhs[col], rhs[pivots[col]]);
        for (std::size_t row = col + 1; row < 4; ++row) rhs[row] -= factors[col][row] * rhs[col];
      }
      Piece piece;
      piece.u0 = u0;
      piece.width = width;
      for (std::size_t row = 4; row-- > 0;) {
        double sum = rhs[row];
        for (std::size_t c = row + 1; c < 4; ++c) sum -= matrix[row][c] * piece.power[c];
        piece.power[row] = sum / matrix[row][row];
      }
      const auto& a = piece.power;
      for (int j = 0; j <= kTable; ++j) {
        const double x = static_cast<double>(j) / kTable;
        piece.table[static_cast<std::size_t>(j)] = x * (a[0] + x * (a[1] / 2 + x * (a[2] / 3 + x * (a[3] / 4))));
      }
      cumulative += width * (a[0] + a[1] / 2 + a[2] / 3 + a[3] / 4);
      cumulative_.push_back(cumulative);
      pieces_.push_back(piece);
    }
  }
  first_piece_[basis.size()] = static_cast<std::uint32_t>(pieces_.size());
}

double BasisSampler::mass(std::size_t k) const { return cumulative_[first_piece_[k + 1] - 1]; }

double BasisSampler::sample(std::size_t k, double u1, double u2) const {
  const std::uint32_t begin = first_piece_[k];
  const std::uint32_t end = first_piece_[k + 1];
  const double total = cumulative_[end - 1];
  const double target = u1 * total;
  std::uint32_t i = begin;
  while (i + 1 < end && cumulative_[i] <= target) ++i;
  const Piece& piece = pieces_[i];
  const auto& a = piece.power;
  // Solve G(x) = u2 G(1) on [0,1] with G(x) = a0 x + a1 x^2/2 + a2 x^3/3 + a3 x^4/4, increasing
  // since G' = phi_k >= 0. The table brackets the root in an interval of width 1/8 and a linear
  // interpolation starts Newton there; a step leaving the bracket bisects instead. It stops when G
  // is within rounding of the goal or the bracket is down to a few ulps.
  const auto& table = piece.table;
  if (a[2] == 0.0 && a[3] == 0.0) {
    // Constant or linear phi: a0 x + a1 x^2 / 2 = goal in closed form, written without
    // cancellation as x = 2 goal / (a0 + sqrt(a0^2 + 2 a1 goal)).
    const double goal = u2 * table[kTable];
    const double root = std::sqrt(std::max(0.0, a[0] * a[0] + 2.0 * a[1] * goal));
    const double x = a[0] + root > 0.0 ? 2.0 * goal / (a[0] + root) : u2;
    return wrap(piece.u0 + std::clamp(x, 0.0, 1.0) * piece.width);
  }
  auto cdf = [&a](double x) { return x * (a[0] + x * (a[1] / 2 + x * (a[2] / 3 + x * (a[3] / 4)))); };
  auto density = [&a](double x) { return a[0] + x * (a[1] + x * (a[2] + x * a[3])); };
  const double goal = u2 * table[kTable];
  int j = 0;
  while (j + 1 < kTable && table[static_cast<std::size_t>(j + 1)] <= goal) ++j;
  double lo = static_cast<double>(j) / kTable;
  double hi = static_cast<double>(j + 1) / kTable;
  const double g_lo = table[static_cast<std::size_t>(j)];
  const double g_hi = table[static_cast<std::size_t>(j + 1)];
  double x = g_hi > g_lo ? lo + (hi - lo) * (goal - g_lo) / (g_hi - g_lo) : 0.5 * (lo + hi);
  x = newton_bisection([&](double t) { return cdf(t) - goal; }, density, x, lo, hi, 60, 4e-16 * table[kTable],
                       [](double at, double, double low, double high) -> std::optional<double> {
                         if (high - low <= 4e-16) return at;  // a few ulps of [0, 1]
                         return std::nullopt;
                       });
  return wrap(piece.u0 + std::clamp(x, 0.0, 1.0) * piece.width);
}

void BasisSampler::prefetch(std::size_t k, bool inversion) const {
#if defined(__GNUC__)
  if (inversion) {
    const std::uint32_t begin = first_piece_[k];
    const std::uint32_t end = first_piece_[k + 1];
    __builtin_prefetch(cumulative_.data() + begin);
    const char* piece = reinterpret_cast<const char*>(pieces_.data() + begin);
    const char* last = reinterpret_cast<const char*>(pieces_.data() + end);
    for (; piece < last; piece += 64) __builtin_prefetch(piece);
  } else {
    __builtin_prefetch(knots_.data() + k);
    __builtin_prefetch(knots_.data() + k + static_cast<std::size_t>(degree_) + 1);
  }
#else
  (void)k;
  (void)inversion;
#endif
}

double BasisSampler::sample_simplex(std::size_t k, const std::array<double, 4>& uniforms) const {
  // With v_(1) <= .. <= v_(p+1) the sorted uniforms, lambda_0 = v_(1), lambda_i = v_(i+1) - v_(i),
  // lambda_(p+1) = 1 - v_(p+1), and sum lambda_i t_i = t_(p+1) - sum v_(i) (t_i - t_(i-1)): every
  // term is >= 0 and they sum to at most t_(p+1) - t_0, so u stays on the support.
  const double* t = knots_.data() + k;
  auto sorted = [](double& a, double& b) {
    const double low = std::min(a, b);
    b = std::max(a, b);
    a = low;
  };
  std::array<double, 4> v = uniforms;
  // Each degree's sum written out: the same sums as one loop over i <= p (the same roundings),
  // which keeps random-sampler photons 8-12 % cheaper (docs/performance.md).
  double u = 0.0;
  switch (degree_) {  // sorting networks of the p + 1 uniforms, then the sum
    case 0: u = t[1] - v[0] * (t[1] - t[0]); break;
    case 1:
      sorted(v[0], v[1]);
      u = t[2] - v[0] * (t[1] - t[0]) - v[1] * (t[2] - t[1]);
      break;
    case 2:
      sorted(v[0], v[1]);
      sorted(v[1], v[2]);
      sorted(v[0], v[1]);
      u = t[3] - v[0] * (t[1] - t[0]) - v[1] * (t[2] - t[1]) - v[2] * (t[3] - t[2]);
      break;
    default:  // a sorting network of five exchanges
      sorted(v[0], v[1]);
      sorted(v[2], v[3]);
      sorted(v[0], v[2]);
      sorted(v[1], v[3]);
      sorted(v[1], v[2]);
      u = t[4] - v[0] * (t[1] - t[0]) - v[1] * (t[2] - t[1]) - v[2] * (t[3] - t[2]) - v[3] * (t[4] - t[3]);
      break;
  }
  return wrap(std::clamp(u, t[0], t[degree_ + 1]));
}

double BasisSampler::wrap(double u) const {
  // A periodic function's pieces may lie a period before u_begin or past u_end.
  return periodic_ ? wrap_into_period(u, u_begin_, u_end_) : u;
}

double BasisSampler::pdf(std::size_t k, double u) const {
  const double length = u_end_ - u_begin_;
  for (std::uint32_t i = first_piece_[k]; i < first_piece_[k + 1]; ++i) {
    const Piece& piece = pieces_[i];
    // On a periodic basis a piece may lie a period away from u.
    for (const double shift : {0.0, -length, length}) {
      if (shift != 0.0 && !periodic_) break;
      const double v = u + shift;
      if (v >= piece.u0 && v < piece.u0 + piece.width) {
        const double x = (v - piece.u0) / piece.width;
        const auto& a = piece.power;
        return std::max(0.0, a[0] + x * (a[1] + x * (a[2] + x * a[3]))) / mass(k);
      }
    }
  }
  return 0.0;
}

}  // namespace flatland
