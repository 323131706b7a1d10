// The flatland command line: the parser with every subcommand, parse-error reports, and the
// option checks of each command that need no file (src/app/cli.hpp).
#include "app/cli.hpp"

#include <algorithm>
#include <cstdio>
#include <string>
#include <utility>
#include <vector>

#include "flatland/base/text.hpp"
#include "flatland/base/version.hpp"
#include "flatland/reference/reference.hpp"
#ifdef FLATLAND_HAVE_VIEWER
#include "viewer/viewer_app.hpp"
#endif

namespace flatland::app {

namespace {

// The long option names a command accepts, for did-you-mean hints.
std::vector<std::string> option_names(const CLI::App& command) {
  std::vector<std::string> names;
  for (const CLI::Option* option : command.get_options())
    for (const std::string& name : option->get_lnames()) names.push_back("--" + name);
  return names;
}

// CLI11's messages name the problem; add a likely intended word and which help to read.
int report_parse_error(const CLI::App& app, const CLI::ParseError& error, int argc, const char* const* argv) {
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
    if (const auto hint = closest_match(argv[1], commands))
      message += "; did you mean '" + *hint + "'?";
    else {
      message += "; commands:";
      for (const std::string& name : commands) message += " " + name;
    }
  } else {
    const std::vector<std::string> known = option_names(*command);
    for (int i = 1; i < argc; ++i) {
      const std::string word = std::string(argv[i]).substr(0, std::string(argv[i]).find('='));
      if (word.rfind("--", 0) != 0 || std::find(known.begin(), known.end(), word) != known.end()) continue;
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

CommandLine::CommandLine()
    : app{"flatland: light transport in 2D scenes of lines and cubic Bezier curves (diffuse surfaces,\n"
          "mirrors, glass and detectors), after 'Cubic Monte Carlo Radiosity' (Elias, Feda, Ferschin,\n"
          "Purgathofer).\n"
          "Scenes are JSON files (docs/scene-format.md); examples are in scenes2d/.",
          "flatland"} {
  app.set_version_flag("--version",
                       std::string("flatland ") + program_version() + " (commit " + program_commit() + ")");
  app.require_subcommand(1);
  app.fallthrough(false);
  app.footer(
      "Under mpirun (docs/mpi.md), solve shares every round among the processes with the bits of one\n"
      "process, and converge deals its runs out; give each process its cores with --threads.");
  add_solve_command(app, solve);
  add_reference_command(app, reference);
  add_converge_command(app, converge);
  add_compare_command(app, compare);
#ifdef FLATLAND_HAVE_VIEWER
  add_view_command(app, view);
#endif
#ifdef FLATLAND_HAVE_RENDER
  add_render_command(app, render);
#endif
}

std::optional<int> parse_command_line(int argc, const char* const* argv, CommandLine& command_line) {
  CLI::App& app = command_line.app;
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
  const std::pair<const char*, Command> commands[] = {{"solve", Command::Solve},     {"reference", Command::Reference},
                                                      {"compare", Command::Compare}, {"converge", Command::Converge},
                                                      {"view", Command::View},       {"render", Command::Render}};
  command_line.command = Command::None;
  for (const CLI::App* sub : app.get_subcommands())
    for (const auto& [name, command] : commands)
      if (sub->get_name() == name) command_line.command = command;
  // require_subcommand(1) makes a missing command a parse error; exit as for one all the same.
  if (command_line.command == Command::None) return kExitUsage;
  return std::nullopt;
}

Status validate_command_line(CommandLine& command_line) {
  switch (command_line.command) {
    case Command::Solve: return finish_solver_settings(command_line.solve);
    case Command::Reference: {
      // The element length that --elements gives depends on the scene; the rest does not.
      ReferenceSettings settings = command_line.reference.settings;
      settings.max_element_length = command_line.reference.max_element_length;
      return validate(settings);
    }
    case Command::Compare: return ok_status();
    case Command::Converge: return check_converge_options(command_line.converge);
    case Command::View: {
      if (Status status = finish_solver_settings(command_line.view.solve); !status) return status;
#ifdef FLATLAND_HAVE_VIEWER
      if (Result<viewer::FrameStep> step = viewer::parse_frame_step(command_line.view.step); !step) return step.error();
#endif
      return ok_status();
    }
    case Command::Render: return finish_solver_settings(command_line.render.solve);
    case Command::None: break;
  }
  return Error{"no command given"};
}

}  // namespace flatland::app
