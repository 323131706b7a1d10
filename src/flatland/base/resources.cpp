#include "flatland/base/resources.hpp"

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>

namespace flatland {

std::size_t address_space_left() {
  rlimit limit{};
  if (::getrlimit(RLIMIT_AS, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return SIZE_MAX;
  // What is mapped now: the first number of /proc/self/statm, in pages.
  std::size_t mapped = 0;
  if (std::FILE* statm = std::fopen("/proc/self/statm", "r")) {
    unsigned long pages = 0;
    if (std::fscanf(statm, "%lu", &pages) == 1) mapped = pages * static_cast<std::size_t>(::sysconf(_SC_PAGESIZE));
    std::fclose(statm);
  }
  const auto cap = static_cast<std::size_t>(limit.rlim_cur);
  return cap > mapped ? cap - mapped : 0;
}

std::size_t thread_stack_bytes() {
  rlimit limit{};
  constexpr std::size_t kDefault = std::size_t{8} << 20;
  if (::getrlimit(RLIMIT_STACK, &limit) != 0 || limit.rlim_cur == RLIM_INFINITY) return kDefault;
  return std::max<std::size_t>(static_cast<std::size_t>(limit.rlim_cur), std::size_t{64} << 10);
}

std::size_t default_memory_budget() {
  const long pages = ::sysconf(_SC_PHYS_PAGES);
  const long page_size = ::sysconf(_SC_PAGESIZE);
  std::size_t budget = pages <= 0 || page_size <= 0
                           ? std::size_t{4} << 30
                           : static_cast<std::size_t>(pages) / 4 * 3 * static_cast<std::size_t>(page_size);
  const std::size_t left = address_space_left();
  if (left != SIZE_MAX) budget = std::min(budget, left / 2);
  rlimit data{};
  if (::getrlimit(RLIMIT_DATA, &data) == 0 && data.rlim_cur != RLIM_INFINITY)
    budget = std::min(budget, static_cast<std::size_t>(data.rlim_cur) / 2);
  return budget;
}

std::string format_bytes(double bytes) {
  char text[32];
  if (bytes >= 1e12)
    std::snprintf(text, sizeof text, "%.3g TB", bytes / 1e12);
  else if (bytes >= 1e9)
    std::snprintf(text, sizeof text, "%.3g GB", bytes / 1e9);
  else if (bytes >= 1e6)
    std::snprintf(text, sizeof text, "%.3g MB", bytes / 1e6);
  else
    std::snprintf(text, sizeof text, "%.3g kB", bytes / 1e3);
  return text;
}

}  // namespace flatland
