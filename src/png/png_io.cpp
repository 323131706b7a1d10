#include "png/png_io.hpp"

#include <png.h>

#include <cstdio>

#include "flatland/results/result_io.hpp"

namespace flatland::png {

namespace {

void write_png_bytes(png_structp png, png_bytep data, png_size_t size) {
  auto* out = static_cast<std::string*>(png_get_io_ptr(png));
  out->append(reinterpret_cast<const char*>(data), size);
}
void flush_png(png_structp) {}

// libpng reports errors by longjmp, so these functions hold no C++ objects of their own: buffers
// and strings are owned by the caller.
bool encode_rows(const png_byte* rows, int width, int height, int channels, std::string* out) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  if (png == nullptr) return false;
  png_infop info = png_create_info_struct(png);
  if (info == nullptr || setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_set_write_fn(png, out, write_png_bytes, flush_png);
  png_set_IHDR(png, info, static_cast<png_uint_32>(width), static_cast<png_uint_32>(height), 8,
               channels == 4 ? PNG_COLOR_TYPE_RGBA : PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  const std::size_t stride = static_cast<std::size_t>(width) * static_cast<std::size_t>(channels);
  for (int y = 0; y < height; ++y) png_write_row(png, rows + static_cast<std::size_t>(y) * stride);
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

bool decode_rows(FILE* file, PngImage* image, std::vector<png_bytep>* row_pointers) {
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  if (png == nullptr) return false;
  png_infop info = png_create_info_struct(png);
  if (info == nullptr || setjmp(png_jmpbuf(png))) {
    png_destroy_read_struct(&png, &info, nullptr);
    return false;
  }
  png_init_io(png, file);
  png_read_info(png, info);
  png_set_expand(png);
  png_set_strip_16(png);
  png_set_gray_to_rgb(png);
  png_set_add_alpha(png, 0xff, PNG_FILLER_AFTER);
  png_read_update_info(png, info);
  image->width = static_cast<int>(png_get_image_width(png, info));
  image->height = static_cast<int>(png_get_image_height(png, info));
  image->channels = 4;
  image->pixels.resize(static_cast<std::size_t>(image->width) * static_cast<std::size_t>(image->height) * 4);
  row_pointers->resize(static_cast<std::size_t>(image->height));
  for (int y = 0; y < image->height; ++y)
    (*row_pointers)[static_cast<std::size_t>(y)] =
        image->pixels.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(image->width) * 4;
  png_read_image(png, row_pointers->data());
  png_read_end(png, nullptr);
  png_destroy_read_struct(&png, &info, nullptr);
  return true;
}

}  // namespace

Result<std::string> encode_png(const PngImage& image) {
  std::string bytes;
  if (image.width <= 0 || image.height <= 0 || (image.channels != 3 && image.channels != 4) ||
      image.pixels.size() != static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height) *
                                 static_cast<std::size_t>(image.channels))
    return Error{"internal error: the picture's size does not match its pixels"};
  if (!encode_rows(image.pixels.data(), image.width, image.height, image.channels, &bytes))
    return Error{"libpng failed while encoding the picture"};
  return bytes;
}

Status write_png(const std::string& path, const PngImage& image, const std::atomic<bool>* cancel) {
  Result<std::string> bytes = encode_png(image);
  if (!bytes) return Error{path + ": " + bytes.error().message};
  return write_file_atomically(path, *bytes, cancel);
}

Result<PngImage> read_png(const std::string& path) {
  FILE* file = std::fopen(path.c_str(), "rb");
  if (file == nullptr) return Error{path + ": cannot open the picture"};
  PngImage image;
  std::vector<png_bytep> rows;
  const bool ok = decode_rows(file, &image, &rows);
  std::fclose(file);
  if (!ok) return Error{path + ": not a readable PNG file"};
  return image;
}

}  // namespace flatland::png
