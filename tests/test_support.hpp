// Shared helpers of the test suites: scene loading, statistics with derived thresholds.
#pragma once

#include <cmath>
#include <span>
#include <string>

#include <gtest/gtest.h>

#include "flatland/scene.hpp"

namespace flatland::testing {

inline std::string source_path(const std::string& relative) {
  return std::string(FLATLAND_SOURCE_DIR) + "/" + relative;
}

inline Scene scene_from_text(const std::string& text) {
  Result<Scene> scene = parse_scene(text, "test-scene");
  if (!scene) {
    ADD_FAILURE() << scene.error().message;
    return Scene{};
  }
  return std::move(scene).value();
}

inline Scene scene_from_file(const std::string& relative) {
  Result<Scene> scene = load_scene(source_path(relative));
  if (!scene) {
    ADD_FAILURE() << scene.error().message;
    return Scene{};
  }
  return std::move(scene).value();
}

// Upper quantile of the chi-square distribution with k degrees of freedom at significance alpha
// = 1e-4 (Wilson-Hilferty approximation; z = 3.719 is the normal 1 - 1e-4 quantile). A correct
// sampler fails such a test with probability 1e-4; with fixed seeds the outcome is fixed.
inline double chi_square_critical(int k) {
  const double z = 3.719;
  const double a = 2.0 / (9.0 * k);
  return k * std::pow(1.0 - a + z * std::sqrt(a), 3.0);
}

// Pearson's statistic of observed counts against expected counts (bins with tiny expectations
// should be merged by the caller).
inline double chi_square(std::span<const double> observed, std::span<const double> expected) {
  double sum = 0.0;
  for (std::size_t i = 0; i < observed.size(); ++i) {
    const double d = observed[i] - expected[i];
    sum += d * d / expected[i];
  }
  return sum;
}

}  // namespace flatland::testing
