// Output files of the commands: checked before any work starts, written all or nothing, and not
// at all when an interrupt (Ctrl-C, SIGTERM) arrived before they were in place.
#pragma once

#include <optional>
#include <string>
#include <vector>

#include "flatland/result_io.hpp"

namespace flatland::app {

// Checks every non-empty path with check_output_file; prints the first problem as a one-line
// error and returns its exit code (2), or nullopt when all can be written.
std::optional<int> check_outputs(const std::vector<std::string>& paths);

// Renames the staged files into place unless the run was interrupted: then they are discarded,
// "interrupted; nothing written" is printed and the exit code is 130. A failed rename prints its
// error and gives 2. nullopt when everything was written.
std::optional<int> commit_outputs(OutputFiles& files);

// Prints "flatland: interrupted; nothing written" and returns 130.
int interrupted();

// Prints "flatland: error: MESSAGE" and returns 2 (bad input).
int usage_error(const std::string& message);

}  // namespace flatland::app
