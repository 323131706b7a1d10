#include "flatland/storage/restriction.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>

namespace flatland {

Restriction restriction_between(const SplineBasis& coarse, const SplineBasis& fine) {
  const int p = fine.degree();
  const auto pu = static_cast<std::size_t>(p);
  const std::size_t terms = pu + 1;
  const std::vector<double>& knots = fine.knots();
  // Rows of R as (fine column, weight) lists, each pair set from the first fine span where both
  // functions are alive (nested bases make every span give the same numbers).
  std::vector<std::vector<std::pair<std::uint32_t, double>>> rows(coarse.size());
  std::array<double, SplineBasis::kMaxDegree + 1> values{};
  for (std::size_t span = fine.first_span(); span < fine.end_span(); ++span) {
    const double a = knots[span];
    const double b = knots[span + 1];
    if (!(b > a)) continue;
    // A[m][r] = phi_fine_(span - p + r)(x_m); right-hand sides: the coarse functions at x_m.
    std::array<std::array<double, SplineBasis::kMaxDegree + 1>, SplineBasis::kMaxDegree + 1> matrix{};
    std::array<std::array<double, SplineBasis::kMaxDegree + 1>, SplineBasis::kMaxDegree + 1> rhs{};
    std::array<std::size_t, SplineBasis::kMaxDegree + 1> coarse_index{};
    for (std::size_t m = 0; m < terms; ++m) {
      const double x = a + (b - a) * (static_cast<double>(m) + 0.5) / static_cast<double>(terms);
      fine.evaluate_in_span(span, x, values.data());
      for (std::size_t r = 0; r < terms; ++r) matrix[m][r] = values[r];
      const std::size_t first = coarse.evaluate(x, values.data());
      for (std::size_t r = 0; r < terms; ++r) {
        rhs[m][r] = values[r];
        coarse_index[r] = coarse.index(first + r);  // the same coarse span for every x_m
      }
    }
    // Gaussian elimination with partial pivoting, all right-hand sides at once.
    for (std::size_t col = 0; col < terms; ++col) {
      std::size_t pivot = col;
      for (std::size_t m = col + 1; m < terms; ++m)
        if (std::fabs(matrix[m][col]) > std::fabs(matrix[pivot][col])) pivot = m;
      std::swap(matrix[col], matrix[pivot]);
      std::swap(rhs[col], rhs[pivot]);
      for (std::size_t m = col + 1; m < terms; ++m) {
        const double factor = matrix[m][col] / matrix[col][col];
        for (std::size_t r = col; r < terms; ++r) matrix[m][r] -= factor * matrix[col][r];
        for (std::size_t r = 0; r < terms; ++r) rhs[m][r] -= factor * rhs[col][r];
      }
    }
    for (std::size_t col = terms; col-- > 0;) {
      for (std::size_t r = 0; r < terms; ++r) {
        double sum = rhs[col][r];
        for (std::size_t m = col + 1; m < terms; ++m) sum -= matrix[col][m] * rhs[m][r];
        rhs[col][r] = sum / matrix[col][col];
      }
    }
    // rhs[f][r]: the weight of fine function span - p + f in coarse function coarse_index[r].
    for (std::size_t r = 0; r < terms; ++r) {
      auto& row = rows[coarse_index[r]];
      for (std::size_t f = 0; f < terms; ++f) {
        const auto column = static_cast<std::uint32_t>(fine.index(span - pu + f));
        // Spans come in order, so a pair seen before was added within the last few entries (the
        // functions of the previous spans), or, round a periodic basis's closing point, within the
        // first few: two short searches keep this linear.
        const auto reach = static_cast<std::ptrdiff_t>(std::min(row.size(), 2 * terms));
        auto same = [&](const auto& e) { return e.first == column; };
        const bool known =
            std::any_of(row.end() - reach, row.end(), same) || std::any_of(row.begin(), row.begin() + reach, same);
        if (!known) row.emplace_back(column, rhs[f][r]);
      }
    }
  }
  Restriction result;
  result.fine_size = fine.size();
  result.first.assign(coarse.size() + 1, 0);
  for (std::size_t i = 0; i < coarse.size(); ++i) {
    std::sort(rows[i].begin(), rows[i].end());
    for (const auto& [column, weight] : rows[i]) {
      if (!(std::fabs(weight) > 1e-14)) continue;
      result.column.push_back(column);
      result.weight.push_back(weight);
    }
    result.first[i + 1] = result.column.size();
  }
  return result;
}

void restrict_deposits(const Restriction& r, const double* fine, std::size_t stride, double* coarse) {
  for (std::size_t i = 0; i + 1 < r.first.size(); ++i) {
    double sum = 0.0;
    for (std::size_t e = r.first[i]; e < r.first[i + 1]; ++e) sum += r.weight[e] * fine[r.column[e] * stride];
    coarse[i] = sum;
  }
}

void prolong_coefficients(const Restriction& r, const double* coarse, double* fine, std::size_t stride) {
  for (std::size_t j = 0; j < r.fine_size; ++j) fine[j * stride] = 0.0;
  for (std::size_t i = 0; i + 1 < r.first.size(); ++i)
    for (std::size_t e = r.first[i]; e < r.first[i + 1]; ++e) fine[r.column[e] * stride] += r.weight[e] * coarse[i];
}

}  // namespace flatland
