#include "app/processes.hpp"

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
    const std::string prefix = "flatland (process " + std::to_string(processes->rank()) + " of " +
                               std::to_string(processes->size()) + "): ";
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
    std::fprintf(stderr, "flatland: error: process %u of %u stopped (its message is above); nothing done\n",
                 first_rank, processes->size());
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

}  // namespace flatland::app
