// A one-line progress display on stderr, shown only when stderr is a terminal.
#pragma once

#include "flatland/solver.hpp"

namespace flatland::app {

class ProgressLine {
 public:
  explicit ProgressLine(bool enabled);
  ~ProgressLine();
  void update(const SolverProgress& progress);
  void finish();  // clears the line

 private:
  bool enabled_ = false;
  bool shown_ = false;
};

// 1234567 -> "1.23M"; for summaries and progress.
std::string human_count(double value);

}  // namespace flatland::app
