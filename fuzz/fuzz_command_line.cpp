// libFuzzer target: the command line, parsed and validated, never run.
//
// The bytes are an argument list: arguments separated by NUL or newline bytes, at most
// kMaxArguments of at most kMaxArgumentLength bytes each (the rest is dropped), after "flatland".
// They go through the parser main() uses (parse_command_line: every subcommand, every option and
// its checks, the did-you-mean hints of a parse error) and the checks each command makes before
// any work (validate_command_line). Nothing is dispatched: no solve, no file read or written, no
// process started.
//
// CLI11 prints --help and --version to stdout, which is sent to /dev/null at start-up; parse
// errors are one line each on stderr (run with -close_fd_mask=2 to hide them: libFuzzer keeps its
// own output and the sanitizers' reports). A crash, a sanitizer report, an exception escaping, an
// assertion or a hang is a bug. docs/fuzzing.md says how to run it.
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "app/cli.hpp"
#include "app/commands.hpp"

namespace {

constexpr std::size_t kMaxArguments = 32;
constexpr std::size_t kMaxArgumentLength = 256;

std::vector<std::string> split_arguments(const std::uint8_t* data, std::size_t size) {
  std::vector<std::string> arguments;
  std::string current;
  for (std::size_t i = 0; i < size && arguments.size() < kMaxArguments; ++i) {
    const char byte = static_cast<char>(data[i]);
    if (byte == '\0' || byte == '\n') {
      arguments.push_back(current);
      current.clear();
    } else if (current.size() < kMaxArgumentLength) {
      current += byte;
    }
  }
  // A last argument without a separator after it; "a\n" is one argument, not "a" and "".
  if (!current.empty() && arguments.size() < kMaxArguments) arguments.push_back(current);
  return arguments;
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  // Thousands of help pages would bury the fuzzer's log.
  if (std::freopen("/dev/null", "w", stdout) == nullptr) std::perror("fuzz_command_line: /dev/null");
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::vector<std::string> arguments = split_arguments(data, size);
  arguments.insert(arguments.begin(), "flatland");
  std::vector<const char*> argv;
  for (const std::string& argument : arguments) argv.push_back(argument.c_str());
  argv.push_back(nullptr);  // as the kernel passes it: argv[argc] is a null pointer

  flatland::app::CommandLine command_line;
  if (flatland::app::parse_command_line(static_cast<int>(arguments.size()), argv.data(), command_line)) return 0;
  (void)flatland::app::validate_command_line(command_line);
  return 0;
}
