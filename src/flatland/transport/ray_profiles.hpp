// The energy profile across an extended ray of width W (docs/method.md): its density, CDF and
// inverse, and the quadrature of the band of sub-rays.
//
// A profile is a density k(x) on x in [-1, 1] (x = offset / (W/2)) integrating to exactly 1:
//   box           1/2
//   tent          1 - |x|
//   epanechnikov  3/4 (1 - x^2)
//   cosine        pi/4 cos(pi x / 2)
//   gauss         exp(-x^2 / (2 sigma^2)) / Z with sigma = 1/3, truncated at |x| <= 1 (3 sigma)
//                 and renormalised: Z = sigma sqrt(2 pi) erf(3 / sqrt 2), so 0.27 % of the
//                 untruncated mass is cut off and the density jumps to 0.0133 at the ends.
#pragma once

#include <array>
#include <cmath>
#include <numbers>
#include <vector>

#include "flatland/base/portable_math.hpp"

namespace flatland {

namespace profile_detail {
// The truncated Gaussian: sigma = 1/3, so |x| <= 1 is |z| <= 3. kGaussTail = erfc(3/sqrt 2) is the
// untruncated mass beyond 3 sigma on both sides (the tests check 1/Z against std::erf); the
// normaliser is Z = integral over [-1,1] of exp(-x^2/(2 sigma^2)) = sigma sqrt(2 pi) (1 - tail).
inline constexpr double kGaussTail = 0.0026997960632601913;
inline constexpr double kGaussKept = 1.0 - kGaussTail;
inline constexpr double kSqrt2Pi = std::numbers::sqrt2 / std::numbers::inv_sqrtpi;
inline constexpr double kGaussNorm = 1.0 / ((1.0 / 3.0) * kSqrt2Pi * kGaussKept);  // 1/Z
inline constexpr double kGaussScale = 3.0 / std::numbers::sqrt2;                   // x / (sigma sqrt 2)
}  // namespace profile_detail

enum class RayProfile { Box, Tent, Epanechnikov, Cosine, Gauss };
inline constexpr std::array<RayProfile, 5> kRayProfiles = {RayProfile::Box, RayProfile::Tent, RayProfile::Epanechnikov,
                                                           RayProfile::Cosine, RayProfile::Gauss};

// "box", "tent", "epanechnikov", "cosine", "gauss" (options.hpp reads them).
const char* to_string(RayProfile profile);

// Box, tent and Epanechnikov: polynomial on each side of the centre (FootprintTable serves them).
inline bool is_polynomial(RayProfile profile) {
  return profile == RayProfile::Box || profile == RayProfile::Tent || profile == RayProfile::Epanechnikov;
}

// Sample / Pdf / Invert set of a profile. The density is 0 outside [-1, 1]; the CDF is a closed
// form (erf for the Gaussian), 0 below -1 and 1 above 1.
double profile_density(RayProfile profile, double x);
double profile_cdf(RayProfile profile, double x);
// Inverse CDF for u in [0, 1] (clamped): closed forms for box, tent, Epanechnikov (trigonometric
// root of the cubic) and cosine; Newton's method safeguarded by bisection for the Gaussian.
double profile_sample(RayProfile profile, double u);

// The band of K sub-rays: offsets in [-1, 1] (increasing, symmetric about 0) and weights summing
// to 1. The profile's mass is cut into K strata of equal mass 1/K (boundaries profile_sample(i/K))
// and each sub-ray sits at its stratum's centroid with weight 1/K. Equal weights keep every
// sub-ray at the same power (the premise of the equal-power photons) and give the smallest
// possible error, one stratum's mass, for the step functions the band actually integrates
// (partial occlusion, a beam split between curves). Centroids make each stratum's first moment
// exact, so linear functions are integrated exactly and the second moment falls short by the
// mean within-stratum variance: 1/(3K^2) for the box, below 1/K^2 for every profile up to K = 64
// (the wide tail strata of the tent and the Gaussian add a slowly growing factor). A Gauss rule
// for the weight k would integrate x^2 exactly from K = 2 but with unequal weights, and no better
// than equal strata for the steps that matter. `count` >= 1.
void profile_quadrature(RayProfile profile, int count, std::vector<double>& offsets, std::vector<double>& weights);

// k(x) for x already in [-1, 1] (profile_density without the range check), inline for the
// footprint's inner loops.
inline double profile_density_inside(RayProfile profile, double x) {
  switch (profile) {
    case RayProfile::Box: return 0.5;
    case RayProfile::Tent: return 1.0 - std::fabs(x);
    case RayProfile::Epanechnikov: return 0.75 * (1.0 - x * x);
    case RayProfile::Cosine: return 0.25 * std::numbers::pi * portable::cos(0.5 * std::numbers::pi * x);
    case RayProfile::Gauss: return profile_detail::kGaussNorm * portable::exp(-4.5 * x * x);
  }
  return 0.0;
}

}  // namespace flatland
