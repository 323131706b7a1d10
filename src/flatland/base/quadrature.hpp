// Gauss-Legendre rules, the one source of every quadrature in the core: the fixed 3-, 4- and
// 8-point rules on [-1, 1], and a rule of any number of points on [0, 1] (the reference's form
// factors). An n-point rule integrates polynomials of degree 2n - 1 exactly.
#pragma once

#include <array>
#include <vector>

namespace flatland::gauss {

inline constexpr std::array<double, 3> kNodes3 = {-0.7745966692414833770, 0.0, 0.7745966692414833770};
inline constexpr std::array<double, 3> kWeights3 = {5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0};

inline constexpr std::array<double, 4> kNodes4 = {-0.8611363115940525752, -0.3399810435848562648, 0.3399810435848562648,
                                                  0.8611363115940525752};
inline constexpr std::array<double, 4> kWeights4 = {0.3478548451374538574, 0.6521451548625461426, 0.6521451548625461426,
                                                    0.3478548451374538574};

inline constexpr std::array<double, 8> kNodes8 = {
    -0.9602898564975362317, -0.7966664774136267396, -0.5255324099163289858, -0.1834346424956498049,
    0.1834346424956498049,  0.5255324099163289858,  0.7966664774136267396,  0.9602898564975362317};
inline constexpr std::array<double, 8> kWeights8 = {0.1012285362903762591, 0.2223810344533744706, 0.3137066458778872873,
                                                    0.3626837833783619830, 0.3626837833783619830, 0.3137066458778872873,
                                                    0.2223810344533744706, 0.1012285362903762591};

// The n-point rule on [0, 1] (weights summing to 1, nodes increasing): Newton's method on the
// Legendre polynomial P_n from the Chebyshev-like first guesses cos(pi (k + 3/4) / (n + 1/2)),
// with P_n and P_n' by the three-term recurrence. Accurate to rounding for n <= 64.
void legendre_unit_rule(int n, std::vector<double>& nodes, std::vector<double>& weights);

}  // namespace flatland::gauss
