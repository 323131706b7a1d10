// The machine's memory, for refusing work that cannot fit before any of it is allocated.
#pragma once

#include <cstddef>
#include <string>

namespace flatland {

// Three quarters of the physical memory (the rest is left to the system and other programs);
// 4 GiB when the system does not say.
std::size_t default_memory_budget();

// "1.5 GB", "820 MB": a byte count for messages.
std::string format_bytes(double bytes);

}  // namespace flatland
