#include "mpi/world.hpp"

#include <mpi.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <system_error>
#include <vector>

namespace flatland::mpi {

namespace {

// The tag of a cancel message on the relay's communicator.
constexpr int kCancelTag = 1;

}  // namespace

// The relay's own communicator (so its messages never meet the sums), the cancel messages this
// process sent to and received from each other process, and the sends' requests. The counts are
// the relay thread's while it runs, the World's after it has stopped.
struct World::Relay {
  MPI_Comm comm = MPI_COMM_NULL;
  std::vector<int> sent;
  std::vector<int> received;
  std::vector<MPI_Request> requests;
  int message = 1;  // what every cancel message carries (a send's buffer must outlive it)
};

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
  stop_relay();
  MPI_Finalize();
}

void World::abort(int code) {
  MPI_Abort(MPI_COMM_WORLD, code);
  std::abort();
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
  if (!threads_supported_ || size_ < 2 || relay_state_) return;
  relay_state_ = std::make_unique<Relay>();
  MPI_Comm_dup(MPI_COMM_WORLD, &relay_state_->comm);
  relay_state_->sent.assign(size_, 0);
  relay_state_->received.assign(size_, 0);
  try {
    relay_ = std::thread([this, flag] { relay(flag); });
  } catch (const std::system_error&) {
    // No thread to spare: a cancel still reaches the others at the round's sum.
  }
}

void World::relay(std::atomic<bool>* flag) {
  Relay& state = *relay_state_;
  bool told = false;  // whether this process has told the others (or heard from one)
  while (!stopping_.load()) {
    if (!told && flag->load()) {
      // Not waited for here: a peer receives it at its next look, or when the relays stop.
      for (unsigned other = 0; other < size_; ++other) {
        if (other == rank_) continue;
        MPI_Request request;
        MPI_Isend(&state.message, 1, MPI_INT, static_cast<int>(other), kCancelTag, state.comm, &request);
        state.requests.push_back(request);
        ++state.sent[other];
      }
      told = true;
    }
    int arrived = 0;
    MPI_Status status;
    MPI_Iprobe(MPI_ANY_SOURCE, kCancelTag, state.comm, &arrived, &status);
    if (arrived != 0) {
      int ignored = 0;
      MPI_Recv(&ignored, 1, MPI_INT, status.MPI_SOURCE, kCancelTag, state.comm, MPI_STATUS_IGNORE);
      ++state.received[static_cast<std::size_t>(status.MPI_SOURCE)];
      flag->store(true);
      told = true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
}

void World::stop_relay() {
  if (!relay_state_) return;
  stopping_.store(true);
  if (relay_.joinable()) relay_.join();
  // Collective: how many messages each process sent each other one, so that every message still
  // on its way is received before the communicator goes (two processes may both have cancelled).
  Relay& state = *relay_state_;
  std::vector<int> coming(size_, 0);
  MPI_Alltoall(state.sent.data(), 1, MPI_INT, coming.data(), 1, MPI_INT, state.comm);
  for (unsigned other = 0; other < size_; ++other)
    for (int k = state.received[other]; k < coming[other]; ++k) {
      int ignored = 0;
      MPI_Recv(&ignored, 1, MPI_INT, static_cast<int>(other), kCancelTag, state.comm, MPI_STATUS_IGNORE);
    }
  if (!state.requests.empty())
    MPI_Waitall(static_cast<int>(state.requests.size()), state.requests.data(), MPI_STATUSES_IGNORE);
  MPI_Comm_free(&state.comm);
  relay_state_.reset();
}

}  // namespace flatland::mpi
