// An OpenGL 3.3 core context without any window or display (EGL, Mesa's surfaceless platform, which
// falls back to the llvmpipe software rasteriser), with a colour framebuffer to draw into and read
// back: `flatland render` and the README's first command on a machine without a display.
#pragma once

#include <memory>

#include "flatland/base/status.hpp"

namespace flatland::viewer {

class OffscreenContext {
 public:
  // Makes the context current on the calling thread and binds a width x height RGBA8 framebuffer.
  static Result<std::unique_ptr<OffscreenContext>> create(int width, int height);
  ~OffscreenContext();
  OffscreenContext(const OffscreenContext&) = delete;
  OffscreenContext& operator=(const OffscreenContext&) = delete;

 private:
  OffscreenContext() = default;
  void* display_ = nullptr;
  void* context_ = nullptr;
  unsigned framebuffer_ = 0;
  unsigned colour_ = 0;
};

}  // namespace flatland::viewer
