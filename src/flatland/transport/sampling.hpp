// The samplers of the shooter, in Sample / Pdf / Invert sets (its random numbers and the alias
// method live in base/, where storage/ can use them too).
#pragma once

#include <cmath>
#include <cstdint>
#include <numbers>
#include <span>
#include <utility>
#include <vector>

#include "flatland/base/discrete_distribution.hpp"
#include "flatland/base/portable_math.hpp"
#include "flatland/base/random.hpp"
#include "flatland/base/vec2.hpp"

namespace flatland {

// Diffuse emission in 2D: the angle theta from the normal has pdf cos(theta)/2 on [-pi/2, pi/2]
// and CDF (1 + sin theta)/2, so sin theta = 2u - 1. Without trigonometry:
// dir = s * tangent + sqrt(1 - s^2) * normal with s = 2u - 1. (The 3D rule cos theta = sqrt(u)
// would put zero density along the normal.)
inline Vec2 square_to_diffuse(double u, Vec2 normal) {
  const double s = 2.0 * u - 1.0;
  const double c = std::sqrt(std::fmax(0.0, 1.0 - s * s));
  const Vec2 tangent{normal.y, -normal.x};  // normal rotated -90 degrees
  return s * tangent + c * normal;
}
// Density per radian of a direction; zero behind the surface.
inline double square_to_diffuse_pdf(Vec2 normal, Vec2 direction) {
  return std::fmax(0.0, dot(normal, direction)) * 0.5;
}
// The u that square_to_diffuse maps to the given direction (in front of the surface).
inline double square_to_diffuse_invert(Vec2 normal, Vec2 direction) {
  const Vec2 tangent{normal.y, -normal.x};
  return 0.5 * (dot(tangent, direction) + 1.0);
}

// A cos^n lobe in 2D: pdf(theta) = cos(theta)^n / c_n on [-pi/2, pi/2]. Sampled exactly by
// rejection: theta uniform, accepted with probability cos(theta)^n (expected tries pi / c_n:
// 1.6 for n = 1, 4 for n = 10, 12.6 for n = 100).
inline Vec2 sample_lobe(Rng& rng, double exponent, Vec2 normal) {
  const Vec2 tangent{normal.y, -normal.x};
  for (;;) {
    const double theta = (rng.uniform() - 0.5) * std::numbers::pi;
    double s = 0.0;
    double c = 0.0;
    portable::sin_cos(theta, s, c);  // portable: the same directions on every platform
    if (rng.uniform() < portable::pow(c, exponent)) return s * tangent + c * normal;
  }
}
// Its density per radian: cos^n / c_n with c_n = integral of cos^n over [-pi/2, pi/2]
// = sqrt(pi) Gamma((n+1)/2) / Gamma(n/2 + 1).
inline double sample_lobe_pdf(double exponent, Vec2 normal, Vec2 direction) {
  const double c = dot(normal, direction);
  if (!(c > 0.0)) return 0.0;
  const double norm =
      std::sqrt(std::numbers::pi) * std::exp(std::lgamma(0.5 * (exponent + 1.0)) - std::lgamma(0.5 * exponent + 1.0));
  return std::pow(c, exponent) / norm;
}

// A beam: the diffuse distribution restricted to |theta| <= a, so sin(theta) is uniform in
// [-sin a, sin a] (pdf cos(theta) / (2 sin a)).
inline Vec2 square_to_beam(double u, double half_angle, Vec2 normal) {
  const double s = (2.0 * u - 1.0) * portable::sin(half_angle);
  const Vec2 tangent{normal.y, -normal.x};
  return s * tangent + std::sqrt(std::fmax(0.0, 1.0 - s * s)) * normal;
}
inline double square_to_beam_pdf(double half_angle, Vec2 normal, Vec2 direction) {
  const double c = dot(normal, direction);
  if (!(c > 0.0) || c < portable::cos(half_angle)) return 0.0;
  return c / (2.0 * portable::sin(half_angle));
}

}  // namespace flatland
