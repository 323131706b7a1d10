#include "mpi/world.hpp"

#include <mpi.h>

#include <algorithm>
#include <cstdlib>

namespace flatland::mpi {

bool started_by_launcher() {
  // (Per-process variables only: Slurm's SLURM_NTASKS is also set in a job script's own shell.)
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMI_RANK", "PMIX_RANK"})
    if (std::getenv(name) != nullptr) return true;
  return false;
}

World::World(int* argc, char*** argv) {
  int provided = 0;
  MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
  int rank = 0;
  int size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  rank_ = static_cast<unsigned>(rank);
  size_ = static_cast<unsigned>(size);
}

World::~World() { MPI_Finalize(); }

void World::sum(std::span<std::int64_t> values) {
  constexpr std::size_t kPiece = std::size_t{1} << 28;
  for (std::size_t at = 0; at < values.size(); at += kPiece) {
    const std::size_t count = std::min(kPiece, values.size() - at);
    MPI_Allreduce(MPI_IN_PLACE, values.data() + at, static_cast<int>(count), MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  }
  bytes_summed_ += values.size() * sizeof(std::int64_t);
}

}  // namespace flatland::mpi
