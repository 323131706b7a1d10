// The machine's memory and this process's limits, for refusing work that cannot fit before any of
// it is allocated.
#pragma once

#include <cstddef>
#include <string>

namespace flatland {

// The memory a piece of work may plan on: three quarters of the physical memory (the rest is left
// to the system and other programs), and at most half of the address space this process may still
// map under its limits (ulimit -v and -d); 4 GiB when the system does not say.
std::size_t default_memory_budget();

// The address space this process may still map: its limit (RLIMIT_AS, ulimit -v) less what it has
// mapped now; SIZE_MAX when there is no limit.
std::size_t address_space_left();

// The address space a new thread's stack takes: RLIMIT_STACK (ulimit -s), which glibc takes as the
// default, or 8 MiB when that is unlimited.
std::size_t thread_stack_bytes();

// "1.5 GB", "820 MB": a byte count for messages.
std::string format_bytes(double bytes);

}  // namespace flatland
