#include "mpi/world.hpp"

#include <mpi.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <system_error>

namespace flatland::mpi {

namespace {

// The tag of a cancel message on the relay's communicator.
constexpr int kCancelTag = 1;

MPI_Comm& communicator(void* slot) { return *static_cast<MPI_Comm*>(slot); }

}  // namespace

bool started_by_launcher() {
  // (Per-process variables only: Slurm's SLURM_NTASKS is also set in a job script's own shell.)
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMI_RANK", "PMIX_RANK"})
    if (std::getenv(name) != nullptr) return true;
  return false;
}

World::World(int* argc, char*** argv) {
  int provided = 0;
  MPI_Init_thread(argc, argv, MPI_THREAD_MULTIPLE, &provided);
  threads_supported_ = provided >= MPI_THREAD_MULTIPLE;
  int rank = 0;
  int size = 1;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  rank_ = static_cast<unsigned>(rank);
  size_ = static_cast<unsigned>(size);
}

World::~World() {
  if (relay_.joinable()) {
    stopping_.store(true);
    relay_.join();
  }
  if (relay_communicator_ != nullptr) {
    // Messages still on their way (two processes cancelled at once) are received, not left behind.
    MPI_Comm& comm = communicator(relay_communicator_);
    for (int arrived = 1; arrived != 0;) {
      MPI_Status status;
      MPI_Iprobe(MPI_ANY_SOURCE, kCancelTag, comm, &arrived, &status);
      if (arrived != 0) {
        int ignored = 0;
        MPI_Recv(&ignored, 1, MPI_INT, status.MPI_SOURCE, kCancelTag, comm, MPI_STATUS_IGNORE);
      }
    }
    MPI_Comm_free(&comm);
    delete &comm;
  }
  MPI_Finalize();
}

void World::sum(std::span<std::int64_t> values) {
  constexpr std::size_t kPiece = std::size_t{1} << 28;
  for (std::size_t at = 0; at < values.size(); at += kPiece) {
    const std::size_t count = std::min(kPiece, values.size() - at);
    MPI_Allreduce(MPI_IN_PLACE, values.data() + at, static_cast<int>(count), MPI_INT64_T, MPI_SUM, MPI_COMM_WORLD);
  }
  bytes_summed_ += values.size() * sizeof(std::int64_t);
}

void World::relay_cancel(std::atomic<bool>* flag) {
  if (!threads_supported_ || size_ < 2 || relay_.joinable()) return;
  // Collective: every process makes the relay's communicator, so its messages never meet the sums.
  auto* comm = new MPI_Comm;
  MPI_Comm_dup(MPI_COMM_WORLD, comm);
  relay_communicator_ = comm;
  try {
    relay_ = std::thread([this, flag] { relay(flag); });
  } catch (const std::system_error&) {
    // No thread to spare: a cancel still reaches the others at the round's sum.
  }
}

void World::relay(std::atomic<bool>* flag) {
  MPI_Comm& comm = communicator(relay_communicator_);
  bool told = false;  // whether this process has told the others (or heard from one)
  while (!stopping_.load()) {
    if (!told && flag->load()) {
      const int one = 1;
      // One int is sent eagerly: MPI_Send returns without waiting for the receiver.
      for (unsigned other = 0; other < size_; ++other)
        if (other != rank_) MPI_Send(&one, 1, MPI_INT, static_cast<int>(other), kCancelTag, comm);
      told = true;
    }
    int arrived = 0;
    MPI_Status status;
    MPI_Iprobe(MPI_ANY_SOURCE, kCancelTag, comm, &arrived, &status);
    if (arrived != 0) {
      int ignored = 0;
      MPI_Recv(&ignored, 1, MPI_INT, status.MPI_SOURCE, kCancelTag, comm, MPI_STATUS_IGNORE);
      flag->store(true);
      told = true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

}  // namespace flatland::mpi
