// The command line in-process: the parser main() uses (parse_command_line) and the checks each
// command makes before any work (validate_command_line), without starting the binary. What the
// binary does with files, signals and processes is tested in cli_test.cpp.
#include "app/cli.hpp"

#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "flatland/transport/options.hpp"
#include "flatland/transport/settings.hpp"

namespace flatland::app {
namespace {

// Parses `arguments` (after the program's name) into `command_line`: the exit code when parsing
// decided the outcome, else nothing. CLI11 prints help and parse errors; they go to the test's log.
std::optional<int> parse(CommandLine& command_line, std::vector<std::string> arguments) {
  arguments.insert(arguments.begin(), "flatland");
  std::vector<const char*> argv;
  for (const std::string& argument : arguments) argv.push_back(argument.c_str());
  return parse_command_line(static_cast<int>(argv.size()), argv.data(), command_line);
}

// A value of `spec` that is not its default: its last choice, or a number that the option
// accepts (elements takes "auto" or a count).
std::string other_value(const SolveOptionSpec& spec, const SolverSettings& defaults) {
  const std::string current = solve_option_text(defaults, spec.option);
  for (auto it = spec.choices.rbegin(); it != spec.choices.rend(); ++it)
    if (std::string(*it) != current) return std::string(*it);
  switch (spec.option) {
    case SolveOption::Photons: return "12345";
    case SolveOption::Seed: return "77";
    case SolveOption::Threads: return "3";
    case SolveOption::Elements: return "24";
    case SolveOption::RayWidth: return "0.125";
    case SolveOption::BandRays: return "5";
    case SolveOption::Tolerance: return "0.0625";
    case SolveOption::Replicates: return "4";
    case SolveOption::Confidence: return "0.9";
    case SolveOption::TargetError: return "0.01";
    case SolveOption::Importance: return "desk,floor";
    default: break;
  }
  ADD_FAILURE() << "no other value for --" << spec.flag;
  return current;
}

TEST(CommandLine, EverySolveOptionOfTheRegistryIsAFlagOfEverySolvingCommand) {
  CommandLine command_line;
  std::vector<std::string> commands = {"solve"};
#ifdef FLATLAND_HAVE_VIEWER
  commands.insert(commands.end(), {"view", "render"});
#endif
  for (const std::string& name : commands) {
    const CLI::App* command = command_line.app.get_subcommand(name);
    ASSERT_NE(command, nullptr) << name;
    for (const SolveOptionSpec& spec : solve_options()) {
      const CLI::Option* option = command->get_option_no_throw("--" + std::string(spec.flag));
      ASSERT_NE(option, nullptr) << name << " --" << spec.flag;
      EXPECT_EQ(option->get_description(), std::string(spec.help)) << name << " --" << spec.flag;
    }
  }
}

TEST(CommandLine, DefaultsAreTheSolversOwn) {
  CommandLine command_line;
  ASSERT_EQ(parse(command_line, {"solve", "scene.json"}), std::nullopt);
  ASSERT_EQ(command_line.command, Command::Solve);
  ASSERT_TRUE(validate_command_line(command_line));
  const SolverSettings defaults;
  for (const SolveOptionSpec& spec : solve_options())
    EXPECT_EQ(solve_option_text(command_line.solve.settings, spec.option), solve_option_text(defaults, spec.option))
        << "--" << spec.flag;
}

// Each option, set alone to a value other than its default, reaches the settings and nothing else
// changes. A walk's score is set with the transport it needs (alone it is refused: validate).
TEST(CommandLine, EachOptionReachesItsSettingAlone) {
  const SolverSettings defaults;
  for (const SolveOptionSpec& spec : solve_options()) {
    CommandLine command_line;
    const std::string value = other_value(spec, defaults);
    std::vector<std::string> arguments = {"solve", "scene.json", "--" + std::string(spec.flag), value};
    const bool needs_walks = spec.option == SolveOption::WalkScore;
    if (needs_walks) arguments.insert(arguments.end(), {"--transport", "walk"});
    ASSERT_EQ(parse(command_line, arguments), std::nullopt) << spec.flag;
    const Status status = validate_command_line(command_line);
    ASSERT_TRUE(status) << "--" << spec.flag << " " << value << ": " << status.error().message;
    for (const SolveOptionSpec& other : solve_options()) {
      const std::string got = solve_option_text(command_line.solve.settings, other.option);
      const std::string expected = other.option == spec.option ? value
                                   : needs_walks && other.option == SolveOption::Transport
                                       ? "walk"
                                       : solve_option_text(defaults, other.option);
      EXPECT_EQ(got, expected) << "--" << spec.flag << " " << value << ", read back as --" << other.flag;
    }
  }
}

// The core names an option in plain words; the command line's message names the flag typed.
TEST(CommandLine, MessagesNameTheFlag) {
  struct Case {
    std::vector<std::string> arguments;
    std::string starts;
  };
  const std::vector<Case> cases = {
      {{"solve", "s.json", "--ray-width", "-1"}, "--ray-width: "},
      {{"solve", "s.json", "--basis", "cubik"}, "--basis: "},
      {{"solve", "s.json", "--band-rays", "0", "--ray-width", "0.1", "--ray-mode", "band"}, "--band-rays: "},
      {{"solve", "s.json", "--photons", "1.5"}, "--photons: "},
      {{"solve", "s.json", "--seed", "-3"}, "--seed: "},
  };
  for (const Case& c : cases) {
    CommandLine command_line;
    ASSERT_EQ(parse(command_line, c.arguments), std::nullopt) << c.arguments[2];
    const Status status = validate_command_line(command_line);
    ASSERT_FALSE(status) << c.arguments[2];
    EXPECT_EQ(status.error().message.rfind(c.starts, 0), 0u) << status.error().message;
    EXPECT_EQ(status.error().message.find('\n'), std::string::npos) << status.error().message;
  }
}

TEST(CommandLine, HelpVersionAndParseErrorsDecideTheExitCode) {
  {
    CommandLine command_line;
    EXPECT_EQ(parse(command_line, {"--version"}), kExitOk);
  }
  {
    CommandLine command_line;
    EXPECT_EQ(parse(command_line, {"solve", "--help"}), kExitOk);
  }
  {
    CommandLine command_line;
    EXPECT_EQ(parse(command_line, {"solve", "s.json", "--no-such-option"}), kExitUsage);
  }
  {
    CommandLine command_line;
    EXPECT_EQ(parse(command_line, {}), kExitUsage);
  }
  {
    CommandLine command_line;
    EXPECT_EQ(parse(command_line, {"solv", "s.json"}), kExitUsage);
  }
}

TEST(CommandLine, ConvergeChecksItsPlanBeforeAnyWork) {
  {
    CommandLine command_line;
    ASSERT_EQ(parse(command_line,
                    {"converge", "s.json", "--methods", "cubic,linear", "--budgets", "1000,4000", "--out", "dir"}),
              std::nullopt);
    EXPECT_TRUE(validate_command_line(command_line));
  }
  {
    CommandLine command_line;
    ASSERT_EQ(parse(command_line, {"converge", "s.json", "--methods", "cubic,cubic", "--out", "dir"}), std::nullopt);
    EXPECT_FALSE(validate_command_line(command_line));
  }
  {
    CommandLine command_line;
    ASSERT_EQ(parse(command_line, {"converge", "s.json", "--methods", "cubic+ray-widht=0.1", "--out", "dir"}),
              std::nullopt);
    const Status status = validate_command_line(command_line);
    ASSERT_FALSE(status);
    EXPECT_NE(status.error().message.find("ray-width"), std::string::npos) << status.error().message;
  }
}

}  // namespace
}  // namespace flatland::app
