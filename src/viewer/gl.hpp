// OpenGL for the viewer: 3.3 core through libepoxy on the desktop, OpenGL ES 3.0 (WebGL2) in the
// web build. The viewer uses only what both have.
#pragma once

#ifdef __EMSCRIPTEN__
#include <GLES3/gl3.h>
#include <emscripten/html5.h>
#else
#include <epoxy/gl.h>
#endif

namespace flatland::viewer {

// The first lines of every shader: the shaders/ sources carry no #version, so one source serves
// GLSL 3.30 core and GLSL ES 3.00 (whose fragment shaders have no default float precision).
#ifdef __EMSCRIPTEN__
inline constexpr const char* kGlslHeader = "#version 300 es\nprecision highp float;\nprecision highp int;\n";
#else
inline constexpr const char* kGlslHeader = "#version 330 core\n";
#endif

// The path buffer's format: 32-bit float where the context can blend into it and filter it (always
// on the desktop; WebGL2 with EXT_float_blend and OES_texture_float_linear), else 16-bit float
// (which WebGL2 filters, and blends with EXT_color_buffer_float).
inline GLenum path_buffer_format() {
#ifdef __EMSCRIPTEN__
  const EMSCRIPTEN_WEBGL_CONTEXT_HANDLE context = emscripten_webgl_get_current_context();
  const bool full = emscripten_webgl_enable_extension(context, "EXT_float_blend") &&
                    emscripten_webgl_enable_extension(context, "OES_texture_float_linear");
  return full ? GL_RGBA32F : GL_RGBA16F;
#else
  return GL_RGBA32F;
#endif
}

}  // namespace flatland::viewer
