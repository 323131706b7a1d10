#include "flatland/scene/light_spectrum.hpp"

#include <algorithm>
#include <cmath>

#include "flatland/base/portable_math.hpp"

namespace flatland {

namespace {

// Planck's law per unit wavelength, up to a constant: lambda^-5 / (exp(c2 / (lambda T)) - 1),
// c2 = h c / k = 1.438777e7 nm K.
double planck(double nanometres, double kelvin) {
  constexpr double kSecondRadiation = 1.438777e7;
  const double x = kSecondRadiation / (nanometres * kelvin);
  const double scaled = nanometres / 1000.0;  // micrometres: keeps lambda^-5 near 1
  const double power5 = scaled * scaled * scaled * scaled * scaled;
  // For x beyond ~700 the exponential overflows: the density is zero to any precision.
  if (x > 700.0) return 0.0;
  return 1.0 / (power5 * (portable::exp(x) - 1.0));
}

constexpr int kBins = static_cast<int>(kMaxWavelength - kMinWavelength);  // 1-nm bins

}  // namespace

// The CIE 1931 2-degree standard observer, x, y and z every 5 nm from kMinWavelength to
// kMaxWavelength: the CIE's table as distributed by the Colour and Vision Research Laboratory
// (file ciexyz31_1, rows at multiples of 5 nm). Kept as data: analytic fits of these functions
// drift in the tails, where a few per cent of a small value decides the hue (a fit whose y falls
// slower than x past 690 nm turns deep red into green).
constexpr double kCieStep = 5.0;
constexpr std::array<std::array<double, 3>, 81> kCie1931 = {{
    {0.001368, 0.000039, 0.006450001},    // 380 nm
    {0.002236, 0.000064, 0.01054999},     // 385 nm
    {0.004243, 0.00012, 0.02005001},      // 390 nm
    {0.00765, 0.000217, 0.03621},         // 395 nm
    {0.01431, 0.000396, 0.06785001},      // 400 nm
    {0.02319, 0.00064, 0.1102},           // 405 nm
    {0.04351, 0.00121, 0.2074},           // 410 nm
    {0.07763, 0.00218, 0.3713},           // 415 nm
    {0.13438, 0.004, 0.6456},             // 420 nm
    {0.21477, 0.0073, 1.0390501},         // 425 nm
    {0.2839, 0.0116, 1.3856},             // 430 nm
    {0.3285, 0.01684, 1.62296},           // 435 nm
    {0.34828, 0.023, 1.74706},            // 440 nm
    {0.34806, 0.0298, 1.7826},            // 445 nm
    {0.3362, 0.038, 1.77211},             // 450 nm
    {0.3187, 0.048, 1.7441},              // 455 nm
    {0.2908, 0.06, 1.6692},               // 460 nm
    {0.2511, 0.0739, 1.5281},             // 465 nm
    {0.19536, 0.09098, 1.28764},          // 470 nm
    {0.1421, 0.1126, 1.0419},             // 475 nm
    {0.09564, 0.13902, 0.8129501},        // 480 nm
    {0.05795001, 0.1693, 0.6162},         // 485 nm
    {0.03201, 0.20802, 0.46518},          // 490 nm
    {0.0147, 0.2586, 0.3533},             // 495 nm
    {0.0049, 0.323, 0.272},               // 500 nm
    {0.0024, 0.4073, 0.2123},             // 505 nm
    {0.0093, 0.503, 0.1582},              // 510 nm
    {0.0291, 0.6082, 0.1117},             // 515 nm
    {0.06327, 0.71, 0.07824999},          // 520 nm
    {0.1096, 0.7932, 0.05725001},         // 525 nm
    {0.1655, 0.862, 0.04216},             // 530 nm
    {0.2257499, 0.9148501, 0.02984},      // 535 nm
    {0.2904, 0.954, 0.0203},              // 540 nm
    {0.3597, 0.9803, 0.0134},             // 545 nm
    {0.4334499, 0.9949501, 0.008749999},  // 550 nm
    {0.5120501, 1, 0.005749999},          // 555 nm
    {0.5945, 0.995, 0.0039},              // 560 nm
    {0.6784, 0.9786, 0.002749999},        // 565 nm
    {0.7621, 0.952, 0.0021},              // 570 nm
    {0.8425, 0.9154, 0.0018},             // 575 nm
    {0.9163, 0.87, 0.001650001},          // 580 nm
    {0.9786, 0.8163, 0.0014},             // 585 nm
    {1.0263, 0.757, 0.0011},              // 590 nm
    {1.0567, 0.6949, 0.001},              // 595 nm
    {1.0622, 0.631, 0.0008},              // 600 nm
    {1.0456, 0.5668, 0.0006},             // 605 nm
    {1.0026, 0.503, 0.00034},             // 610 nm
    {0.9384, 0.4412, 0.00024},            // 615 nm
    {0.8544499, 0.381, 0.00019},          // 620 nm
    {0.7514, 0.321, 0.0001},              // 625 nm
    {0.6424, 0.265, 0.00004999999},       // 630 nm
    {0.5419, 0.217, 0.00003},             // 635 nm
    {0.4479, 0.175, 0.00002},             // 640 nm
    {0.3608, 0.1382, 0.00001},            // 645 nm
    {0.2835, 0.107, 0},                   // 650 nm
    {0.2187, 0.0816, 0},                  // 655 nm
    {0.1649, 0.061, 0},                   // 660 nm
    {0.1212, 0.04458, 0},                 // 665 nm
    {0.0874, 0.032, 0},                   // 670 nm
    {0.0636, 0.0232, 0},                  // 675 nm
    {0.04677, 0.017, 0},                  // 680 nm
    {0.0329, 0.01192, 0},                 // 685 nm
    {0.0227, 0.00821, 0},                 // 690 nm
    {0.01584, 0.005723, 0},               // 695 nm
    {0.01135916, 0.004102, 0},            // 700 nm
    {0.008110916, 0.002929, 0},           // 705 nm
    {0.005790346, 0.002091, 0},           // 710 nm
    {0.004109457, 0.001484, 0},           // 715 nm
    {0.002899327, 0.001047, 0},           // 720 nm
    {0.00204919, 0.00074, 0},             // 725 nm
    {0.001439971, 0.00052, 0},            // 730 nm
    {0.0009999493, 0.0003611, 0},         // 735 nm
    {0.0006900786, 0.0002492, 0},         // 740 nm
    {0.0004760213, 0.0001719, 0},         // 745 nm
    {0.0003323011, 0.00012, 0},           // 750 nm
    {0.0002348261, 0.0000848, 0},         // 755 nm
    {0.0001661505, 0.00006, 0},           // 760 nm
    {0.000117413, 0.0000424, 0},          // 765 nm
    {0.00008307527, 0.00003, 0},          // 770 nm
    {0.00005870652, 0.0000212, 0},        // 775 nm
    {0.00004150994, 0.00001499, 0},       // 780 nm
}};
static_assert(kMinWavelength + kCieStep * (kCie1931.size() - 1) == kMaxWavelength);

std::array<double, 3> cie_1931(double nm) {
  // Linear between the table's rows; outside [kMinWavelength, kMaxWavelength] the nearest end (and
  // for NaN the first row: the comparisons below are false for it, so it never reaches the cast).
  const auto last = static_cast<double>(kCie1931.size() - 1);
  const double position = nm >= kMaxWavelength ? last : nm > kMinWavelength ? (nm - kMinWavelength) / kCieStep : 0.0;
  const std::size_t row = std::min(static_cast<std::size_t>(position), kCie1931.size() - 2);
  const double f = position - static_cast<double>(row);
  std::array<double, 3> xyz{};
  for (std::size_t i = 0; i < 3; ++i) xyz[i] = kCie1931[row][i] + f * (kCie1931[row + 1][i] - kCie1931[row][i]);
  return xyz;
}

Spectrum linear_srgb(const std::array<double, 3>& c) {
  return {3.2406 * c[0] - 1.5372 * c[1] - 0.4986 * c[2], -0.9689 * c[0] + 1.8758 * c[1] + 0.0415 * c[2],
          0.0557 * c[0] - 0.2040 * c[1] + 1.0570 * c[2]};
}

Spectrum channel_shares(double nm) {
  Spectrum rgb = linear_srgb(cie_1931(nm));
  double sum = 0.0;
  for (double& value : rgb) {
    value = std::max(value, 0.0);
    sum += value;
  }
  // r + g + b = 2.3274 x + 0.1346 y + 0.5999 z (the matrix's column sums are positive), and
  // x, y, z >= 0 with x > 0 at every wavelength (cie_1931 clamps to the table's ends): some
  // channel is positive, so sum > 0.
  if (!(sum > 0.0)) return {1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0};
  for (double& value : rgb) value /= sum;
  return rgb;
}

double EmitterSpectrum::density(double nm) const {
  switch (kind) {
    case Kind::Blackbody: return planck(nm, kelvin);
    case Kind::Line: return 0.0;
    case Kind::Table: {
      if (points.empty() || nm < points.front().first || nm > points.back().first) return 0.0;
      const auto after =
          std::upper_bound(points.begin(), points.end(), nm,
                           [](double value, const std::pair<double, double>& p) { return value < p.first; });
      if (after == points.end()) return points.back().second;
      const auto before = after - 1;
      const double f = (nm - before->first) / (after->first - before->first);
      return before->second + f * (after->second - before->second);
    }
  }
  return 0.0;
}

bool EmitterSpectrum::prepare() {
  if (kind == Kind::Line) {
    cdf.clear();
    mean_shares = channel_shares(line);
    return true;
  }
  cdf.assign(kBins + 1, 0.0);
  Spectrum shares{};
  double total = 0.0;
  for (int bin = 0; bin < kBins; ++bin) {
    const double middle = kMinWavelength + bin + 0.5;
    const double weight = std::max(density(middle), 0.0);
    total += weight;
    cdf[static_cast<std::size_t>(bin) + 1] = total;
    const Spectrum s = channel_shares(middle);
    for (std::size_t ch = 0; ch < 3; ++ch) shares[ch] += weight * s[ch];
  }
  if (!(total > 0.0) || !std::isfinite(total)) return false;
  for (double& value : cdf) value /= total;
  cdf.back() = 1.0;
  for (std::size_t ch = 0; ch < 3; ++ch) mean_shares[ch] = shares[ch] / total;
  return true;
}

double EmitterSpectrum::sample(double u) const {
  if (kind == Kind::Line) return line;
  // The first bin whose end exceeds u (bins of zero weight are never chosen).
  const auto end = std::upper_bound(cdf.begin() + 1, cdf.end(), u);
  const auto bin = std::min<std::ptrdiff_t>(end - cdf.begin() - 1, kBins - 1);
  const double low = cdf[static_cast<std::size_t>(bin)];
  const double high = cdf[static_cast<std::size_t>(bin) + 1];
  const double f = high > low ? std::clamp((u - low) / (high - low), 0.0, 1.0) : 0.5;
  return kMinWavelength + static_cast<double>(bin) + f;
}

}  // namespace flatland
