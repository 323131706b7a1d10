#include "flatland/base/discrete_distribution.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace flatland {

void DiscreteDistribution::assign(std::span<const double> weights) {
  const std::size_t n = weights.size();
  weights_.assign(weights.begin(), weights.end());
  total_ = 0.0;
  for (double w : weights) total_ += w;
  probability_.assign(n, 0.0);
  alias_.assign(n, 0);
  if (n == 0 || !(total_ > 0.0)) return;
  // Scaled weights w_i n / total average 1. Columns below 1 ("small") are topped up from one above
  // ("large"), which becomes their alias and loses what it gave. A column within kTie of 1 is full
  // as it is: structured weights (equal ones, zeros) often give a scaled weight or a large column's
  // remainder that is an integer up to rounding, and which side of 1 rounding put it on decided
  // every pairing after it, so the same scene scaled or moved (weights equal to 1e-14) drew other
  // sources for the same u. Treating it as exactly 1 moves probabilities by at most kTie / n.
  constexpr double kTie = 1e-9;
  std::vector<double>& scaled = scratch_.scaled;
  std::vector<std::uint32_t>& small = scratch_.small;
  std::vector<std::uint32_t>& large = scratch_.large;
  scaled.resize(n);
  small.clear();
  large.clear();
  std::uint32_t any_positive = 0;
  auto full = [&](std::uint32_t i) {
    probability_[i] = 1.0;
    alias_[i] = i;
  };
  for (std::size_t i = 0; i < n; ++i) {
    scaled[i] = weights[i] * static_cast<double>(n) / total_;
    if (weights[i] > 0.0) any_positive = static_cast<std::uint32_t>(i);
    if (std::fabs(scaled[i] - 1.0) <= kTie)
      full(static_cast<std::uint32_t>(i));
    else
      (scaled[i] < 1.0 ? small : large).push_back(static_cast<std::uint32_t>(i));
  }
  while (!small.empty() && !large.empty()) {
    const std::uint32_t s = small.back();
    small.pop_back();
    const std::uint32_t l = large.back();
    probability_[s] = scaled[s];
    alias_[s] = l;
    scaled[l] = (scaled[l] + scaled[s]) - 1.0;
    if (std::fabs(scaled[l] - 1.0) <= kTie) {
      large.pop_back();
      full(l);
    } else if (scaled[l] < 1.0) {
      large.pop_back();
      small.push_back(l);
    }
  }
  // What is left is 1 up to rounding: keep the column itself, unless its weight is zero.
  for (std::vector<std::uint32_t>* rest : {&small, &large}) {
    for (std::uint32_t i : *rest) {
      probability_[i] = weights[i] > 0.0 ? 1.0 : 0.0;
      alias_[i] = weights[i] > 0.0 ? i : any_positive;
    }
  }
  // A column of zero weight must never keep itself.
  for (std::size_t i = 0; i < n; ++i)
    if (!(weights[i] > 0.0)) probability_[i] = 0.0;
}

}  // namespace flatland
