#include "app/picture.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

#include "flatland/results/result_io.hpp"
#include "png/png_io.hpp"

namespace flatland::app {

namespace {

struct Image {
  int width = 0;
  int height = 0;
  std::vector<float> rgb;  // linear colour, 3 floats per pixel

  void blend(int x, int y, const Spectrum& colour, double coverage) {
    float* pixel =
        &rgb[(static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x)) * 3];
    for (int c = 0; c < 3; ++c)
      pixel[c] = static_cast<float>(pixel[c] * (1.0 - coverage) + colour[static_cast<std::size_t>(c)] * coverage);
  }
};

// Anti-aliased thick segment a-b: coverage from the distance of each pixel centre to the segment.
void draw_segment(Image& image, Vec2 a, Vec2 b, double half_width, const Spectrum& colour) {
  const double reach = half_width + 1.0;
  const int x0 = std::max(0, static_cast<int>(std::floor(std::min(a.x, b.x) - reach)));
  const int x1 = std::min(image.width - 1, static_cast<int>(std::ceil(std::max(a.x, b.x) + reach)));
  const int y0 = std::max(0, static_cast<int>(std::floor(std::min(a.y, b.y) - reach)));
  const int y1 = std::min(image.height - 1, static_cast<int>(std::ceil(std::max(a.y, b.y) + reach)));
  const Vec2 ab = b - a;
  const double ab2 = std::max(length_squared(ab), 1e-12);
  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const Vec2 p{x + 0.5, y + 0.5};
      const double h = std::clamp(dot(p - a, ab) / ab2, 0.0, 1.0);
      const double distance = length(p - (a + h * ab));
      const double coverage = std::clamp(half_width + 0.5 - distance, 0.0, 1.0);
      if (coverage > 0.0) image.blend(x, y, colour, coverage);
    }
  }
}

double to_display(double linear) {
  // Reinhard tone curve, then the sRGB transfer function.
  const double mapped = linear / (1.0 + linear);
  return mapped <= 0.0031308 ? 12.92 * mapped : 1.055 * std::pow(mapped, 1.0 / 2.4) - 0.055;
}

PngImage to_png(const Image& image) {
  PngImage png;
  png.width = image.width;
  png.height = image.height;
  png.channels = 3;
  png.pixels.resize(image.rgb.size());
  for (std::size_t i = 0; i < png.pixels.size(); ++i)
    png.pixels[i] = static_cast<std::uint8_t>(std::lround(std::clamp(image.rgb[i], 0.0f, 1.0f) * 255.0f));
  return png;
}

}  // namespace

PngImage draw_picture(const Solver& solver, int width, int height) {
  const Scene& scene = solver.scene();
  Image image;
  image.width = width;
  image.height = height;
  image.rgb.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * 3, 0.06f);

  // Fit the scene's bounds into the picture with a margin; y points up in the scene.
  const Vec2 extent = scene.bounds.extent();
  const double margin = 0.06;
  const double zoom = std::min(width * (1 - 2 * margin) / std::max(extent.x, 1e-300),
                               height * (1 - 2 * margin) / std::max(extent.y, 1e-300));
  const Vec2 centre = scene.bounds.center();
  auto to_pixels = [&](Vec2 p) {
    return Vec2{0.5 * width + zoom * (p.x - centre.x), 0.5 * height - zoom * (p.y - centre.y)};
  };

  // Radiosity along every side, sampled about every two pixels. The tone mapping (docs/viewer.md,
  // Pictures): the exposure puts the 90th percentile of B on the curves that do not emit at
  // mid-grey, so reflectors are readable and emitters, usually far brighter, saturate; only when
  // nothing but emitters is lit do they set the scale.
  struct Band {
    std::vector<Vec2> points;
    std::vector<Vec2> normals;  // scene-space front normals
    std::vector<Spectrum> front, back;
    bool has_front = false, has_back = false;
  };
  std::vector<Band> bands;
  std::vector<double> levels;          // on curves that do not emit
  std::vector<double> emitter_levels;  // on emitters
  for (std::uint32_t c = 0; c < scene.curves.size(); ++c) {
    const Curve& curve = scene.curves[c];
    std::vector<double>& into = scene.is_emitter(curve) ? emitter_levels : levels;
    Band band;
    band.has_front = solver.has_side(c, Side::Front);
    band.has_back = solver.has_side(c, Side::Back);
    const int steps = std::clamp(static_cast<int>(curve.length * zoom / 2.0), 8, 4000);
    for (int j = 0; j <= steps; ++j) {
      const double s = curve.length * j / steps;
      const CurvePoint point = point_at_arc_length(scene, curve, s);
      const SceneSegment& segment = scene.segments[curve.first_segment + point.segment_in_curve];
      band.points.push_back(point.position);
      band.normals.push_back(unit_normal(segment.geometry.shape, point.t, scene.scale));
      band.front.push_back(solver.radiosity(c, Side::Front, point.u));
      band.back.push_back(solver.radiosity(c, Side::Back, point.u));
      for (const Spectrum* value : {&band.front.back(), &band.back.back()})
        for (int ch = 0; ch < scene.channels; ++ch)
          if ((*value)[static_cast<std::size_t>(ch)] > 0.0) into.push_back((*value)[static_cast<std::size_t>(ch)]);
    }
    bands.push_back(std::move(band));
  }
  double exposure = 1.0;
  if (levels.empty()) levels.swap(emitter_levels);
  if (!levels.empty()) {
    const auto percentile = levels.begin() + static_cast<std::ptrdiff_t>(levels.size() * 9 / 10);
    std::nth_element(levels.begin(), percentile, levels.end());
    if (*percentile > 0.0) exposure = 1.0 / *percentile;
  }
  auto display = [&](const Spectrum& value) {
    Spectrum colour{};
    for (std::size_t ch = 0; ch < 3; ++ch) colour[ch] = to_display(exposure * value[scene.channels == 1 ? 0 : ch]);
    return colour;
  };

  const double half_band = std::max(2.0, width / 320.0);
  const Spectrum absorber{0.22, 0.22, 0.24};
  for (std::uint32_t c = 0; c < bands.size(); ++c) {
    const Band& band = bands[c];
    // Mirrors, glass and detectors hold no light of their own: drawn as lines of their colour
    // (mirrors steel blue, glass cyan, detectors green).
    const Optics optics = scene.material_of(scene.curves[c]).optics;
    if (optics != Optics::Diffuse) {
      const Spectrum colour = optics == Optics::Mirror       ? Spectrum{0.45, 0.6, 0.95}
                              : optics == Optics::Dielectric ? Spectrum{0.25, 0.8, 0.9}
                                                             : Spectrum{0.3, 0.85, 0.35};
      for (std::size_t j = 0; j + 1 < band.points.size(); ++j)
        draw_segment(image, to_pixels(band.points[j]), to_pixels(band.points[j + 1]),
                     optics == Optics::Mirror ? 0.75 * half_band : 0.5 * half_band, colour);
      continue;
    }
    for (std::size_t j = 0; j + 1 < band.points.size(); ++j) {
      const Vec2 a = to_pixels(band.points[j]);
      const Vec2 b = to_pixels(band.points[j + 1]);
      // Pixel space flips y, so the front normal (x, y) becomes (x, -y).
      const Vec2 n{band.normals[j].x, -band.normals[j].y};
      for (int side = 0; side < 2; ++side) {
        const bool active = side == 0 ? band.has_front : band.has_back;
        const double sign = side == 0 ? 1.0 : -1.0;
        const double half = active ? half_band : 0.6;
        const Vec2 offset = (sign * half) * n;
        const Spectrum colour = !active ? absorber : side == 0 ? display(band.front[j]) : display(band.back[j]);
        draw_segment(image, a + offset, b + offset, half, colour);
      }
    }
  }

  return to_png(image);
}

}  // namespace flatland::app
