// Output files of the commands: checked before any work starts, written all or nothing, and not
// at all when an interrupt (Ctrl-C, SIGTERM) arrived before they were in place.
#pragma once

#include <cstdio>
#include <optional>
#include <string>
#include <vector>

#include "flatland/base/files.hpp"

namespace flatland::app {

// A file a command reads or writes, and the option (or argument) that names it, for messages.
struct NamedPath {
  std::string option;
  std::string path;
};

// Checks the outputs (those with a non-empty path) before any work: each can be written
// (examine_output), and none is one of `inputs` or another output, by the file it names whatever
// its spelling. Prints the first problem as a one-line error and returns its exit code (2), or
// nullopt when all can be written. When an output goes to the standard output, the command's
// reports go to standard error from then on (report_stream).
std::optional<int> check_outputs(const std::vector<NamedPath>& outputs, const std::vector<NamedPath>& inputs = {});

// Where a command prints its reports (summaries, tables, "wrote ..."): the standard output, or
// standard error once check_outputs has seen an output that goes to the standard output.
std::FILE* report_stream();

// Renames or writes the staged files unless the run was interrupted: then they are discarded,
// "interrupted; nothing written" is printed and the exit code is 130. A failed write prints its
// error and gives 2 (130 when an interrupt ended a wait for a pipe). nullopt when everything was
// written.
std::optional<int> commit_outputs(OutputFiles& files);

// Prints "flatland: interrupted; nothing written" and returns 130.
int interrupted();

// Prints "flatland: note: MESSAGE" on standard error (rank 0 only): something the user should
// know that changes nothing in the results.
void note(const std::string& message);

// Prints "flatland: error: MESSAGE" and returns 2 (bad input).
int usage_error(const std::string& message);

// For a failed read of an input: 130 and the interrupt's message when an interrupt ended a wait
// for a pipe (kFileWaitCancelled), otherwise usage_error(prefix + message).
int input_error(const Error& error, const std::string& prefix = "");

}  // namespace flatland::app
