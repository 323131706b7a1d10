// Processes that share the rounds of one solve: the interface the core defines and src/mpi
// implements, so the core knows nothing of MPI.
#pragma once

#include <cstdint>
#include <span>

namespace flatland {

// Processes that share every round of one solve (the MPI ranks of src/mpi; the core knows nothing
// of MPI). Process `rank()` of `size()` shoots the round's batches b with b mod size() == rank(),
// the same batches with the same streams as one process would, into its own integer deposits;
// `sum` adds a vector of integers over all processes, in place, on every process. Integer addition
// does not depend on order, so every process ends each round with the deposits of one process and
// derives the next round identically: the result is bit-identical for any number of processes.
class RoundSharing {
 public:
  virtual ~RoundSharing() = default;
  virtual unsigned rank() const = 0;
  virtual unsigned size() const = 0;
  // Collective: every process calls it with a vector of the same length. The sums never exceed
  // 2^63 in magnitude (the fixed point's budget is one process's), so no addition overflows.
  virtual void sum(std::span<std::int64_t> values) = 0;
  // Bytes this process handed to `sum` so far (what a round moves, for the performance notes).
  std::uint64_t bytes_summed() const { return bytes_summed_; }

 protected:
  std::uint64_t bytes_summed_ = 0;
};

}  // namespace flatland
