// The web page's window: the page's canvas through emscripten's GLFW 3, a WebGL2 (OpenGL ES 3.0)
// context, and Dear ImGui's GLFW and OpenGL3 backends. Files the viewer writes for the user are
// handed to the browser as downloads.
#include <GLFW/glfw3.h>
#include <emscripten.h>
#include <imgui.h>
#include <imgui_impl_glfw.h>
#include <imgui_impl_opengl3.h>

#include <cstdio>
#include <string>

#include "viewer/gl.hpp"
#include "viewer/window.hpp"

namespace flatland::viewer {

namespace {

// The events GLFW's callbacks deliver between two polls (the page has one window).
std::vector<WindowEvent>* pending = nullptr;
GLFWwindow* the_window = nullptr;

// GLFW's key as the viewer's (window.hpp).
int viewer_key(int key) {
  if (key >= GLFW_KEY_A && key <= GLFW_KEY_Z) return 'a' + (key - GLFW_KEY_A);
  if (key >= GLFW_KEY_0 && key <= GLFW_KEY_9) return '0' + (key - GLFW_KEY_0);
  switch (key) {
    case GLFW_KEY_SPACE: return ' ';
    case GLFW_KEY_PERIOD: return '.';
    case GLFW_KEY_EQUAL: return '=';
    case GLFW_KEY_MINUS:
    case GLFW_KEY_KP_SUBTRACT: return '-';
    case GLFW_KEY_KP_ADD: return '+';
    case GLFW_KEY_BACKSPACE: return keys::kBackspace;
    case GLFW_KEY_TAB: return keys::kTab;
    case GLFW_KEY_ESCAPE: return keys::kEscape;
    case GLFW_KEY_F1: return keys::kF1;
    case GLFW_KEY_F5: return keys::kF5;
    default: return 0;
  }
}

void on_key(GLFWwindow*, int key, int, int action, int mods) {
  if (pending == nullptr || (action != GLFW_PRESS && action != GLFW_REPEAT)) return;
  WindowEvent event;
  event.type = WindowEvent::Type::Key;
  event.key = viewer_key(key);
  event.ctrl = (mods & GLFW_MOD_CONTROL) != 0;
  if (event.key != 0) pending->push_back(event);
}

void on_scroll(GLFWwindow* window, double, double y) {
  if (pending == nullptr || y == 0.0) return;
  double x_pos = 0.0;
  double y_pos = 0.0;
  glfwGetCursorPos(window, &x_pos, &y_pos);
  WindowEvent event;
  event.type = WindowEvent::Type::Wheel;
  // A browser's wheel reports pixels or lines; one event is one notch, in the wheel's direction.
  event.wheel = y > 0.0 ? 1.0f : -1.0f;
  event.x = static_cast<float>(x_pos);
  event.y = static_cast<float>(y_pos);
  pending->push_back(event);
}

void on_drop(GLFWwindow*, int count, const char** paths) {
  if (pending == nullptr) return;
  for (int i = 0; i < count; ++i) {
    WindowEvent event;
    event.type = WindowEvent::Type::Drop;
    event.path = paths[i];
    pending->push_back(event);
  }
}

// clang-format off
EM_JS(void, set_page_title, (const char* title), {
  document.title = UTF8ToString(title);
});

EM_JS(void, download_file, (const char* path), {
  const name = UTF8ToString(path);
  const data = FS.readFile(name);
  const type = name.endsWith('.png') ? 'image/png' : 'application/json';
  const link = document.createElement('a');
  link.href = URL.createObjectURL(new Blob([data], {type: type}));
  link.download = name.split('/').pop();
  document.body.appendChild(link);
  link.click();
  link.remove();
  setTimeout(() => URL.revokeObjectURL(link.href), 10000);
  FS.unlink(name);
});
// clang-format on

}  // namespace

struct Window::State {
  GLFWwindow* window = nullptr;
  bool imgui = false;
  std::vector<WindowEvent> events;

  ~State() {
    if (imgui) {
      ImGui_ImplOpenGL3_Shutdown();
      ImGui_ImplGlfw_Shutdown();
      ImGui::DestroyContext();
    }
    pending = nullptr;
    the_window = nullptr;
    if (window != nullptr) glfwDestroyWindow(window);
    glfwTerminate();
  }
};

Result<std::unique_ptr<Window>> Window::open(const std::string& title, int width, int height, bool) {
  if (the_window != nullptr) return Error{"the page has a viewer already"};
  if (glfwInit() != GLFW_TRUE) return Error{"cannot start GLFW in this browser"};
  std::unique_ptr<Window> window(new Window());
  window->state_ = std::make_unique<State>();
  State& state = *window->state_;
  glfwWindowHint(GLFW_CLIENT_API, GLFW_OPENGL_ES_API);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 3);
  glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 0);
  state.window = glfwCreateWindow(width, height, title.c_str(), nullptr, nullptr);
  if (state.window == nullptr)
    return Error{
        "this browser gives the page no WebGL2 context (enable hardware acceleration, or try another browser)"};
  glfwMakeContextCurrent(state.window);
  // The viewer's own callbacks first: Dear ImGui's backend chains to them.
  glfwSetKeyCallback(state.window, on_key);
  glfwSetScrollCallback(state.window, on_scroll);
  glfwSetDropCallback(state.window, on_drop);
  pending = &state.events;
  the_window = state.window;
  set_page_title(title.c_str());
  return window;
}

Window::~Window() = default;

bool Window::closable() { return false; }

void Window::start_imgui() {
  ImGui_ImplGlfw_InitForOpenGL(state_->window, true);
  ImGui_ImplOpenGL3_Init("#version 300 es");
  state_->imgui = true;
}

std::vector<WindowEvent> Window::poll_events() {
  glfwPollEvents();
  std::vector<WindowEvent> events;
  events.swap(state_->events);
  return events;
}

void Window::new_imgui_frame() {
  ImGui_ImplOpenGL3_NewFrame();
  ImGui_ImplGlfw_NewFrame();
}

void Window::render_imgui() { ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData()); }

void Window::swap() {}  // the browser shows the canvas when the frame's callback returns

std::array<int, 2> Window::drawable_size() const {
  std::array<int, 2> size{0, 0};
  glfwGetFramebufferSize(state_->window, &size[0], &size[1]);
  return size;
}

void Window::set_title(const std::string& title) { set_page_title(title.c_str()); }

void Window::set_size(int width, int height) { glfwSetWindowSize(state_->window, width, height); }

void Window::deliver(const std::string& path) { download_file(path.c_str()); }

}  // namespace flatland::viewer
