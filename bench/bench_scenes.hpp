// The benchmarks' scene: one layout of 49 segments (a closed wavy wall of 40, 8 two-sided
// obstacles, a lamp) as real cubics, as straight lines, or as the same lines written as cubics; and
// the ray the casters' benchmarks cast.
#pragma once

#include <cmath>
#include <cstdio>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "flatland/geometry/intersect.hpp"
#include "flatland/geometry/segments.hpp"

namespace flatland::bench {

// A ray of the casters' benchmarks, and how many of them they cycle through.
struct CastRay {
  Ray ray;
  RayOrigin from;
};
constexpr std::size_t kRays = 1 << 16;

enum class Layout { Cubics, Lines, LinesAsCubics };

inline std::string point(double x, double y) {
  char text[64];
  std::snprintf(text, sizeof text, "[%.17g,%.17g]", x, y);
  return text;
}

using Point = std::pair<double, double>;

// The points of a chain through `corners`: the corners themselves for lines, else 3k+1 control
// points whose inner ones sit at the thirds, pushed sideways by `bulge` times the chord for cubics.
inline std::string chain(Layout layout, const std::vector<Point>& corners, double bulge) {
  std::string text = point(corners[0].first, corners[0].second);
  for (std::size_t i = 1; i < corners.size(); ++i) {
    const auto [ax, ay] = corners[i - 1];
    const auto [bx, by] = corners[i];
    if (layout != Layout::Lines) {
      const double k = layout == Layout::Cubics ? bulge : 0.0;
      const double dx = bx - ax;
      const double dy = by - ay;
      text += "," + point(ax + dx / 3 - k * dy, ay + dy / 3 + k * dx);
      text += "," + point(ax + 2 * dx / 3 - k * dy, ay + 2 * dy / 3 + k * dx);
    }
    text += "," + point(bx, by);
  }
  return text;
}

// A closed wavy enclosure of 40 segments around 8 obstacles of one segment each, and a lamp:
// 49 segments in all.
inline std::string make_scene(Layout layout) {
  const char* key = layout == Layout::Lines ? "line" : "bezier";
  auto curve = [&](const std::string& id, const char* material, const char* sides, const std::vector<Point>& corners,
                   double bulge) {
    return std::string("{\"id\": \"") + id + "\", \"material\": \"" + material + "\", \"sides\": \"" + sides +
           "\", \"" + key + "\": [" + chain(layout, corners, bulge) + "]}";
  };
  std::vector<Point> ring;
  for (int i = 0; i <= 40; ++i) {
    const double angle = 2 * std::numbers::pi * (i % 40) / 40;
    const double radius = 5.0 + 0.6 * std::sin(5 * angle);
    ring.emplace_back(radius * std::cos(angle), radius * std::sin(angle));
  }
  std::string curves = curve("wall", "wall", "front", ring, 0.15);
  for (int j = 0; j < 8; ++j) {
    const double angle = 2 * std::numbers::pi * j / 8;
    curves += "," + curve("obstacle" + std::to_string(j), "wall", "both",
                          {{2.5 * std::cos(angle), 2.5 * std::sin(angle)},
                           {3.2 * std::cos(angle + 0.3), 3.2 * std::sin(angle + 0.3)}},
                          0.3);
  }
  curves += "," + curve("lamp", "lamp", "front", {{0.5, -0.3}, {-0.5, -0.3}}, 0.2);
  return R"({"flatland": 1, "materials": {"wall": {"reflectivity": 0.6},
             "lamp": {"reflectivity": 0.2, "emittance": 10}}, "curves": [)" +
         curves + "]}";
}

}  // namespace flatland::bench
