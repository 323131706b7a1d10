#include "app/output.hpp"

#include <cstdio>

#include "app/commands.hpp"
#include "app/processes.hpp"
#include "flatland/transport/options.hpp"

namespace flatland::app {

std::atomic<bool>& interrupt_flag() {
  static std::atomic<bool> flag{false};
  return flag;
}

namespace {

// Rank 0 prints; the other ranks of an MPI run keep the message for agree().
void say(const std::string& line) {
  if (speaks_for_the_run())
    std::fputs(line.c_str(), stderr);
  else
    deferred_messages() += line;
}

bool& reports_to_standard_error() {
  static bool moved = false;
  return moved;
}

}  // namespace

std::FILE* report_stream() { return reports_to_standard_error() ? stderr : stdout; }

void note(const std::string& message) {
  if (speaks_for_the_run()) std::fprintf(stderr, "flatland: note: %s\n", message.c_str());
}

int usage_error(const std::string& message) {
  // A message of the core that begins with an option's name ("ray width: ...") names it as this
  // command line spells it ("--ray-width: ...").
  say("flatland: error: " + spelled(message, Spelling::CommandLine) + "\n");
  return kExitUsage;
}

int interrupted() {
  say("flatland: interrupted; nothing written\n");
  return kExitInterrupted;
}

int input_error(const Error& error, const std::string& prefix) {
  if (error.message == kFileWaitCancelled || interrupt_flag().load()) return interrupted();
  return usage_error(prefix + error.message);
}

std::optional<int> check_outputs(const std::vector<NamedPath>& outputs, const std::vector<NamedPath>& inputs) {
  std::vector<std::pair<const NamedPath*, FileIdentity>> seen;
  for (const NamedPath& input : inputs) {
    if (input.path.empty()) continue;
    if (const std::optional<FileIdentity> identity = existing_file_identity(input.path))
      seen.emplace_back(&input, *identity);
  }
  const std::size_t input_count = seen.size();
  bool standard_output = false;
  for (const NamedPath& output : outputs) {
    if (output.path.empty()) continue;
    Result<OutputTarget> target = examine_output(output.path);
    if (!target) return usage_error(target.error().message);
    for (std::size_t i = 0; i < seen.size(); ++i) {
      // The null device takes any number of outputs (--out /dev/null --picture /dev/null).
      if (seen[i].second != target->identity || (i >= input_count && target->discards)) continue;
      const NamedPath& other = *seen[i].first;
      const std::string what = other.option.rfind("--", 0) == 0 ? other.option : "the " + other.option;
      if (i < input_count)
        return usage_error(output.option + " " + output.path + ": is " + what + " (" + other.path +
                           "), which this command reads; give the output another path");
      return usage_error(output.option + " " + output.path + ": is also " + what + " (" + other.path +
                         "); give each output its own path");
    }
    seen.emplace_back(&output, target->identity);
    standard_output = standard_output || target->shares_standard_output;
  }
  if (standard_output) {
    std::fflush(stdout);
    reports_to_standard_error() = true;
  }
  return std::nullopt;
}

std::optional<int> commit_outputs(OutputFiles& files) {
  if (interrupt_flag().load()) {
    files.discard();
    return interrupted();
  }
  if (Status status = files.commit(); !status) {
    if (status.error().message == kFileWaitCancelled) {
      say("flatland: interrupted while waiting to write an output; it may be incomplete\n");
      return kExitInterrupted;
    }
    return usage_error(status.error().message);
  }
  return std::nullopt;
}

}  // namespace flatland::app
