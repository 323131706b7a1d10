// The viewer's OpenGL 3.3 core renderer, shared by the window (`flatland view`) and the offscreen
// picture (`flatland render`): photon paths accumulated additively into a floating-point buffer and
// tone mapped (into an 8-bit buffer of the same size, again only when the paths or the exposure
// changed), that laid over the background, then the overlay (curves, radiosity bands and graphs,
// markers) on top. It draws into whatever framebuffer is bound; the caller owns the GL context,
// which must be current.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "flatland/base/status.hpp"
#include "viewer/frame.hpp"

namespace flatland::viewer {

// The GLSL source of a shader by file name ("paths.vert"): from `directory` when it is not empty
// (for shader development: edit shaders/ and rerun without rebuilding), else the copy built into
// the executable from shaders/.
Result<std::string> shader_source(const std::string& name, const std::string& directory);

class Renderer {
 public:
  // Compiles and links every program. A compile or link error returns the shader's name and the
  // GL info log. `shader_directory` as for shader_source.
  // `path_resolution` is the path buffer's size relative to the framebuffer: 1 for pictures, 0.5 in
  // the viewer, where a software rasteriser's fill rate limits how many paths a frame can draw (half
  // the resolution halves the pixels of every 1-pixel line; the buffer is smoothly upsampled).
  static Result<std::unique_ptr<Renderer>> create(const std::string& shader_directory = "",
                                                  float path_resolution = 1.0f);
  ~Renderer();
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;

  // Updates the path buffer as `paths` says, then draws the tone-mapped paths and the overlay into
  // the bound framebuffer, whose size is the view's: inside `stage` (pixels, y down) when given,
  // the rest filled with the background (the viewer's docked panels cover it; a software
  // rasteriser's fill rate is the viewer's largest cost).
  // Fails only when the path buffer cannot be made (too large a picture); nothing is drawn then.
  Status draw(const std::vector<LineVertex>& overlay, const PathDraw& paths, const ViewTransform& view,
              float path_exposure, const PixelRect* stage = nullptr);

  // (Re)allocates an RGBA8 colour framebuffer of this size (generating the objects when they are
  // 0) and leaves it bound; an error when it is incomplete (too large).
  static Status make_colour_framebuffer(int width, int height, unsigned& framebuffer, unsigned& colour);

  // The bound framebuffer's pixels, RGBA8, rows from top to bottom.
  static std::vector<std::uint8_t> read_pixels(int width, int height);

  static constexpr float kBackground[3] = {0.07f, 0.075f, 0.09f};

 private:
  Renderer() = default;
  Status ensure_hdr_target(int width, int height);

  unsigned lines_program_ = 0;
  unsigned paths_program_ = 0;
  unsigned tonemap_program_ = 0;
  unsigned composite_program_ = 0;
  unsigned decay_program_ = 0;
  unsigned field_program_ = 0;
  // The light field's texture (RGBA16F) and the image it holds.
  unsigned field_texture_ = 0;
  std::shared_ptr<const FieldImage> uploaded_field_;
  unsigned lines_vao_ = 0;
  unsigned lines_vbo_ = 0;
  unsigned paths_vao_ = 0;
  unsigned paths_vbo_ = 0;
  unsigned empty_vao_ = 0;
  unsigned hdr_framebuffer_ = 0;
  unsigned hdr_texture_ = 0;
  // The tone-mapped paths, premultiplied, at the path buffer's size: the exponentials and powers
  // of the tone map run on a quarter of the viewer's pixels, and not at all in a frame where
  // neither the paths nor the exposure changed.
  unsigned mapped_framebuffer_ = 0;
  unsigned mapped_texture_ = 0;
  bool mapped_valid_ = false;
  bool hdr_empty_ = true;  // the float path buffer holds nothing (cleared, nothing added since)
  float mapped_exposure_ = 0.0f;
  int hdr_width_ = 0;
  int hdr_height_ = 0;
  float path_resolution_ = 1.0f;
};

}  // namespace flatland::viewer
