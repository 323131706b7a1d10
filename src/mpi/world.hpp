// The MPI processes of one run (`mpirun -np K flatland ...`): a thin layer over the core's
// RoundSharing, so the core and the command line know nothing of MPI. docs/mpi.md says how the
// work is shared.
#pragma once

#include <cstdint>
#include <span>

#include "flatland/solver.hpp"

namespace flatland::mpi {

// Whether a process launcher started this process (OpenMPI's mpirun, MPICH's Hydra and Slurm's
// srun set per-process variables for it). A program started alone never initialises MPI.
bool started_by_launcher();

// MPI initialised for the life of the object (only the thread that made it calls MPI), finalised
// when it goes away. One per process.
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

 private:
  unsigned rank_ = 0;
  unsigned size_ = 1;
};

}  // namespace flatland::mpi
