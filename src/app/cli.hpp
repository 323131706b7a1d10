// The flatland command line without its work: the parser with every subcommand and its options,
// the one-line reports of parse errors, and the checks each command makes of its options before it
// touches a file. main() parses and dispatches with it; the command-line fuzz target
// (fuzz/fuzz_command_line.cpp) parses and validates with it and never dispatches, so it exercises
// exactly what a user's arguments reach.
#pragma once

#include <optional>

#include <CLI/CLI.hpp>

#include "app/commands.hpp"

namespace flatland::app {

enum class Command { None, Solve, Reference, Compare, Converge, View, Render };

// Every command's options and the parser that fills them. The parser keeps pointers into the
// options, so a CommandLine is neither copied nor moved. The view and render options exist in every
// build (so the layout does not depend on FLATLAND_HAVE_VIEWER); their subcommands only in builds
// with the viewer.
struct CommandLine {
  CommandLine();
  CommandLine(const CommandLine&) = delete;
  CommandLine& operator=(const CommandLine&) = delete;

  SolveOptions solve;
  ReferenceOptions reference;
  ConvergeOptions converge;
  CompareOptions compare;
  ViewCommandOptions view;
  RenderOptions render;
  Command command = Command::None;  // the subcommand given, once parse_command_line succeeded
  CLI::App app;
};

// Parses argv into `command_line`. Returns the exit code when parsing already decided the outcome:
// --help and --version (printed to stdout, 0), or a parse error (one line on stderr naming the
// problem, a likely intended word and which help to read; kExitUsage). Returns nothing when a
// subcommand is to run: command_line.command says which.
std::optional<int> parse_command_line(int argc, const char* const* argv, CommandLine& command_line);

// The checks the chosen command makes of its options before any work, without reading or writing a
// file or starting a process: solve, view and render turn their text options into solver settings
// (finish_solver_settings); view also reads --step; converge parses --methods and --budgets or
// --times; reference checks the settings that do not depend on the scene. compare has nothing to
// check before it reads its files. The error is the message the command would print.
Status validate_command_line(CommandLine& command_line);

}  // namespace flatland::app
