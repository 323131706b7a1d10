// The MPI processes of one run (`mpirun -np K flatland ...`): a thin layer over the core's
// RoundSharing, so the core and the command line know nothing of MPI. docs/mpi.md says how the
// work is shared.
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>
#include <span>
#include <thread>

#include "flatland/transport/solver.hpp"

namespace flatland::mpi {

// Whether a process launcher started this process (OpenMPI's mpirun, MPICH's Hydra and Slurm's
// srun set per-process variables for it). A program started alone never initialises MPI.
bool started_by_launcher();

// MPI initialised for the life of the object, finalised when it goes away. One per process. The
// thread that made it makes the collective calls; relay_cancel's thread sends and receives its
// cancel messages on a communicator of its own.
class World final : public RoundSharing {
 public:
  World(int* argc, char*** argv);
  ~World() override;
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  unsigned rank() const override { return rank_; }
  unsigned size() const override { return size_; }
  // MPI_Allreduce (sum) in place, in pieces of at most 2^28 integers.
  void sum(std::span<std::int64_t> values) override;

  // Collective. Makes `flag` (the process's interrupt flag) collective: a thread looks every 20 ms
  // whether it was set here, and then tells every other process, and whether another process told
  // this one, and then sets it. A Ctrl-C on any process so stops all of them within a fraction of a
  // second, wherever each is in its work. Needs MPI_THREAD_MULTIPLE; without it (an MPI built
  // without thread support) a cancel reaches the others at the end of the round, as the round's
  // sum. The relay stops when the World goes away, collectively: every cancel message sent is
  // received first, as MPI requires before a communicator is freed.
  void relay_cancel(std::atomic<bool>* flag);

  // Ends the whole job at once with `code` (MPI_Abort): for a process that cannot go on (out of
  // memory) while the others may be waiting for it in a sum.
  [[noreturn]] void abort(int code);

 private:
  struct Relay;
  void relay(std::atomic<bool>* flag);
  void stop_relay();

  unsigned rank_ = 0;
  unsigned size_ = 1;
  bool threads_supported_ = false;
  std::unique_ptr<Relay> relay_state_;  // its communicator and message counts (mpi.h stays in the .cpp)
  std::atomic<bool> stopping_{false};
  std::thread relay_;
};

}  // namespace flatland::mpi
