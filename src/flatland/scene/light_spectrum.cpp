#include "flatland/scene/light_spectrum.hpp"

#include <algorithm>
#include <cmath>

#include "flatland/base/portable_math.hpp"

namespace flatland {

namespace {

// exp(-(x - mean)^2 / (2 sigma^2)) with sigma = below left of the mean and above right of it.
double lobe(double x, double mean, double below, double above) {
  const double t = (x - mean) / (x < mean ? below : above);
  return portable::exp(-0.5 * t * t);
}

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

std::array<double, 3> cie_1931(double nm) {
  const double x =
      1.056 * lobe(nm, 599.8, 37.9, 31.0) + 0.362 * lobe(nm, 442.0, 16.0, 26.7) - 0.065 * lobe(nm, 501.1, 20.4, 26.2);
  const double y = 0.821 * lobe(nm, 568.8, 46.9, 40.5) + 0.286 * lobe(nm, 530.9, 16.3, 31.1);
  const double z = 1.217 * lobe(nm, 437.0, 11.8, 36.0) + 0.681 * lobe(nm, 459.0, 26.0, 13.8);
  return {x, y, z};
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
  // The fit is positive over the visible range, so some channel is: sum > 0 there. (Outside it,
  // where no photon is drawn, green stands in.)
  if (!(sum > 0.0)) return {0.0, 1.0, 0.0};
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
