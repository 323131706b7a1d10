// The MPI processes of one run (`mpirun -np K flatland ...`): a thin layer over the core's
// RoundSharing, so the core and the command line know nothing of MPI. docs/mpi.md says how the
// work is shared.
#pragma once

#include <atomic>
#include <cstdint>
#include <span>
#include <thread>

#include "flatland/solver.hpp"

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

  // Makes `flag` (the process's interrupt flag) collective: a thread looks every 20 ms whether it
  // was set here, and then tells every other process, and whether another process told this one,
  // and then sets it. A Ctrl-C on any process so stops all of them within a fraction of a second,
  // wherever each is in its work. Needs MPI_THREAD_MULTIPLE; without it (an MPI built without
  // thread support) a cancel reaches the others at the end of the round, as the round's sum.
  void relay_cancel(std::atomic<bool>* flag);
  bool relays_cancel() const { return relay_.joinable(); }

 private:
  void relay(std::atomic<bool>* flag);

  unsigned rank_ = 0;
  unsigned size_ = 1;
  bool threads_supported_ = false;
  void* relay_communicator_ = nullptr;  // an MPI_Comm, kept opaque so this header needs no mpi.h
  std::atomic<bool> stopping_{false};
  std::thread relay_;
};

}  // namespace flatland::mpi
