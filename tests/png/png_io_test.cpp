// PNG files: libpng's encoder and the stored (uncompressed) one both read back, through libpng, as
// the pixels they were given.
#include "png/png_io.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <tuple>

namespace flatland::png {
namespace {

PngImage noise(int width, int height, int channels, unsigned seed) {
  PngImage image{width, height, channels, {}};
  std::mt19937 random(seed);
  image.pixels.resize(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) *
                      static_cast<std::size_t>(channels));
  for (std::uint8_t& byte : image.pixels) byte = static_cast<std::uint8_t>(random() & 0xFFu);
  return image;
}

// The picture as read_png gives it: 8-bit RGBA.
std::vector<std::uint8_t> as_rgba(const PngImage& image) {
  if (image.channels == 4) return image.pixels;
  std::vector<std::uint8_t> rgba;
  for (std::size_t i = 0; i < image.pixels.size(); i += 3) {
    rgba.insert(rgba.end(), image.pixels.begin() + static_cast<std::ptrdiff_t>(i),
                image.pixels.begin() + static_cast<std::ptrdiff_t>(i + 3));
    rgba.push_back(255);
  }
  return rgba;
}

void expect_reads_back(const std::string& bytes, const PngImage& image, const std::string& name) {
  const std::filesystem::path path = std::filesystem::temp_directory_path() / ("flatland_png_test_" + name + ".png");
  std::ofstream(path, std::ios::binary) << bytes;
  Result<PngImage> read = read_png(path.string());
  std::filesystem::remove(path);
  ASSERT_TRUE(read.ok()) << read.error().message;
  EXPECT_EQ(read->width, image.width);
  EXPECT_EQ(read->height, image.height);
  EXPECT_EQ(read->pixels, as_rgba(image));
}

TEST(PngIo, StoredPicturesReadBackExactly) {
  // 1x1; an RGB row of odd length; a picture of several deflate blocks (over 65,535 bytes) whose
  // last block is short.
  for (const auto& [width, height, channels] : {std::tuple{1, 1, 4}, std::tuple{37, 5, 3}, std::tuple{301, 71, 4}}) {
    const PngImage image = noise(width, height, channels, static_cast<unsigned>(width));
    Result<std::string> bytes = encode_png_stored(image);
    ASSERT_TRUE(bytes.ok());
    expect_reads_back(*bytes, image, "stored" + std::to_string(width));
  }
}

TEST(PngIo, CompressedPicturesReadBackExactly) {
  const PngImage image = noise(64, 48, 3, 7);
  Result<std::string> bytes = encode_png(image);
  ASSERT_TRUE(bytes.ok());
  expect_reads_back(*bytes, image, "compressed");
}

TEST(PngIo, PixelsThatDoNotMatchTheSizeAreRefused) {
  PngImage image = noise(4, 4, 3, 1);
  image.pixels.pop_back();
  EXPECT_FALSE(encode_png_stored(image).ok());
  EXPECT_FALSE(encode_png(image).ok());
}

}  // namespace
}  // namespace flatland::png
