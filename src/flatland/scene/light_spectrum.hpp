// Spectral light: an emitter's spectrum (a black body, a line or a table), the wavelengths its
// photons draw from it, and how a wavelength's power is shared among the three colour channels
// through the CIE 1931 colour matching functions and linear sRGB (docs/optics.md, "Spectral
// light"). Every function here uses the four basic operations and portable::exp only, so a
// photon's wavelength and shares are the same bits on every platform.
#pragma once

#include <array>
#include <utility>
#include <vector>

namespace flatland {

using Spectrum = std::array<double, 3>;

// The wavelengths spectral light is drawn from, in nanometres: the visible range.
inline constexpr double kMinWavelength = 380.0;
inline constexpr double kMaxWavelength = 780.0;

// The CIE 1931 2-degree colour matching functions x, y, z at `nanometres`: the CIE's table every
// 5 nm over [kMinWavelength, kMaxWavelength], linear between rows, the nearest end outside.
std::array<double, 3> cie_1931(double nanometres);

// Linear sRGB (D65 white) of CIE XYZ.
Spectrum linear_srgb(const std::array<double, 3>& xyz);

// The share of light of wavelength `nanometres` that each colour channel receives: its linear sRGB
// with the negative components (colours outside the sRGB gamut, as every pure spectral colour is)
// set to zero, divided by their sum. The shares are >= 0 and sum to 1, so a photon's power is
// split among the channels without changing its total.
Spectrum channel_shares(double nanometres);

// An emitter's relative spectral power over [kMinWavelength, kMaxWavelength].
struct EmitterSpectrum {
  enum class Kind { Blackbody, Line, Table };
  Kind kind = Kind::Line;
  double kelvin = 0.0;                            // Blackbody: Planck's law at this temperature
  double line = 550.0;                            // Line: all the power at this wavelength (nm)
  std::vector<std::pair<double, double>> points;  // Table: (nm, relative power), linear between

  // Filled by prepare(): the cumulative distribution over 1-nm bins from kMinWavelength (for
  // drawing wavelengths), and the mean channel shares of its light (what the emitter's emittance
  // is split by).
  std::vector<double> cdf;
  Spectrum mean_shares{};

  // Relative power at `nanometres` (Line: not a density; unused).
  double density(double nanometres) const;
  // The bins and the mean shares, by the midpoint rule over 1-nm bins. False when the spectrum has
  // no power in the visible range.
  bool prepare();
  // A wavelength (nm) from uniform `u` in [0, 1): the inverse of the cumulative distribution,
  // linear within a bin.
  double sample(double u) const;
};

}  // namespace flatland
