// The processes of one run: this one alone, or the ranks of `mpirun -np K flatland ...` (src/mpi
// makes them; this file knows only the core's RoundSharing). Rank 0 speaks for the run: it prints,
// checks and writes the outputs; the other ranks work silently and keep their error messages until
// the run agrees whether to go on (so a bad input is reported once, not K times).
#pragma once

#include <optional>
#include <string>

#include "flatland/transport/solver.hpp"

namespace flatland::app {

// The run's processes, or null when this process runs alone (the default).
RoundSharing* shared_processes();
void set_shared_processes(RoundSharing* processes);
inline unsigned process_rank() { return shared_processes() != nullptr ? shared_processes()->rank() : 0; }
inline unsigned process_count() { return shared_processes() != nullptr ? shared_processes()->size() : 1; }
inline bool speaks_for_the_run() { return process_rank() == 0; }

// Messages usage_error and interrupted would print on a rank other than 0: kept until agree().
std::string& deferred_messages();

// Collective: every process says whether it can go on (nullopt) or stops with an exit code. Alone,
// returns `code`. Shared: the code of the lowest-numbered process that stops, on every process, or
// nullopt when all go on. A rank other than 0 prints its kept message when rank 0 went on (the
// problem was its own); rank 0 names such a rank.
std::optional<int> agree(std::optional<int> code);

// Collective: rank 0's `text` on every process (alone: unchanged).
void share_text(std::string& text);

// Collective, before parsing: whether every process was given the same command line (but for
// --threads, which each may set for its machine). A process whose arguments differ from rank 0's
// stops with a message naming the first that differs; then all stop with exit code 2. Alone,
// nullopt.
std::optional<int> agree_on_command_line(int argc, const char* const* argv);

// Collective: whether every process read the same bytes as `what` (`path`, SHA-256 `digest`), as
// when two machines hold different versions of a scene file. As agree(): nullopt when they all
// did; otherwise all stop with exit code 2, and a process whose bytes differ from rank 0's says so.
// `digest` is empty on a process that has nothing to compare (it stops anyway).
std::optional<int> agree_on_digest(const std::string& what, const std::string& path, const std::string& digest);

}  // namespace flatland::app
