#include "viewer/renderer.hpp"

#include "viewer/gl.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>

namespace flatland::viewer {

namespace {

// Overlay vertices uploaded and drawn at a time: whole triangles, 96 MB.
constexpr std::size_t kOverlayPiece = std::size_t{3} << 20;

struct EmbeddedShader {
  const char* name;
  const char* source;
};
constexpr EmbeddedShader kEmbeddedShaders[] = {
#include "flatland_shaders.inc"
};

Result<unsigned> compile(GLenum type, const std::string& name, const std::string& directory) {
  Result<std::string> source = shader_source(name, directory);
  if (!source) return source.error();
  // The context's GLSL version first (a #version line of a shader from --shaders gives way to it).
  std::string code = kGlslHeader;
  std::istringstream lines(*source);
  for (std::string line; std::getline(lines, line);)
    if (line.rfind("#version", 0) != 0) code += line + "\n";
  const GLuint shader = glCreateShader(type);
  const char* text = code.c_str();
  glShaderSource(shader, 1, &text, nullptr);
  glCompileShader(shader);
  GLint ok = GL_FALSE;
  glGetShaderiv(shader, GL_COMPILE_STATUS, &ok);
  if (ok != GL_TRUE) {
    GLint length = 0;
    glGetShaderiv(shader, GL_INFO_LOG_LENGTH, &length);
    std::string log(static_cast<std::size_t>(std::max(length, 1)), '\0');
    glGetShaderInfoLog(shader, length, nullptr, log.data());
    glDeleteShader(shader);
    while (!log.empty() && (log.back() == '\0' || log.back() == '\n')) log.pop_back();
    return Error{"shader " + name + " does not compile: " + log};
  }
  return shader;
}

Result<unsigned> link(const std::string& vertex, const std::string& fragment, const std::string& directory) {
  Result<unsigned> vs = compile(GL_VERTEX_SHADER, vertex, directory);
  if (!vs) return vs.error();
  Result<unsigned> fs = compile(GL_FRAGMENT_SHADER, fragment, directory);
  if (!fs) {
    glDeleteShader(*vs);
    return fs.error();
  }
  const GLuint program = glCreateProgram();
  glAttachShader(program, *vs);
  glAttachShader(program, *fs);
  glLinkProgram(program);
  glDeleteShader(*vs);
  glDeleteShader(*fs);
  GLint ok = GL_FALSE;
  glGetProgramiv(program, GL_LINK_STATUS, &ok);
  if (ok != GL_TRUE) {
    GLint length = 0;
    glGetProgramiv(program, GL_INFO_LOG_LENGTH, &length);
    std::string log(static_cast<std::size_t>(std::max(length, 1)), '\0');
    glGetProgramInfoLog(program, length, nullptr, log.data());
    glDeleteProgram(program);
    while (!log.empty() && (log.back() == '\0' || log.back() == '\n')) log.pop_back();
    return Error{"shaders " + vertex + " + " + fragment + " do not link: " + log};
  }
  return program;
}

void set_view_uniforms(unsigned program, const ViewTransform& view) {
  glUniform2f(glGetUniformLocation(program, "u_center"), static_cast<float>(view.center.x),
              static_cast<float>(view.center.y));
  glUniform1f(glGetUniformLocation(program, "u_scale"), static_cast<float>(view.scale));
  glUniform2f(glGetUniformLocation(program, "u_viewport"), static_cast<float>(view.width),
              static_cast<float>(view.height));
}

}  // namespace

Result<std::string> shader_source(const std::string& name, const std::string& directory) {
  if (!directory.empty()) {
    const std::string path = directory + "/" + name;
    std::ifstream file(path, std::ios::binary);
    if (!file) return Error{path + ": cannot read the shader; check the shader directory"};
    std::ostringstream text;
    text << file.rdbuf();
    return text.str();
  }
  for (const EmbeddedShader& shader : kEmbeddedShaders)
    if (name == shader.name) return std::string(shader.source);
  return Error{"shader " + name + " is not built into this executable"};
}

Result<std::unique_ptr<Renderer>> Renderer::create(const std::string& shader_directory, float path_resolution) {
  std::unique_ptr<Renderer> renderer(new Renderer());
  renderer->path_resolution_ = std::clamp(path_resolution, 0.125f, 1.0f);
  Result<unsigned> lines = link("lines.vert", "lines.frag", shader_directory);
  if (!lines) return lines.error();
  renderer->lines_program_ = *lines;
  Result<unsigned> paths = link("paths.vert", "paths.frag", shader_directory);
  if (!paths) return paths.error();
  renderer->paths_program_ = *paths;
  Result<unsigned> tonemap = link("tonemap.vert", "tonemap.frag", shader_directory);
  if (!tonemap) return tonemap.error();
  renderer->tonemap_program_ = *tonemap;
  Result<unsigned> composite = link("tonemap.vert", "composite.frag", shader_directory);
  if (!composite) return composite.error();
  renderer->composite_program_ = *composite;
  Result<unsigned> decay = link("tonemap.vert", "decay.frag", shader_directory);
  if (!decay) return decay.error();
  renderer->decay_program_ = *decay;
  Result<unsigned> field = link("field.vert", "field.frag", shader_directory);
  if (!field) return field.error();
  renderer->field_program_ = *field;

  glGenVertexArrays(1, &renderer->lines_vao_);
  glGenBuffers(1, &renderer->lines_vbo_);
  glBindVertexArray(renderer->lines_vao_);
  glBindBuffer(GL_ARRAY_BUFFER, renderer->lines_vbo_);
  const auto stride = static_cast<GLsizei>(sizeof(LineVertex));
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 2, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<void*>(offsetof(LineVertex, x)));
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 2, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<void*>(offsetof(LineVertex, offset_x)));
  glEnableVertexAttribArray(2);
  glVertexAttribPointer(2, 4, GL_FLOAT, GL_FALSE, stride, reinterpret_cast<void*>(offsetof(LineVertex, r)));

  glGenVertexArrays(1, &renderer->paths_vao_);
  glGenBuffers(1, &renderer->paths_vbo_);
  glBindVertexArray(renderer->paths_vao_);
  glBindBuffer(GL_ARRAY_BUFFER, renderer->paths_vbo_);
  const auto path_stride = static_cast<GLsizei>(sizeof(PathInstance));
  glEnableVertexAttribArray(0);
  glVertexAttribPointer(0, 4, GL_FLOAT, GL_FALSE, path_stride, reinterpret_cast<void*>(offsetof(PathInstance, from_x)));
  glVertexAttribDivisor(0, 1);
  glEnableVertexAttribArray(1);
  glVertexAttribPointer(1, 4, GL_FLOAT, GL_FALSE, path_stride, reinterpret_cast<void*>(offsetof(PathInstance, r)));
  glVertexAttribDivisor(1, 1);
  glEnableVertexAttribArray(2);
  glVertexAttribPointer(2, 1, GL_FLOAT, GL_FALSE, path_stride, reinterpret_cast<void*>(offsetof(PathInstance, width)));
  glVertexAttribDivisor(2, 1);

  glGenVertexArrays(1, &renderer->empty_vao_);
  glBindVertexArray(0);
  return renderer;
}

Renderer::~Renderer() {
  glDeleteProgram(lines_program_);
  glDeleteProgram(paths_program_);
  glDeleteProgram(tonemap_program_);
  glDeleteProgram(composite_program_);
  glDeleteProgram(decay_program_);
  glDeleteProgram(field_program_);
  if (field_texture_ != 0) glDeleteTextures(1, &field_texture_);
  glDeleteVertexArrays(1, &lines_vao_);
  glDeleteVertexArrays(1, &paths_vao_);
  glDeleteVertexArrays(1, &empty_vao_);
  glDeleteBuffers(1, &lines_vbo_);
  glDeleteBuffers(1, &paths_vbo_);
  if (hdr_framebuffer_ != 0) glDeleteFramebuffers(1, &hdr_framebuffer_);
  if (hdr_texture_ != 0) glDeleteTextures(1, &hdr_texture_);
  if (mapped_framebuffer_ != 0) glDeleteFramebuffers(1, &mapped_framebuffer_);
  if (mapped_texture_ != 0) glDeleteTextures(1, &mapped_texture_);
}

namespace {

// (Re)allocates a texture of this size and format, attached to the framebuffer (generating both
// when they are 0), and leaves the framebuffer bound; whether it is complete.
bool attach_texture(int width, int height, GLint format, GLenum type, unsigned& framebuffer, unsigned& texture) {
  if (framebuffer == 0) {
    glGenFramebuffers(1, &framebuffer);
    glGenTextures(1, &texture);
  }
  glBindTexture(GL_TEXTURE_2D, texture);
  glTexImage2D(GL_TEXTURE_2D, 0, format, width, height, 0, GL_RGBA, type, nullptr);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
  glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
  glBindFramebuffer(GL_FRAMEBUFFER, framebuffer);
  glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, texture, 0);
  return glCheckFramebufferStatus(GL_FRAMEBUFFER) == GL_FRAMEBUFFER_COMPLETE;
}

}  // namespace

Status Renderer::ensure_hdr_target(int width, int height) {
  if (hdr_framebuffer_ != 0 && width == hdr_width_ && height == hdr_height_) return ok_status();
  mapped_valid_ = false;
  if (!attach_texture(width, height, path_buffer_format(), GL_FLOAT, hdr_framebuffer_, hdr_texture_) ||
      !attach_texture(width, height, GL_RGBA8, GL_UNSIGNED_BYTE, mapped_framebuffer_, mapped_texture_)) {
    hdr_width_ = 0;
    hdr_height_ = 0;
    return Error{"cannot make the " + std::to_string(width) + "x" + std::to_string(height) +
                 " path buffers (out of graphics memory?); use a smaller picture"};
  }
  hdr_empty_ = true;
  glBindFramebuffer(GL_FRAMEBUFFER, hdr_framebuffer_);
  glClearColor(0.0f, 0.0f, 0.0f, 0.0f);
  glClear(GL_COLOR_BUFFER_BIT);
  hdr_width_ = width;
  hdr_height_ = height;
  return ok_status();
}

Status Renderer::draw(const std::vector<LineVertex>& overlay, const PathDraw& paths, const ViewTransform& view,
                      float path_exposure, const PixelRect* stage) {
  if (view.width <= 0 || view.height <= 0) return ok_status();  // a minimised window
  GLint target = 0;
  glGetIntegerv(GL_DRAW_FRAMEBUFFER_BINDING, &target);
  glDisable(GL_DEPTH_TEST);
  glDisable(GL_CULL_FACE);
  glDisable(GL_SCISSOR_TEST);

  // The path buffer (32-bit float: sums of many faint paths, and subtraction, stay exact enough),
  // at path_resolution_ of the framebuffer.
  ViewTransform path_view = view;
  path_view.width = std::max(1, static_cast<int>(std::lround(static_cast<float>(view.width) * path_resolution_)));
  path_view.height = std::max(1, static_cast<int>(std::lround(static_cast<float>(view.height) * path_resolution_)));
  path_view.scale = view.scale * path_view.width / view.width;
  if (Status made = ensure_hdr_target(path_view.width, path_view.height); !made) {
    glBindFramebuffer(GL_FRAMEBUFFER, static_cast<GLuint>(target));
    return made;
  }
  glBindFramebuffer(GL_FRAMEBUFFER, hdr_framebuffer_);
  glViewport(0, 0, path_view.width, path_view.height);
  if (paths.clear) {
    glClearColor(0.0f, 0.0f, 0.0f, 0.0f);
    glClear(GL_COLOR_BUFFER_BIT);
  }
  glEnable(GL_BLEND);
  if (paths.decay != 1.0f) {
    glBlendFunc(GL_ZERO, GL_CONSTANT_COLOR);
    glBlendColor(paths.decay, paths.decay, paths.decay, paths.decay);
    glUseProgram(decay_program_);
    glBindVertexArray(empty_vao_);
    glDrawArrays(GL_TRIANGLES, 0, 3);
  }
  const bool field_drawn = paths.field != nullptr && paths.clear && paths.field->width > 0;
  if (field_drawn) {
    const FieldImage& field = *paths.field;
    if (field_texture_ == 0) glGenTextures(1, &field_texture_);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, field_texture_);
    if (uploaded_field_ != paths.field) {
      // Half floats hold the normalised fluence (about 0 .. 100) to 3 digits; they are filterable
      // in OpenGL 3.3 and WebGL2 alike (32-bit floats need an extension in WebGL2).
      glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
      glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA16F, field.width, field.height, 0, GL_RGBA, GL_FLOAT, field.rgba.data());
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
      glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
      uploaded_field_ = paths.field;
    }
    glBlendFunc(GL_ONE, GL_ONE);
    glUseProgram(field_program_);
    set_view_uniforms(field_program_, path_view);
    glUniform4f(glGetUniformLocation(field_program_, "u_box"), static_cast<float>(field.box.lower.x),
                static_cast<float>(field.box.lower.y), static_cast<float>(field.box.upper.x),
                static_cast<float>(field.box.upper.y));
    glUniform1i(glGetUniformLocation(field_program_, "u_field"), 0);
    glBindVertexArray(empty_vao_);
    glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
  }
  if (!paths.instances.empty()) {
    glBlendFunc(GL_ONE, GL_ONE);
    glUseProgram(paths_program_);
    set_view_uniforms(paths_program_, path_view);
    glUniform1i(glGetUniformLocation(paths_program_, "u_lines"), paths.lines ? 1 : 0);
    glBindVertexArray(paths_vao_);
    glBindBuffer(GL_ARRAY_BUFFER, paths_vbo_);
    glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(paths.instances.size() * sizeof(PathInstance)),
                 paths.instances.data(), GL_STREAM_DRAW);
    const auto count = static_cast<GLsizei>(paths.instances.size());
    // A quad per path: as wide as an extended ray, or 2 pixels for a point ray's antialiased line.
    glDrawArraysInstanced(GL_TRIANGLE_STRIP, 0, 4, count);
  }

  // The tone map, into the 8-bit buffer of the same size, when the paths or the exposure changed.
  // The normalisation is for full-resolution pixels; a coarser buffer holds lines that are as many
  // times shorter in its pixels, over an area smaller by the square.
  const float resolution = static_cast<float>(path_view.width) / static_cast<float>(view.width);
  // The field comes normalised: its exposure is the user's alone.
  const float exposure = paths.field ? path_exposure : path_exposure * paths.normalisation * resolution;
  // (With the paths hidden every frame clears an empty buffer: nothing changes.)
  const bool was_empty = hdr_empty_;
  if (paths.clear) hdr_empty_ = true;
  if (!paths.instances.empty() || field_drawn) hdr_empty_ = false;
  const bool changed =
      !paths.instances.empty() || field_drawn || (paths.clear && !was_empty) || (paths.decay != 1.0f && !hdr_empty_);
  if (changed || !mapped_valid_ || exposure != mapped_exposure_) {
    glDisable(GL_BLEND);
    glBindFramebuffer(GL_FRAMEBUFFER, mapped_framebuffer_);
    glUseProgram(tonemap_program_);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, hdr_texture_);
    glUniform1i(glGetUniformLocation(tonemap_program_, "u_hdr"), 0);
    glUniform1f(glGetUniformLocation(tonemap_program_, "u_exposure"), exposure);
    glBindVertexArray(empty_vao_);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glEnable(GL_BLEND);
    mapped_valid_ = true;
    mapped_exposure_ = exposure;
  }

  glBindFramebuffer(GL_FRAMEBUFFER, static_cast<GLuint>(target));
  glViewport(0, 0, view.width, view.height);
  glClearColor(kBackground[0], kBackground[1], kBackground[2], 1.0f);
  glClear(GL_COLOR_BUFFER_BIT);
  if (stage != nullptr) {
    // Whole pixels that the stage touches; GL counts rows from the bottom.
    const int x0 = std::clamp(static_cast<int>(std::floor(stage->x0)), 0, view.width);
    const int x1 = std::clamp(static_cast<int>(std::ceil(stage->x1)), x0, view.width);
    const int y0 = std::clamp(static_cast<int>(std::floor(stage->y0)), 0, view.height);
    const int y1 = std::clamp(static_cast<int>(std::ceil(stage->y1)), y0, view.height);
    glEnable(GL_SCISSOR_TEST);
    glScissor(x0, view.height - y1, x1 - x0, y1 - y0);
  }
  glBlendFuncSeparate(GL_ONE, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
  glUseProgram(composite_program_);
  glActiveTexture(GL_TEXTURE0);
  glBindTexture(GL_TEXTURE_2D, mapped_texture_);
  glUniform1i(glGetUniformLocation(composite_program_, "u_mapped"), 0);
  glBindVertexArray(empty_vao_);
  glDrawArrays(GL_TRIANGLES, 0, 3);
  glBlendFuncSeparate(GL_SRC_ALPHA, GL_ONE_MINUS_SRC_ALPHA, GL_ONE, GL_ONE_MINUS_SRC_ALPHA);
  if (!overlay.empty()) {
    glUseProgram(lines_program_);
    set_view_uniforms(lines_program_, view);
    glBindVertexArray(lines_vao_);
    glBindBuffer(GL_ARRAY_BUFFER, lines_vbo_);
    // In pieces of whole triangles, drawn in order (so blended alike): one buffer of a large
    // scene's overlay would pass 4 GB, where drivers' offsets overflow (Mesa's llvmpipe crashes),
    // and the driver would copy it whole.
    for (std::size_t first = 0; first < overlay.size(); first += kOverlayPiece) {
      const std::size_t count = std::min(kOverlayPiece, overlay.size() - first);
      glBufferData(GL_ARRAY_BUFFER, static_cast<GLsizeiptr>(count * sizeof(LineVertex)), overlay.data() + first,
                   GL_STREAM_DRAW);
      glDrawArrays(GL_TRIANGLES, 0, static_cast<GLsizei>(count));
    }
  }
  glBindVertexArray(0);
  glUseProgram(0);
  glDisable(GL_SCISSOR_TEST);
  glDisable(GL_BLEND);
  return ok_status();
}

Status Renderer::make_colour_framebuffer(int width, int height, unsigned& framebuffer, unsigned& colour) {
  if (framebuffer == 0) {
    glGenFramebuffers(1, &framebuffer);
    glGenRenderbuffers(1, &colour);
  }
  glBindRenderbuffer(GL_RENDERBUFFER, colour);
  glRenderbufferStorage(GL_RENDERBUFFER, GL_RGBA8, width, height);
  glBindFramebuffer(GL_FRAMEBUFFER, framebuffer);
  glFramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, colour);
  if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
    return Error{"cannot make a " + std::to_string(width) + "x" + std::to_string(height) +
                 " picture (too large for the OpenGL implementation?)"};
  return ok_status();
}

std::vector<std::uint8_t> Renderer::read_pixels(int width, int height) {
  std::vector<std::uint8_t> pixels(static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * 4);
  glPixelStorei(GL_PACK_ALIGNMENT, 1);
  glReadPixels(0, 0, width, height, GL_RGBA, GL_UNSIGNED_BYTE, pixels.data());
  // GL rows run bottom to top.
  const std::size_t row = static_cast<std::size_t>(width) * 4;
  for (int y = 0; y < height / 2; ++y)
    std::swap_ranges(pixels.begin() + static_cast<std::ptrdiff_t>(y * row),
                     pixels.begin() + static_cast<std::ptrdiff_t>((y + 1) * row),
                     pixels.begin() + static_cast<std::ptrdiff_t>((height - 1 - y) * row));
  return pixels;
}

}  // namespace flatland::viewer
