// A one-line progress display on stderr, shown only when stderr is a terminal.
#pragma once

#include <string>

#include "flatland/transport/solver.hpp"

namespace flatland::app {

class ProgressLine {
 public:
  explicit ProgressLine(bool enabled);
  ~ProgressLine();
  void update(const SolverProgress& progress);
  // Any text in place of the line.
  void show(const std::string& text);
  void finish();  // clears the line

 private:
  bool enabled_ = false;
  bool shown_ = false;
};

// 1234567 -> "1.23M" (k, M, G, T, P); for summaries and progress.
std::string human_count(double value);
// 95 -> "95 s", 4000 -> "67 min", 1e6 -> "12 days", 1.4e8 -> "4.6 years".
std::string human_duration(double seconds);

}  // namespace flatland::app
