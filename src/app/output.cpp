#include "app/output.hpp"

#include <cstdio>

#include "app/commands.hpp"
#include "app/processes.hpp"

namespace flatland::app {

namespace {

// Rank 0 prints; the other ranks of an MPI run keep the message for agree().
void say(const std::string& line) {
  if (speaks_for_the_run())
    std::fputs(line.c_str(), stderr);
  else
    deferred_messages() += line;
}

}  // namespace

int usage_error(const std::string& message) {
  say("flatland: error: " + message + "\n");
  return kExitUsage;
}

int interrupted() {
  say("flatland: interrupted; nothing written\n");
  return kExitInterrupted;
}

std::optional<int> check_outputs(const std::vector<std::string>& paths) {
  for (const std::string& path : paths) {
    if (path.empty()) continue;
    if (Status status = check_output_file(path); !status) return usage_error(status.error().message);
  }
  return std::nullopt;
}

std::optional<int> commit_outputs(OutputFiles& files) {
  if (interrupt_flag().load()) {
    files.discard();
    return interrupted();
  }
  if (Status status = files.commit(); !status) return usage_error(status.error().message);
  return std::nullopt;
}

}  // namespace flatland::app
