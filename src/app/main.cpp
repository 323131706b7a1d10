// flatland: light transport in 2D (diffuse surfaces, mirrors, glass) after "Cubic Monte Carlo Radiosity".
#include <csignal>
#include <cstdio>
#include <exception>
#include <new>
#include <optional>
#include <string>

#include <fcntl.h>
#include <unistd.h>

#include "app/cli.hpp"
#include "app/commands.hpp"
#include "app/output.hpp"
#include "app/processes.hpp"
#ifdef FLATLAND_HAVE_MPI
#include "mpi/world.hpp"
#endif

namespace flatland::app {

namespace {

extern "C" void handle_interrupt(int) { interrupt_flag().store(true); }

}  // namespace

}  // namespace flatland::app

namespace {

using namespace flatland::app;

// Points `fd` at /dev/null; returns a duplicate of what it was (or -1).
int silence(int fd) {
  std::fflush(nullptr);
  const int saved = ::dup(fd);
  const int null = ::open("/dev/null", O_WRONLY);
  if (null >= 0) {
    ::dup2(null, fd);
    ::close(null);
  }
  return saved;
}

void restore(int fd, int saved) {
  if (saved < 0) return;
  std::fflush(nullptr);
  ::dup2(saved, fd);
  ::close(saved);
}

int run_command(CommandLine& command_line) {
  switch (command_line.command) {
    case Command::Solve: return run_solve(command_line.solve);
    case Command::Reference: return run_reference(command_line.reference);
    case Command::Compare: return run_compare(command_line.compare);
    case Command::Converge: return run_converge(command_line.converge);
#ifdef FLATLAND_HAVE_VIEWER
    case Command::View: return run_view(command_line.view);
#endif
#ifdef FLATLAND_HAVE_RENDER
    case Command::Render: return run_render(command_line.render);
#endif
    default: break;
  }
  return kExitUsage;
}

// Commands that share their work among the processes of mpirun (docs/mpi.md).
bool shares_work(Command command) { return command == Command::Solve || command == Command::Converge; }

}  // namespace

int main(int argc, char** argv) {
#ifdef FLATLAND_HAVE_MPI
  // Started by mpirun: join the run (MPI is never initialised for a program started alone).
  std::optional<flatland::mpi::World> world;
  if (flatland::mpi::started_by_launcher()) {
    world.emplace(&argc, &argv);
    if (world->size() > 1) set_shared_processes(&*world);
  }
#endif
  // Every process must run the same command (on the same files, checked once they are read).
  if (const std::optional<int> exit_code = agree_on_command_line(argc, argv)) return *exit_code;
  // Only rank 0 prints; the others' output is dropped (their errors are kept, processes.hpp).
  int saved_error = -1;
  if (!speaks_for_the_run()) {
    ::close(silence(STDOUT_FILENO));
    saved_error = silence(STDERR_FILENO);
  }
  CommandLine command_line;
  std::optional<int> parsed = parse_command_line(argc, argv, command_line);
  if (!speaks_for_the_run()) restore(STDERR_FILENO, saved_error);
  if (!parsed && process_count() > 1 && !shares_work(command_line.command))
    parsed = usage_error(
        "this command runs in one process; under mpirun only solve and converge share their work "
        "(run it without mpirun, or with -np 1)");
  if (const std::optional<int> exit_code = agree(parsed)) return *exit_code;

  std::signal(SIGINT, handle_interrupt);
  std::signal(SIGTERM, handle_interrupt);
  // A reader that closes a pipe early (`flatland solve s.json --out - | head`) gives a write error
  // (EPIPE) with a one-line message, not death by SIGPIPE.
  std::signal(SIGPIPE, SIG_IGN);
#ifdef FLATLAND_HAVE_MPI
  // A Ctrl-C on any process reaches the others within a fraction of a second (docs/mpi.md).
  if (world && world->size() > 1) world->relay_cancel(&interrupt_flag());
#endif
  // A failure that one process meets alone (out of memory) cannot wait for the others to agree:
  // they may be waiting for it in a sum. It says so itself and, under MPI, ends the whole job.
  const auto stop_alone = [&](const std::string& message, int code) {
    std::string prefix = "flatland: ";
    if (process_count() > 1)
      prefix = "flatland (process " + std::to_string(process_rank()) + " of " + std::to_string(process_count()) + "): ";
    std::fprintf(stderr, "%s%s\n", prefix.c_str(), message.c_str());
#ifdef FLATLAND_HAVE_MPI
    if (world && world->size() > 1) world->abort(code);
#endif
    return code;
  };
  try {
    return run_command(command_line);
  } catch (const std::bad_alloc&) {
    return stop_alone(
        "error: out of memory: the work does not fit in the memory this process may use (see "
        "ulimit -v); ask for less (fewer elements, samples or threads)",
        kExitUsage);
  } catch (const std::exception& e) {
    return stop_alone(std::string("internal error: ") + e.what(), kExitFailure);
  }
}
