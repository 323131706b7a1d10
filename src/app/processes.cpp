#include "app/processes.hpp"

#include "app/output.hpp"

#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

namespace flatland::app {

namespace {

RoundSharing*& processes_slot() {
  static RoundSharing* processes = nullptr;
  return processes;
}

}  // namespace

RoundSharing* shared_processes() { return processes_slot(); }
void set_shared_processes(RoundSharing* processes) { processes_slot() = processes; }

std::string& deferred_messages() {
  static std::string messages;
  return messages;
}

std::optional<int> agree(std::optional<int> code) {
  RoundSharing* processes = shared_processes();
  if (processes == nullptr) return code;
  std::vector<std::int64_t> codes(processes->size(), 0);
  codes[processes->rank()] = code.value_or(0) != 0 ? *code : (code ? -1 : 0);  // -1: stops with code 0
  processes->sum(codes);
  std::optional<int> first;
  unsigned first_rank = 0;
  for (unsigned r = 0; r < codes.size() && !first; ++r) {
    if (codes[r] != 0) {
      first = codes[r] == -1 ? 0 : static_cast<int>(codes[r]);
      first_rank = r;
    }
  }
  // Its own lines, "flatland: ..." each, as "flatland (process R of K): ...".
  if (processes->rank() != 0 && code && codes[0] == 0) {
    const std::string prefix =
        "flatland (process " + std::to_string(processes->rank()) + " of " + std::to_string(processes->size()) + "): ";
    std::string line;
    for (const char c : deferred_messages()) {
      line += c;
      if (c != '\n') continue;
      std::fputs((prefix + (line.rfind("flatland: ", 0) == 0 ? line.substr(10) : line)).c_str(), stderr);
      line.clear();
    }
  }
  deferred_messages().clear();
  if (first && processes->rank() == 0 && first_rank != 0)
    std::fprintf(stderr, "flatland: error: process %u of %u stopped (its message is above); nothing done\n", first_rank,
                 processes->size());
  return first;
}

void share_text(std::string& text) {
  RoundSharing* processes = shared_processes();
  if (processes == nullptr) return;
  const bool speaker = processes->rank() == 0;
  std::vector<std::int64_t> length{speaker ? static_cast<std::int64_t>(text.size()) : 0};
  processes->sum(length);
  // Eight bytes to an integer; only rank 0's are nonzero, so the sum is rank 0's text.
  std::vector<std::int64_t> words((static_cast<std::size_t>(length[0]) + 7) / 8, 0);
  if (speaker && !text.empty()) std::memcpy(words.data(), text.data(), text.size());
  processes->sum(words);
  if (!speaker) text.assign(reinterpret_cast<const char*>(words.data()), static_cast<std::size_t>(length[0]));
}

namespace {

// The arguments that say what the run does: all but the program's name and --threads (with its
// value), which a process may set for the cores of its own machine.
std::vector<std::string> meaningful_arguments(int argc, const char* const* argv) {
  std::vector<std::string> kept;
  for (int i = 1; i < argc; ++i) {
    const std::string argument = argv[i];
    if (argument == "--threads") {
      ++i;
      continue;
    }
    if (argument.rfind("--threads=", 0) == 0) continue;
    kept.push_back(argument);
  }
  return kept;
}

// Argument i in quotes, after its option when it is an option's value ('--seed 2').
std::string quoted_or_none(const std::vector<std::string>& arguments, std::size_t i) {
  if (i >= arguments.size()) return "nothing";
  const bool value = i > 0 && arguments[i - 1].rfind("--", 0) == 0 && arguments[i - 1].find('=') == std::string::npos &&
                     arguments[i].rfind("-", 0) != 0;
  return "'" + (value ? arguments[i - 1] + " " : std::string()) + arguments[i] + "'";
}

}  // namespace

std::optional<int> agree_on_command_line(int argc, const char* const* argv) {
  if (shared_processes() == nullptr) return std::nullopt;
  const std::vector<std::string> mine = meaningful_arguments(argc, argv);
  // The arguments joined by NUL, which no argument can hold.
  std::string joined;
  for (const std::string& argument : mine) joined += argument + '\0';
  std::string first = joined;
  share_text(first);
  std::optional<int> code;
  if (first != joined) {
    std::vector<std::string> theirs;
    for (std::size_t at = 0; at < first.size();) {
      const std::size_t end = first.find('\0', at);
      theirs.push_back(first.substr(at, end - at));
      at = end + 1;
    }
    std::size_t i = 0;
    while (i < mine.size() && i < theirs.size() && mine[i] == theirs[i]) ++i;
    code = usage_error("this process's command line differs from process 0's at argument " + std::to_string(i + 1) +
                       ": " + quoted_or_none(mine, i) + " here, " + quoted_or_none(theirs, i) +
                       " there; start every process with the same command (only --threads may differ)");
  }
  return agree(code);
}

std::optional<int> agree_on_digest(const std::string& what, const std::string& path, const std::string& digest) {
  if (shared_processes() == nullptr) return std::nullopt;
  std::string first = digest;
  share_text(first);
  std::optional<int> code;
  if (digest != first && !digest.empty() && !first.empty())
    code =
        usage_error(path + ": this process read another " + what + " than process 0 (SHA-256 " + digest.substr(0, 12) +
                    "... here, " + first.substr(0, 12) + "... there); give every process the same file");
  return agree(code);
}

}  // namespace flatland::app
