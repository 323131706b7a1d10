// PNG files through libpng (without it: stored, uncompressed, and write-only; png_io_stored.cpp): 8-bit RGB or RGBA
// rows, top row first. Writing is atomic (a temporary file renamed over the target), so a failure never leaves a
// partial picture.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include "flatland/base/status.hpp"

namespace flatland::png {

struct PngImage {
  int width = 0;
  int height = 0;
  int channels = 3;                  // 3 (RGB) or 4 (RGBA)
  std::vector<std::uint8_t> pixels;  // width * height * channels bytes, rows top to bottom
};

Result<std::string> encode_png(const PngImage& image);
// The same picture without compression (no libpng needed; png_io_stored.cpp).
Result<std::string> encode_png_stored(const PngImage& image);
// Written as every output is (files.hpp): `cancel` ends a wait for a FIFO's reader.
Status write_png(const std::string& path, const PngImage& image, const std::atomic<bool>* cancel = nullptr);
// Any PNG, converted to 8-bit RGBA.
Result<PngImage> read_png(const std::string& path);

}  // namespace flatland::png
