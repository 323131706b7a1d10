#include "flatland/resources.hpp"

#include <cstdio>

#include <unistd.h>

namespace flatland {

std::size_t default_memory_budget() {
  const long pages = ::sysconf(_SC_PHYS_PAGES);
  const long page_size = ::sysconf(_SC_PAGESIZE);
  if (pages <= 0 || page_size <= 0) return std::size_t{4} << 30;
  return static_cast<std::size_t>(pages) / 4 * 3 * static_cast<std::size_t>(page_size);
}

std::string format_bytes(double bytes) {
  char text[32];
  if (bytes >= 1e9) std::snprintf(text, sizeof text, "%.3g GB", bytes / 1e9);
  else if (bytes >= 1e6) std::snprintf(text, sizeof text, "%.3g MB", bytes / 1e6);
  else std::snprintf(text, sizeof text, "%.3g kB", bytes / 1e3);
  return text;
}

}  // namespace flatland
