// The desktop window: SDL2, an OpenGL 3.3 core context loaded through libepoxy, and Dear ImGui's
// SDL2 and OpenGL3 backends.
#include <SDL.h>
#include <imgui.h>
#include <imgui_impl_opengl3.h>
#include <imgui_impl_sdl.h>

#include <cstdlib>
#include <string>

#include "viewer/gl.hpp"
#include "viewer/window.hpp"

namespace flatland::viewer {

namespace {

// SDL's key code as the viewer's (window.hpp): SDL's printable codes are already ASCII.
int viewer_key(SDL_Keycode key) {
  switch (key) {
    case SDLK_KP_PLUS: return '+';
    case SDLK_KP_MINUS: return '-';
    case SDLK_F1: return keys::kF1;
    case SDLK_F5: return keys::kF5;
    default: return key < 128 ? static_cast<int>(key) : 0;
  }
}

bool set(const char* name) { return std::getenv(name) != nullptr && *std::getenv(name) != '\0'; }

}  // namespace

struct Window::State {
  SDL_Window* window = nullptr;
  SDL_GLContext context = nullptr;
  bool imgui = false;

  ~State() {
    if (imgui) {
      ImGui_ImplOpenGL3_Shutdown();
      ImGui_ImplSDL2_Shutdown();
      ImGui::DestroyContext();
    }
    if (context != nullptr) SDL_GL_DeleteContext(context);
    if (window != nullptr) SDL_DestroyWindow(window);
    SDL_Quit();
  }
};

// SDL falls back to an offscreen video driver when there is no display; the viewer needs a real one
// unless that driver was asked for explicitly.
Result<std::unique_ptr<Window>> Window::open(const std::string& title, int width, int height, bool vsync) {
  const char* requested = std::getenv("SDL_VIDEODRIVER");
  const std::string instead =
      "; use 'flatland render SCENE --out FILE.png' for a picture without one, or run under xvfb-run";
  if (!set("DISPLAY") && !set("WAYLAND_DISPLAY") && requested == nullptr)
    return Error{"cannot open a display (DISPLAY and WAYLAND_DISPLAY are not set)" + instead};
  // With only DISPLAY set, ask for X11 alone: otherwise SDL also tries Wayland, whose library
  // prints its own complaint about XDG_RUNTIME_DIR, and then falls back to its offscreen driver.
  const std::string display = set("DISPLAY") ? std::getenv("DISPLAY") : "";
  if (requested == nullptr && !set("WAYLAND_DISPLAY")) SDL_SetHint(SDL_HINT_VIDEODRIVER, "x11");
  const std::string cannot_open = display.empty() ? std::string("cannot open the Wayland display")
                                                  : "cannot open the display '" + display + "' (DISPLAY)";
  std::unique_ptr<Window> window(new Window());
  window->state_ = std::make_unique<State>();
  State& state = *window->state_;
  if (SDL_Init(SDL_INIT_VIDEO) != 0) return Error{cannot_open + ": " + SDL_GetError() + instead};
  const char* driver = SDL_GetCurrentVideoDriver();
  if (driver != nullptr && (std::string(driver) == "offscreen" || std::string(driver) == "dummy") &&
      (requested == nullptr || std::string(requested) != driver))
    return Error{cannot_open + instead};
  SDL_GL_SetAttribute(SDL_GL_CONTEXT_MAJOR_VERSION, 3);
  SDL_GL_SetAttribute(SDL_GL_CONTEXT_MINOR_VERSION, 3);
  SDL_GL_SetAttribute(SDL_GL_CONTEXT_PROFILE_MASK, SDL_GL_CONTEXT_PROFILE_CORE);
  SDL_GL_SetAttribute(SDL_GL_DOUBLEBUFFER, 1);
  state.window = SDL_CreateWindow(title.c_str(), SDL_WINDOWPOS_CENTERED, SDL_WINDOWPOS_CENTERED, width, height,
                                  SDL_WINDOW_OPENGL | SDL_WINDOW_RESIZABLE);
  if (state.window == nullptr) return Error{std::string("cannot open a window: ") + SDL_GetError()};
  state.context = SDL_GL_CreateContext(state.window);
  if (state.context == nullptr)
    return Error{std::string("cannot create an OpenGL 3.3 core context: ") + SDL_GetError()};
  SDL_GL_MakeCurrent(state.window, state.context);
  SDL_GL_SetSwapInterval(vsync ? 1 : 0);
  return window;
}

Window::~Window() = default;

bool Window::closable() { return true; }

void Window::start_imgui() {
  ImGui_ImplSDL2_InitForOpenGL(state_->window, state_->context);
  ImGui_ImplOpenGL3_Init("#version 330 core");
  state_->imgui = true;
}

std::vector<WindowEvent> Window::poll_events() {
  std::vector<WindowEvent> events;
  SDL_Event event;
  while (SDL_PollEvent(&event)) {
    ImGui_ImplSDL2_ProcessEvent(&event);
    WindowEvent out;
    switch (event.type) {
      case SDL_QUIT: events.push_back(out); break;
      case SDL_WINDOWEVENT:
        if (event.window.event == SDL_WINDOWEVENT_CLOSE) events.push_back(out);
        break;
      case SDL_KEYDOWN:
        out.type = WindowEvent::Type::Key;
        out.key = viewer_key(event.key.keysym.sym);
        out.ctrl = (event.key.keysym.mod & KMOD_CTRL) != 0;
        if (out.key != 0) events.push_back(out);
        break;
      case SDL_MOUSEWHEEL: {
        int x = 0;
        int y = 0;
        SDL_GetMouseState(&x, &y);
        out.type = WindowEvent::Type::Wheel;
        out.wheel = static_cast<float>(event.wheel.y);
        out.x = static_cast<float>(x);
        out.y = static_cast<float>(y);
        if (event.wheel.y != 0) events.push_back(out);
        break;
      }
      case SDL_DROPFILE:
        out.type = WindowEvent::Type::Drop;
        out.path = event.drop.file;
        SDL_free(event.drop.file);
        events.push_back(out);
        break;
      default: break;
    }
  }
  return events;
}

void Window::new_imgui_frame() {
  ImGui_ImplOpenGL3_NewFrame();
  ImGui_ImplSDL2_NewFrame();
}

void Window::render_imgui() { ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData()); }

void Window::swap() { SDL_GL_SwapWindow(state_->window); }

std::array<int, 2> Window::drawable_size() const {
  std::array<int, 2> size{0, 0};
  SDL_GL_GetDrawableSize(state_->window, &size[0], &size[1]);
  return size;
}

void Window::set_title(const std::string& title) { SDL_SetWindowTitle(state_->window, title.c_str()); }

void Window::set_size(int width, int height) { SDL_SetWindowSize(state_->window, width, height); }

void Window::deliver(const std::string&) {}

}  // namespace flatland::viewer
