#include "app/output.hpp"

#include <cstdio>

#include "app/commands.hpp"

namespace flatland::app {

int usage_error(const std::string& message) {
  std::fprintf(stderr, "flatland: error: %s\n", message.c_str());
  return kExitUsage;
}

int interrupted() {
  std::fprintf(stderr, "flatland: interrupted; nothing written\n");
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
