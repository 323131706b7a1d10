// flatland: diffuse light transport in 2D after "Cubic Monte Carlo Radiosity".
#include <csignal>
#include <optional>

#include "app/cli.hpp"
#include "app/commands.hpp"

namespace flatland::app {

std::atomic<bool>& interrupt_flag() {
  static std::atomic<bool> flag{false};
  return flag;
}

namespace {

extern "C" void handle_interrupt(int) { interrupt_flag().store(true); }

}  // namespace

}  // namespace flatland::app

int main(int argc, char** argv) {
  using namespace flatland::app;
  CommandLine command_line;
  if (const std::optional<int> exit_code = parse_command_line(argc, argv, command_line)) return *exit_code;

  std::signal(SIGINT, handle_interrupt);
  std::signal(SIGTERM, handle_interrupt);
  switch (command_line.command) {
    case Command::Solve: return run_solve(command_line.solve);
    case Command::Reference: return run_reference(command_line.reference);
    case Command::Compare: return run_compare(command_line.compare);
    case Command::Converge: return run_converge(command_line.converge);
#ifdef FLATLAND_HAVE_VIEWER
    case Command::View: return run_view(command_line.view);
    case Command::Render: return run_render(command_line.render);
#endif
    default: break;
  }
  return kExitUsage;
}
