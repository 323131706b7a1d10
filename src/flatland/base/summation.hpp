// Compensated summation for totals that collect many terms over a long run (the energy books
// over thousands of rounds): Neumaier's variant of Kahan's algorithm, exact to about one rounding
// of the total whatever the number and the order of magnitude of the terms.
#pragma once

#include <cmath>

namespace flatland {

class CompensatedSum {
 public:
  void add(double term) {
    const double sum = sum_ + term;
    // The low-order part lost in sum_ + term: from term when sum_ is the larger, else from sum_.
    compensation_ += std::fabs(sum_) >= std::fabs(term) ? (sum_ - sum) + term : (term - sum) + sum_;
    sum_ = sum;
  }
  double value() const { return sum_ + compensation_; }

 private:
  double sum_ = 0.0;
  double compensation_ = 0.0;
};

}  // namespace flatland
