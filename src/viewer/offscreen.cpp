#include "viewer/offscreen.hpp"

#include "viewer/renderer.hpp"

#include <epoxy/egl.h>
#include <epoxy/gl.h>

#include <cstdio>
#include <string>

namespace flatland::viewer {

namespace {

std::string egl_error() {
  char text[32];
  std::snprintf(text, sizeof text, "EGL error 0x%04x", static_cast<unsigned>(eglGetError()));
  return text;
}

}  // namespace

Result<std::unique_ptr<OffscreenContext>> OffscreenContext::create(int width, int height) {
  std::unique_ptr<OffscreenContext> result(new OffscreenContext());
  EGLDisplay display = EGL_NO_DISPLAY;
  if (epoxy_has_egl_extension(EGL_NO_DISPLAY, "EGL_MESA_platform_surfaceless"))
    display = eglGetPlatformDisplayEXT(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
  if (display == EGL_NO_DISPLAY)
    return Error{
        "no offscreen OpenGL: EGL has no surfaceless platform (install Mesa's libegl-mesa0 "
        "and libgl1-mesa-dri)"};
  EGLint major = 0;
  EGLint minor = 0;
  if (eglInitialize(display, &major, &minor) != EGL_TRUE)
    return Error{"no offscreen OpenGL: eglInitialize failed (" + egl_error() + ")"};
  result->display_ = display;
  if (!epoxy_has_egl_extension(display, "EGL_KHR_surfaceless_context") || eglBindAPI(EGL_OPENGL_API) != EGL_TRUE)
    return Error{"no offscreen OpenGL: EGL cannot make a desktop OpenGL context without a surface"};
  const EGLint attributes[] = {
      EGL_CONTEXT_MAJOR_VERSION,           3,       EGL_CONTEXT_MINOR_VERSION, 3, EGL_CONTEXT_OPENGL_PROFILE_MASK,
      EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
  EGLConfig config = nullptr;  // EGL_NO_CONFIG_KHR: a surfaceless context needs none
  EGLint configs = 0;
  const EGLint wanted[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
  if (eglChooseConfig(display, wanted, &config, 1, &configs) != EGL_TRUE || configs == 0) config = nullptr;
  EGLContext context = eglCreateContext(display, config, EGL_NO_CONTEXT, attributes);
  if (context == EGL_NO_CONTEXT)
    return Error{"no offscreen OpenGL: cannot create an OpenGL 3.3 core context (" + egl_error() + ")"};
  result->context_ = context;
  if (eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, context) != EGL_TRUE)
    return Error{"no offscreen OpenGL: eglMakeCurrent failed (" + egl_error() + ")"};

  if (Status made = Renderer::make_colour_framebuffer(width, height, result->framebuffer_, result->colour_); !made)
    return made.error();
  return result;
}

OffscreenContext::~OffscreenContext() {
  auto display = static_cast<EGLDisplay>(display_);
  if (context_ != nullptr) {
    if (framebuffer_ != 0) glDeleteFramebuffers(1, &framebuffer_);
    if (colour_ != 0) glDeleteRenderbuffers(1, &colour_);
    eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    eglDestroyContext(display, static_cast<EGLContext>(context_));
  }
  if (display_ != nullptr) eglTerminate(display);
}

}  // namespace flatland::viewer
