// flatland: diffuse light transport in 2D after "Cubic Monte Carlo Radiosity".
#include <csignal>
#include <cstdio>
#include <string>

#include <CLI/CLI.hpp>

#include "app/commands.hpp"

namespace flatland::app {

std::atomic<bool>& interrupt_flag() {
  static std::atomic<bool> flag{false};
  return flag;
}

namespace {

extern "C" void handle_interrupt(int) { interrupt_flag().store(true); }

// CLI11's messages end without a hint; add which help to read.
int report_parse_error(const CLI::App& app, const CLI::ParseError& error) {
  std::string where = "flatland";
  for (const CLI::App* sub : app.get_subcommands()) where += " " + sub->get_name();
  std::string message = error.what();
  while (!message.empty() && (message.back() == '\n' || message.back() == ' ')) message.pop_back();
  std::fprintf(stderr, "flatland: error: %s (see '%s --help')\n", message.c_str(), where.c_str());
  return kExitUsage;
}

}  // namespace

}  // namespace flatland::app

int main(int argc, char** argv) {
  using namespace flatland::app;
  CLI::App app{
      "flatland: diffuse light transport in 2D scenes of lines and cubic Bezier curves, after\n"
      "'Cubic Monte Carlo Radiosity' (Elias, Feda, Ferschin, Purgathofer).\n"
      "Scenes are JSON files (docs/scene-format.md); examples are in scenes2d/.",
      "flatland"};
  app.set_version_flag("--version", "flatland 0.1.0");
  app.require_subcommand(1);
  app.fallthrough(false);

  SolveOptions solve;
  CLI::App* solve_command = add_solve_command(app, solve);

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    return report_parse_error(app, e);
  }

  std::signal(SIGINT, handle_interrupt);
  std::signal(SIGTERM, handle_interrupt);
  if (solve_command->parsed()) return run_solve(solve);
  return kExitUsage;
}
