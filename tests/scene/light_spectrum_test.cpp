// Spectral light: the colour matching functions against the CIE's tabulated values, sRGB's white
// point, the channel shares, Planck's law against Wien's displacement law, and the wavelengths
// drawn from a spectrum against its density.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "flatland/scene/light_spectrum.hpp"
#include "flatland/scene/scene.hpp"

namespace flatland {
namespace {

TEST(LightSpectrum, ColourMatchingFunctionsGiveTheSpectrumLocus) {
  // Chromaticities (x / (x + y + z), y / (x + y + z)) of monochromatic light, as the CIE publishes
  // them for the 1931 observer: an answer independent of how the functions are stored.
  struct Row {
    double nm, x, y;
  };
  const Row rows[] = {{400.0, 0.17334, 0.00480}, {450.0, 0.15664, 0.01771}, {500.0, 0.00817, 0.53842},
                      {550.0, 0.30160, 0.69231}, {600.0, 0.62704, 0.37249}, {650.0, 0.72599, 0.27401},
                      {700.0, 0.73469, 0.26531}, {750.0, 0.73469, 0.26531}, {780.0, 0.73469, 0.26531}};
  for (const Row& row : rows) {
    const std::array<double, 3> xyz = cie_1931(row.nm);
    const double sum = xyz[0] + xyz[1] + xyz[2];
    EXPECT_NEAR(xyz[0] / sum, row.x, 2e-4) << row.nm;
    EXPECT_NEAR(xyz[1] / sum, row.y, 2e-4) << row.nm;
  }
  // The luminous efficiency peaks at 555 nm with y = 1.
  EXPECT_DOUBLE_EQ(cie_1931(555.0)[1], 1.0);
}

TEST(LightSpectrum, EqualEnergyLightIsTheWhitePointOfXyz) {
  // The 1931 functions are normalised so their integrals are equal: light with the same power at
  // every wavelength has chromaticity (1/3, 1/3). Integrated with the midpoint rule on 0.1 nm.
  std::array<double, 3> total{};
  for (double nm = kMinWavelength + 0.05; nm < kMaxWavelength; nm += 0.1) {
    const std::array<double, 3> xyz = cie_1931(nm);
    for (std::size_t i = 0; i < 3; ++i) total[i] += 0.1 * xyz[i];
  }
  const double sum = total[0] + total[1] + total[2];
  EXPECT_NEAR(total[0] / sum, 1.0 / 3.0, 1e-4);
  EXPECT_NEAR(total[1] / sum, 1.0 / 3.0, 1e-4);
  EXPECT_NEAR(total[1], 106.857, 0.05);  // the integral of y over the visible range
}

TEST(LightSpectrum, DeepRedIsRed) {
  // Every wavelength from 620 nm to the end of the range lies outside sRGB on the red side: its
  // green and blue are negative and set to zero, so all its power goes to red.
  for (double nm = 620.0; nm <= kMaxWavelength; nm += 0.5) {
    const Spectrum s = channel_shares(nm);
    EXPECT_GT(s[0], s[1]) << nm;
    EXPECT_GE(s[1], s[2]) << nm;
    EXPECT_DOUBLE_EQ(s[0], 1.0) << nm;
  }
}

TEST(LightSpectrum, SrgbOfTheD65WhiteIsWhite) {
  const Spectrum white = linear_srgb({0.95047, 1.0, 1.08883});
  for (double channel : white) EXPECT_NEAR(channel, 1.0, 2e-3);
}

TEST(LightSpectrum, SharesArePositiveSumToOneAndFollowTheHue) {
  for (double nm = kMinWavelength; nm <= kMaxWavelength; nm += 1.0) {
    const Spectrum s = channel_shares(nm);
    EXPECT_NEAR(s[0] + s[1] + s[2], 1.0, 1e-15) << nm;
    for (double share : s) EXPECT_GE(share, 0.0) << nm;
  }
  EXPECT_GT(channel_shares(650.0)[0], 0.9);  // red
  EXPECT_GT(channel_shares(530.0)[1], 0.9);  // green
  EXPECT_GT(channel_shares(460.0)[2], 0.8);  // blue
}

TEST(LightSpectrum, BlackbodyPeaksWhereWiensLawSays) {
  // lambda_max = b / T, b = 2.897772e6 nm K: for 5000 K, 579.6 nm.
  EmitterSpectrum sun;
  sun.kind = EmitterSpectrum::Kind::Blackbody;
  sun.kelvin = 5000.0;
  double best = 0.0, at = 0.0;
  for (double nm = 500.0; nm <= 650.0; nm += 0.1) {
    const double d = sun.density(nm);
    if (d > best) {
      best = d;
      at = nm;
    }
  }
  EXPECT_NEAR(at, 2.897772e6 / 5000.0, 0.15);
  // A hot body is bluer than a cool one.
  ASSERT_TRUE(sun.prepare());
  EmitterSpectrum candle = sun;
  candle.kelvin = 1900.0;
  ASSERT_TRUE(candle.prepare());
  EXPECT_GT(sun.mean_shares[2], candle.mean_shares[2]);
  EXPECT_GT(candle.mean_shares[0], sun.mean_shares[0]);
}

TEST(LightSpectrum, DrawnWavelengthsFollowTheSpectrum) {
  // A triangular table from 450 to 650 nm peaking at 500: its mean is (450 + 500 + 650) / 3 and
  // its variance (a^2 + b^2 + c^2 - ab - ac - bc) / 18. Stratified draws (u = (i + 1/2) / n)
  // leave only the discretisation: the mean within 0.05 nm.
  EmitterSpectrum table;
  table.kind = EmitterSpectrum::Kind::Table;
  table.points = {{450.0, 0.0}, {500.0, 1.0}, {650.0, 0.0}};
  ASSERT_TRUE(table.prepare());
  const int n = 100'000;
  double sum = 0.0, squares = 0.0;
  for (int i = 0; i < n; ++i) {
    const double nm = table.sample((i + 0.5) / n);
    EXPECT_GE(nm, 450.0);
    EXPECT_LE(nm, 650.0);
    sum += nm;
    squares += nm * nm;
  }
  const double mean = sum / n;
  EXPECT_NEAR(mean, (450.0 + 500.0 + 650.0) / 3.0, 0.05);
  const double a = 450.0, b = 500.0, c = 650.0;
  const double variance = (a * a + b * b + c * c - a * b - a * c - b * c) / 18.0;
  EXPECT_NEAR(squares / n - mean * mean, variance, 0.01 * variance);
  // A line: every photon at its wavelength, its shares the line's.
  EmitterSpectrum line;
  line.line = 589.0;
  ASSERT_TRUE(line.prepare());
  EXPECT_EQ(line.sample(0.3), 589.0);
  EXPECT_EQ(line.mean_shares, channel_shares(589.0));
  // No power in the visible range: refused.
  EmitterSpectrum infrared;
  infrared.kind = EmitterSpectrum::Kind::Table;
  infrared.points = {{800.0, 1.0}, {900.0, 1.0}};
  EXPECT_FALSE(infrared.prepare());
}

TEST(LightSpectrum, ASpectralEmitterSplitsItsEmittanceByItsMeanShares) {
  const Result<Scene> scene = parse_scene(R"({"flatland": 2,
      "materials": {"sun": {"emittance": 2, "spectrum": {"blackbody": 6500}}, "floor": {"reflectivity": 0.5}},
      "curves": [{"id": "sun", "material": "sun", "line": [[1, 1], [0, 1]]},
                 {"id": "floor", "material": "floor", "line": [[0, 0], [1, 0]], "emittance": 0}]})",
                                          "spectral.json");
  ASSERT_TRUE(scene.ok()) << scene.error().message;
  EXPECT_EQ(scene->channels, 3);
  const Material& sun = scene->materials[0];
  ASSERT_TRUE(sun.spectrum.has_value());
  double total = 0.0;
  for (std::size_t ch = 0; ch < 3; ++ch) {
    EXPECT_DOUBLE_EQ(sun.emittance[ch], 6.0 * sun.spectrum->mean_shares[ch]);
    total += sun.emittance[ch];
  }
  EXPECT_NEAR(total, 6.0, 1e-12);  // as a grey 2 in a colour scene
  // 6500 K is near white: no channel below a fifth.
  for (double share : sun.spectrum->mean_shares) EXPECT_GT(share, 0.2);
}

}  // namespace
}  // namespace flatland
