#include "app/progress.hpp"

#include <cstdio>
#include <string>

#include <unistd.h>

namespace flatland::app {

std::string human_count(double value) {
  char text[32];
  if (value >= 1e15)
    std::snprintf(text, sizeof text, "%.3gP", value / 1e15);
  else if (value >= 1e12)
    std::snprintf(text, sizeof text, "%.3gT", value / 1e12);
  else if (value >= 1e9)
    std::snprintf(text, sizeof text, "%.3gG", value / 1e9);
  else if (value >= 1e6)
    std::snprintf(text, sizeof text, "%.3gM", value / 1e6);
  else if (value >= 1e4)
    std::snprintf(text, sizeof text, "%.3gk", value / 1e3);
  else
    std::snprintf(text, sizeof text, "%.0f", value);
  return text;
}

std::string human_duration(double seconds) {
  char text[48];
  if (!(seconds < 1e12)) return "ages";
  if (seconds < 120.0)
    std::snprintf(text, sizeof text, "%.0f s", seconds);
  else if (seconds < 7200.0)
    std::snprintf(text, sizeof text, "%.0f min", seconds / 60.0);
  else if (seconds < 2.0 * 86400.0)
    std::snprintf(text, sizeof text, "%.1f h", seconds / 3600.0);
  else if (seconds < 2.0 * 365.25 * 86400.0)
    std::snprintf(text, sizeof text, "%.0f days", seconds / 86400.0);
  else
    std::snprintf(text, sizeof text, "%.3g years", seconds / (365.25 * 86400.0));
  return text;
}

ProgressLine::ProgressLine(bool enabled) : enabled_(enabled && ::isatty(STDERR_FILENO) == 1) {}

ProgressLine::~ProgressLine() { finish(); }

void ProgressLine::update(const SolverProgress& p) {
  if (!enabled_) return;
  const double done = p.budget > 0 ? static_cast<double>(p.photons) / static_cast<double>(p.budget) : 0.0;
  const double rate = p.seconds > 0.0 ? static_cast<double>(p.photons) / p.seconds : 0.0;
  const std::string eta = rate > 0.0 ? human_duration(static_cast<double>(p.budget - p.photons) / rate) : "?";
  char text[256];
  std::snprintf(text, sizeof text, "photons %s / %s (%.0f%%)  rounds %u  unshot %.3g%%  %.1f s  at most %s left",
                human_count(static_cast<double>(p.photons)).c_str(), human_count(static_cast<double>(p.budget)).c_str(),
                100.0 * done, p.rounds, 100.0 * p.unshot_fraction, p.seconds, eta.c_str());
  show(text);
}

void ProgressLine::show(const std::string& text) {
  if (!enabled_) return;
  std::fprintf(stderr, "\r\033[K  %s", text.c_str());
  std::fflush(stderr);
  shown_ = true;
}

void ProgressLine::finish() {
  if (shown_) {
    std::fprintf(stderr, "\r\033[K");
    std::fflush(stderr);
    shown_ = false;
  }
}

}  // namespace flatland::app
