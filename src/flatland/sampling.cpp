#include "flatland/sampling.hpp"

#include <algorithm>

namespace flatland {

void DiscreteDistribution::assign(std::span<const double> weights) {
  cumulative_.resize(weights.size());
  double sum = 0.0;
  for (std::size_t i = 0; i < weights.size(); ++i) {
    sum += weights[i];
    cumulative_[i] = sum;
  }
  total_ = sum;
}

std::size_t DiscreteDistribution::sample(double u) const {
  // First index whose inclusive prefix sum exceeds u * total: entries of zero weight repeat the
  // previous prefix sum and are never chosen.
  const double target = u * total_;
  const auto it = std::upper_bound(cumulative_.begin(), cumulative_.end(), target);
  if (it == cumulative_.end()) {
    // u * total rounded up to total: take the last index of nonzero weight.
    std::size_t i = cumulative_.size() - 1;
    while (i > 0 && cumulative_[i] == cumulative_[i - 1]) --i;
    return i;
  }
  return static_cast<std::size_t>(it - cumulative_.begin());
}

double DiscreteDistribution::pmf(std::size_t i) const {
  const double previous = i == 0 ? 0.0 : cumulative_[i - 1];
  return (cumulative_[i] - previous) / total_;
}

}  // namespace flatland
