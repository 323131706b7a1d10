// PNG encoding without libpng (encode_png_stored): the rows go into the zlib stream as stored
// (uncompressed) deflate blocks, which every PNG reader accepts; the pictures are several times
// larger than libpng's. Builds without libpng (the web page, which writes only screenshots for
// download) take encode_png, write_png and read_png from here too.
#include <array>
#include <cstdint>
#include <string>

#include "flatland/base/files.hpp"
#include "png/png_io.hpp"

namespace flatland::png {

namespace {

std::uint32_t crc32(const std::string& bytes, std::size_t from) {
  static const std::array<std::uint32_t, 256> table = [] {
    std::array<std::uint32_t, 256> t{};
    for (std::uint32_t n = 0; n < 256; ++n) {
      std::uint32_t c = n;
      for (int k = 0; k < 8; ++k) c = (c & 1u) != 0 ? 0xEDB88320u ^ (c >> 1) : c >> 1;
      t[n] = c;
    }
    return t;
  }();
  std::uint32_t c = 0xFFFFFFFFu;
  for (std::size_t i = from; i < bytes.size(); ++i)
    c = table[(c ^ static_cast<std::uint8_t>(bytes[i])) & 0xFFu] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

void put32(std::string& out, std::uint32_t value) {
  for (int shift = 24; shift >= 0; shift -= 8) out += static_cast<char>((value >> shift) & 0xFFu);
}

// A chunk: length, type, data, and the CRC of type and data.
void chunk(std::string& out, const char* type, const std::string& data) {
  put32(out, static_cast<std::uint32_t>(data.size()));
  const std::size_t start = out.size();
  out += type;
  out += data;
  put32(out, crc32(out, start));
}

// A zlib stream of stored deflate blocks (at most 65,535 bytes each) and its Adler-32.
std::string zlib_stored(const std::string& raw) {
  std::string out = "\x78\x01";
  std::size_t at = 0;
  do {
    const std::size_t n = std::min<std::size_t>(65535, raw.size() - at);
    const bool last = at + n == raw.size();
    out += static_cast<char>(last ? 1 : 0);
    out += static_cast<char>(n & 0xFFu);
    out += static_cast<char>(n >> 8);
    out += static_cast<char>(~n & 0xFFu);
    out += static_cast<char>((~n >> 8) & 0xFFu);
    out.append(raw, at, n);
    at += n;
  } while (at < raw.size());
  std::uint32_t a = 1;
  std::uint32_t b = 0;
  for (const char byte : raw) {
    a = (a + static_cast<std::uint8_t>(byte)) % 65521u;
    b = (b + a) % 65521u;
  }
  put32(out, (b << 16) | a);
  return out;
}

}  // namespace

Result<std::string> encode_png_stored(const PngImage& image) {
  if (image.width <= 0 || image.height <= 0 || (image.channels != 3 && image.channels != 4) ||
      image.pixels.size() != static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height) *
                                 static_cast<std::size_t>(image.channels))
    return Error{"internal error: the picture's size does not match its pixels"};
  const std::size_t row = static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.channels);
  std::string raw;
  raw.reserve((row + 1) * static_cast<std::size_t>(image.height));
  for (int y = 0; y < image.height; ++y) {
    raw += '\0';  // filter: none
    raw.append(reinterpret_cast<const char*>(image.pixels.data()) + static_cast<std::size_t>(y) * row, row);
  }
  std::string header;
  put32(header, static_cast<std::uint32_t>(image.width));
  put32(header, static_cast<std::uint32_t>(image.height));
  header += '\x08';                                 // bits per channel
  header += image.channels == 4 ? '\x06' : '\x02';  // RGBA or RGB
  header += std::string(3, '\0');                   // deflate, adaptive filters, no interlace
  std::string bytes = "\x89PNG\r\n\x1a\n";
  chunk(bytes, "IHDR", header);
  chunk(bytes, "IDAT", zlib_stored(raw));
  chunk(bytes, "IEND", "");
  return bytes;
}

#ifndef FLATLAND_HAVE_LIBPNG
Result<std::string> encode_png(const PngImage& image) { return encode_png_stored(image); }

Status write_png(const std::string& path, const PngImage& image, const std::atomic<bool>* cancel) {
  Result<std::string> bytes = encode_png(image);
  if (!bytes) return Error{path + ": " + bytes.error().message};
  return write_file_atomically(path, *bytes, cancel);
}

Result<PngImage> read_png(const std::string& path) {
  return Error{path + ": this build reads no PNG files (it has no libpng)"};
}
#endif

}  // namespace flatland::png
