// The viewer's platform layer: a window with an OpenGL context, its input events, and Dear ImGui's
// platform and renderer backends on it. The desktop build implements it with SDL2 and OpenGL 3.3
// core (window_sdl.cpp), the web build with emscripten's GLFW 3 and WebGL2 (window_web.cpp); the
// rest of the viewer is the same source for both and knows neither.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "flatland/base/status.hpp"

namespace flatland::viewer {

// Keys as the viewer's shortcuts name them, on every platform: a printable key is its ASCII
// character (letters in lower case; the keypad's + and - are '+' and '-'); the others are these.
namespace keys {
constexpr int kBackspace = 8;
constexpr int kTab = 9;
constexpr int kEscape = 27;
constexpr int kF1 = 0x10001;
constexpr int kF5 = 0x10005;
}  // namespace keys

struct WindowEvent {
  enum class Type {
    Close,  // the user closed the window
    Key,    // a key pressed (or repeated): key, ctrl
    Wheel,  // the mouse wheel turned: wheel notches (positive: away from the user) at x, y
    Drop,   // a file dropped on the window: path (the web build has copied it into its file system)
  };
  Type type = Type::Close;
  int key = 0;
  bool ctrl = false;
  float wheel = 0.0f;
  float x = 0.0f;  // drawable pixels from the left
  float y = 0.0f;  // drawable pixels from the top
  std::string path;
};

class Window {
 public:
  // Opens a resizable window titled `title` with its GL context current on this thread. Errors: no
  // display (one line saying what to do instead), no context of the needed version.
  static Result<std::unique_ptr<Window>> open(const std::string& title, int width, int height, bool vsync);
  ~Window();
  Window(const Window&) = delete;
  Window& operator=(const Window&) = delete;

  // Dear ImGui's backends on this window (the context exists and is styled); stopped, with the
  // context, when the window closes.
  void start_imgui();
  // Events since the last call, each also passed to Dear ImGui.
  std::vector<WindowEvent> poll_events();
  // Dear ImGui's backends start a frame (before ImGui::NewFrame), and draw one (after ImGui::Render).
  void new_imgui_frame();
  void render_imgui();
  void swap();

  std::array<int, 2> drawable_size() const;
  void set_title(const std::string& title);
  void set_size(int width, int height);
  // A file the viewer has just written for the user: the desktop leaves it where it is; the web
  // build hands it to the browser as a download and removes its copy.
  void deliver(const std::string& path);
  // Whether the user can close this window (a web page is closed by the browser, not by Escape).
  static bool closable();

 private:
  Window() = default;
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace flatland::viewer
