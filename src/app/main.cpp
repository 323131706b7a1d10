// flatland: diffuse light transport in 2D after "Cubic Monte Carlo Radiosity".
#include <csignal>
#include <cstdio>
#include <algorithm>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "app/commands.hpp"
#include "flatland/text.hpp"

namespace flatland::app {

std::atomic<bool>& interrupt_flag() {
  static std::atomic<bool> flag{false};
  return flag;
}

namespace {

extern "C" void handle_interrupt(int) { interrupt_flag().store(true); }

// The long option names a command accepts, for did-you-mean hints.
std::vector<std::string> option_names(const CLI::App& command) {
  std::vector<std::string> names;
  for (const CLI::Option* option : command.get_options())
    for (const std::string& name : option->get_lnames()) names.push_back("--" + name);
  return names;
}

// CLI11's messages name the problem; add a likely intended word and which help to read.
int report_parse_error(const CLI::App& app, const CLI::ParseError& error, int argc, char** argv) {
  const CLI::App* command = &app;
  std::string where = "flatland";
  for (const CLI::App* sub : app.get_subcommands()) {
    command = sub;
    where += " " + sub->get_name();
  }
  std::string message = error.what();
  while (!message.empty() && (message.back() == '\n' || message.back() == ' ')) message.pop_back();
  std::vector<std::string> commands;
  for (const CLI::App* sub : app.get_subcommands({})) commands.push_back(sub->get_name());
  if (command == &app && argc > 1 && argv[1][0] != '-') {
    // An unknown word where a command belongs: CLI11 only says that a command is required.
    message = "unknown command '" + std::string(argv[1]) + "'";
    if (const auto hint = closest_match(argv[1], commands)) message += "; did you mean '" + *hint + "'?";
    else {
      message += "; commands:";
      for (const std::string& name : commands) message += " " + name;
    }
  } else {
    const std::vector<std::string> known = option_names(*command);
    for (int i = 1; i < argc; ++i) {
      const std::string word = std::string(argv[i]).substr(0, std::string(argv[i]).find('='));
      if (word.rfind("--", 0) != 0 || std::find(known.begin(), known.end(), word) != known.end())
        continue;
      if (const auto hint = closest_match(word, known)) {
        message += "; did you mean '" + *hint + "'?";
        break;
      }
    }
  }
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
  ReferenceOptions reference;
  CLI::App* reference_command = add_reference_command(app, reference);
  ConvergeOptions converge;
  CLI::App* converge_command = add_converge_command(app, converge);
  CompareOptions compare;
  CLI::App* compare_command = add_compare_command(app, compare);
#ifdef FLATLAND_HAVE_VIEWER
  ViewCommandOptions view;
  CLI::App* view_command = add_view_command(app, view);
  RenderOptions render;
  CLI::App* render_command = add_render_command(app, render);
#endif

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    return report_parse_error(app, e, argc, argv);
  }

  std::signal(SIGINT, handle_interrupt);
  std::signal(SIGTERM, handle_interrupt);
  if (solve_command->parsed()) return run_solve(solve);
  if (reference_command->parsed()) return run_reference(reference);
  if (compare_command->parsed()) return run_compare(compare);
  if (converge_command->parsed()) return run_converge(converge);
#ifdef FLATLAND_HAVE_VIEWER
  if (view_command->parsed()) return run_view(view);
  if (render_command->parsed()) return run_render(render);
#endif
  return kExitUsage;
}
