// libFuzzer target: the reference solver's checks of a scene and, where it accepts one, a coarse
// reference solve.
//
// The bytes are a scene file. When parse_scene accepts them, solve_reference runs with elements
// an eighth of the scene's size long (at least one a segment), two quadrature points and one
// thread: its refusals (glass, detectors, curved, rough or coloured mirrors, mirrors that face
// each other, non-diffuse emitters, too many elements) return errors, and a solve that runs must
// give finite radiosity at the middle of every curve's sides. A crash, a sanitizer report, an
// exception escaping, a hang or a non-finite radiosity (__builtin_trap) is a bug.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "flatland/reference/reference.hpp"
#include "flatland/scene/scene.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const flatland::Result<flatland::Scene> scene = flatland::parse_scene(text, "fuzz.json");
  if (!scene) return 0;
  flatland::ReferenceSettings settings;
  settings.max_element_length = scene->scale / 8.0;
  settings.quadrature = 2;
  settings.threads = 1;
  settings.memory_limit = std::size_t{256} << 20;
  if (flatland::reference_element_count(*scene, settings) > 2000.0) return 0;  // keeps a run short
  const flatland::Result<flatland::ReferenceSolution> solution = flatland::solve_reference(*scene, settings);
  if (!solution) return 0;
  for (std::uint32_t c = 0; c < scene->curves.size(); ++c)
    for (const flatland::Side side : {flatland::Side::Front, flatland::Side::Back}) {
      if (!scene->curves[c].has_side(side)) continue;
      for (const double value : solution->radiosity(c, side, 0.5 * scene->curves[c].segment_count))
        if (!std::isfinite(value)) __builtin_trap();
    }
  return 0;
}
