#include "flatland/base/quadrature.hpp"

#include <cmath>
#include <cstddef>
#include <numbers>

#include "flatland/base/portable_math.hpp"

namespace flatland::gauss {

void legendre_unit_rule(int n, std::vector<double>& nodes, std::vector<double>& weights) {
  nodes.assign(static_cast<std::size_t>(n), 0.0);
  weights.assign(static_cast<std::size_t>(n), 0.0);
  for (int k = 0; k < n; ++k) {
    double z = portable::cos(std::numbers::pi * (k + 0.75) / (n + 0.5));
    double derivative = 1.0;
    for (int iteration = 0; iteration < 100; ++iteration) {
      double p0 = 1.0;
      double p1 = z;
      for (int m = 2; m <= n; ++m) {
        const double p2 = ((2.0 * m - 1.0) * z * p1 - (m - 1.0) * p0) / m;
        p0 = p1;
        p1 = p2;
      }
      // P_n'(z) = n (z P_n - P_(n-1)) / (z^2 - 1).
      derivative = n * (z * p1 - p0) / (z * z - 1.0);
      const double step = p1 / derivative;
      z -= step;
      if (std::fabs(step) < 1e-16) break;
    }
    const double weight = 2.0 / ((1.0 - z * z) * derivative * derivative);
    // Node z in [-1, 1] maps to (1 - z) / 2 so the nodes come out increasing.
    nodes[static_cast<std::size_t>(k)] = 0.5 * (1.0 - z);
    weights[static_cast<std::size_t>(k)] = 0.5 * weight;
  }
}

}  // namespace flatland::gauss
