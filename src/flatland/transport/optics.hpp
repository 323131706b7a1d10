// Specular optics at a smooth interface, for the chains of photon_shooter.hpp: Fresnel's
// reflectance of unpolarised light and the critical angle. Angles are given by their cosines,
// measured from the interface's normal.
#pragma once

#include <cmath>

namespace flatland {

// The fraction of unpolarised light reflected where light in a medium of index n1 meets one of
// index n2, arriving at cos_in and leaving (refracted, by Snell's law n1 sin(in) = n2 sin(out))
// at cos_out: the mean of the s and p reflectances,
//   r_s = (n1 cos_in - n2 cos_out) / (n1 cos_in + n2 cos_out),
//   r_p = (n1 cos_out - n2 cos_in) / (n1 cos_out + n2 cos_in),
// R = (r_s^2 + r_p^2) / 2. At normal incidence ((n1 - n2) / (n1 + n2))^2; 1 at grazing incidence.
inline double fresnel_reflectance(double n1, double n2, double cos_in, double cos_out) {
  const double s_denominator = n1 * cos_in + n2 * cos_out;
  const double p_denominator = n1 * cos_out + n2 * cos_in;
  if (!(s_denominator > 0.0) || !(p_denominator > 0.0)) return 1.0;  // grazing on both sides
  const double r_s = (n1 * cos_in - n2 * cos_out) / s_denominator;
  const double r_p = (n1 * cos_out - n2 * cos_in) / p_denominator;
  return 0.5 * (r_s * r_s + r_p * r_p);
}

// The same from the angle of incidence alone (1 beyond the critical angle: total internal
// reflection).
inline double fresnel_reflectance(double n1, double n2, double cos_in) {
  const double eta = n1 / n2;
  const double sin2_out = eta * eta * (1.0 - cos_in * cos_in);
  if (sin2_out >= 1.0) return 1.0;
  return fresnel_reflectance(n1, n2, cos_in, std::sqrt(1.0 - sin2_out));
}

}  // namespace flatland
