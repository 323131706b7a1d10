#include "flatland/transport/ray_profiles.hpp"

#include <algorithm>
#include <array>
#include <cassert>
#include <cmath>
#include <numbers>
#include <optional>

#include "flatland/base/portable_math.hpp"
#include "flatland/base/roots.hpp"

namespace flatland {
namespace {

using profile_detail::kGaussKept;
using profile_detail::kGaussNorm;
using profile_detail::kGaussScale;
using profile_detail::kGaussTail;

constexpr std::array<const char*, 5> kProfileNames = {"box", "tent", "epanechnikov", "cosine", "gauss"};

// An antiderivative of x k(x) on [-1, 1], for the centroids of the quadrature's strata:
//   box x^2/4; tent x^2/2 - |x|^3/3; Epanechnikov 3/4 (x^2/2 - x^4/4);
//   cosine (pi/4) (x sin(cx)/c + cos(cx)/c^2) with c = pi/2;
//   Gauss -sigma^2 exp(-x^2/(2 sigma^2)) / Z.
double first_moment_antiderivative(RayProfile profile, double x) {
  const double x2 = x * x;
  switch (profile) {
    case RayProfile::Box: return 0.25 * x2;
    case RayProfile::Tent: return 0.5 * x2 - std::fabs(x) * x2 / 3.0;
    case RayProfile::Epanechnikov: return 0.375 * x2 - 0.1875 * x2 * x2;
    case RayProfile::Cosine:
      return 0.5 * x * portable::sin(0.5 * std::numbers::pi * x) +
             portable::cos(0.5 * std::numbers::pi * x) / std::numbers::pi;
    case RayProfile::Gauss: return -kGaussNorm * portable::exp(-4.5 * x2) / 9.0;
  }
  return 0.0;
}

}  // namespace

const char* to_string(RayProfile profile) {
  const auto index = static_cast<std::size_t>(profile);
  return index < kProfileNames.size() ? kProfileNames[index] : "?";
}

double profile_density(RayProfile profile, double x) {
  if (!(std::fabs(x) <= 1.0)) return 0.0;
  return profile_density_inside(profile, x);
}

double profile_cdf(RayProfile profile, double x) {
  if (x <= -1.0) return 0.0;
  if (x >= 1.0) return 1.0;
  if (std::isnan(x)) return x;
  switch (profile) {
    case RayProfile::Box: return 0.5 * (x + 1.0);
    case RayProfile::Tent: {
      // (1+x)^2/2 on the rising side, 1 - (1-x)^2/2 on the falling side.
      if (x < 0.0) return 0.5 * (1.0 + x) * (1.0 + x);
      return 1.0 - 0.5 * (1.0 - x) * (1.0 - x);
    }
    case RayProfile::Epanechnikov: return 0.25 * (2.0 + x * (3.0 - x * x));
    case RayProfile::Cosine: return 0.5 * (1.0 + portable::sin(0.5 * std::numbers::pi * x));
    case RayProfile::Gauss: {
      // F(x) = (erf(3x/sqrt 2) + kept) / (2 kept). On the lower half write it with erfc,
      // F(x) = (erfc(3|x|/sqrt 2) - tail) / (2 kept), which keeps its relative accuracy in the
      // lower tail; the upper half is 1 - F(-x).
      const double lower = 0.5 * (std::erfc(kGaussScale * std::fabs(x)) - kGaussTail) / kGaussKept;
      return x < 0.0 ? lower : 1.0 - lower;
    }
  }
  return 0.0;
}

double profile_sample(RayProfile profile, double u) {
  // The ends exactly (the closed forms below round them to within an ulp).
  if (!(u > 0.0)) return -1.0;
  if (u >= 1.0) return 1.0;
  switch (profile) {
    case RayProfile::Box: return 2.0 * u - 1.0;
    case RayProfile::Tent: return u < 0.5 ? std::sqrt(2.0 * u) - 1.0 : 1.0 - std::sqrt(2.0 * (1.0 - u));
    case RayProfile::Epanechnikov: {
      // Solve (2 + 3x - x^3)/4 = u, i.e. x^3 - 3x + (4u - 2) = 0. With x = 2 sin(theta) the
      // identity sin(3 theta) = 3 sin(theta) - 4 sin^3(theta) turns it into sin(3 theta) = 2u - 1;
      // theta = asin(2u - 1)/3 in [-pi/6, pi/6] gives the root in [-1, 1].
      return 2.0 * portable::sin(std::asin(2.0 * u - 1.0) / 3.0);
    }
    case RayProfile::Cosine: return std::asin(2.0 * u - 1.0) * (2.0 / std::numbers::pi);
    case RayProfile::Gauss: {
      // No closed form (erf has no inverse in the standard library). By symmetry solve on the
      // lower half, F(x) = v with v = min(u, 1-u) <= 1/2 and x in [-1, 0], where F is convex
      // (the density increases): Newton from x = 0 then approaches the root monotonically from
      // above; the bracket [lo, hi] and bisection guard against rounding all the same.
      const double v = std::min(u, 1.0 - u);
      if (v <= 0.0) return u < 0.5 ? -1.0 : 1.0;
      const double x =
          newton_bisection([&](double t) { return profile_cdf(profile, t) - v; },
                           [&](double t) { return profile_density_inside(profile, t); }, 0.0, -1.0, 0.0, 100, 0.0,
                           [](double at, double next, double low, double high) -> std::optional<double> {
                             if (std::fabs(next - at) <= 1e-16 * (1.0 + std::fabs(at)) || high - low <= 1e-16)
                               return next;
                             return std::nullopt;
                           });
      return u < 0.5 ? x : -x;
    }
  }
  return 0.0;
}

void profile_quadrature(RayProfile profile, int count, std::vector<double>& offsets, std::vector<double>& weights) {
  assert(count >= 1);
  const auto n = static_cast<std::size_t>(std::max(count, 1));
  offsets.resize(n);
  weights.assign(n, 1.0 / static_cast<double>(n));
  // Stratum i is [b_i, b_(i+1)] with b_i = F^-1(i/n); its centroid is
  // n * integral over the stratum of x k(x) dx = n (M(b_(i+1)) - M(b_i)).
  double lower = -1.0;
  double lower_moment = first_moment_antiderivative(profile, lower);
  for (std::size_t i = 0; i < n; ++i) {
    const double mass = static_cast<double>(i + 1) / static_cast<double>(n);
    const double upper = i + 1 == n ? 1.0 : profile_sample(profile, mass);
    const double upper_moment = first_moment_antiderivative(profile, upper);
    const double centroid = static_cast<double>(n) * (upper_moment - lower_moment);
    offsets[i] = std::clamp(centroid, lower, upper);
    lower = upper;
    lower_moment = upper_moment;
  }
  // Exact symmetry (the strata are symmetric; rounding is not): mirror the upper half.
  for (std::size_t i = 0; i < n / 2; ++i) {
    const double mirrored = 0.5 * (offsets[n - 1 - i] - offsets[i]);
    offsets[i] = -mirrored;
    offsets[n - 1 - i] = mirrored;
  }
  if (n % 2 == 1) offsets[n / 2] = 0.0;
  // 1/n summed n times need not give 1 exactly; put the residual on the middle weight.
  double sum = 0.0;
  for (double w : weights) sum += w;
  weights[n / 2] += 1.0 - sum;
}

}  // namespace flatland
