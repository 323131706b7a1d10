// libFuzzer target: emitters' spectra and the colour each wavelength is booked as.
//
// The bytes are the value of a lamp's "spectrum" key ({"blackbody": K}, {"line": nm} or a table
// [[nm, power], ...]) in an otherwise fixed scene. When the scene reader accepts it, 256
// wavelengths are drawn from the spectrum (EmitterSpectrum::sample at evenly spaced u) and each is
// split among the colour channels through the CIE 1931 table and sRGB (channel_shares). The bytes'
// first 8, read as a double, are also given to channel_shares directly (any double, NaN and the
// infinities included). Invariants, checked with __builtin_trap: every drawn wavelength lies in
// the visible range, and every split is finite, nonnegative and sums to 1, as is the spectrum's
// mean split (the photon's power is kept whole in the books).
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

#include "flatland/scene/light_spectrum.hpp"
#include "flatland/scene/scene.hpp"

namespace {

void check_shares(const flatland::Spectrum& shares) {
  double sum = 0.0;
  for (const double share : shares) {
    if (!(share >= 0.0 && share <= 1.0)) __builtin_trap();
    sum += share;
  }
  if (!(std::fabs(sum - 1.0) <= 1e-12)) __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size >= sizeof(double)) {
    double nanometres = 0.0;
    std::memcpy(&nanometres, data, sizeof nanometres);
    check_shares(flatland::channel_shares(nanometres));
  }
  const std::string_view value(reinterpret_cast<const char*>(data), size);
  const std::string text =
      R"({"flatland": 2, "materials": {"lamp": {"emittance": 1, "spectrum": )" + std::string(value) +
      R"(}, "floor": {"reflectivity": 0.5}}, "curves": [{"id": "lamp", "material": "lamp", "line": [[1, 1], [-1, 1]]}, {"id": "floor", "material": "floor", "line": [[-2, 0], [2, 0]]}]})";
  const flatland::Result<flatland::Scene> scene = flatland::parse_scene(text, "fuzz.json");
  if (!scene) return 0;
  const auto& spectrum = scene->materials[scene->curves[0].material].spectrum;
  if (!spectrum) __builtin_trap();  // the lamp's spectrum was accepted, so it is there
  check_shares(spectrum->mean_shares);
  for (int k = 0; k < 256; ++k) {
    const double nanometres = spectrum->sample((k + 0.5) / 256.0);
    if (!(nanometres >= flatland::kMinWavelength && nanometres <= flatland::kMaxWavelength)) __builtin_trap();
    check_shares(flatland::channel_shares(nanometres));
  }
  return 0;
}
