// A fixed set of worker threads that live as long as their owner, so that work handed out many
// times (every round of a solve, every 50 ms piece of the viewer's) does not start and join
// threads each time. The pool decides nothing about results: callers split work into pieces whose
// outcome does not depend on which thread runs them (flatland's integer accumulators), so a solve
// is bit-identical on any thread count.
#pragma once

#include <algorithm>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace flatland {

class WorkerPool {
 public:
  // A pool of `threads` workers: the caller of run() is worker 0, threads - 1 helpers wait. When
  // the system refuses a thread (a process limit, an address-space limit), the pool keeps the
  // helpers it could start: threads() is then less than asked, and shortfall() says why.
  explicit WorkerPool(unsigned threads);
  ~WorkerPool();
  WorkerPool(const WorkerPool&) = delete;
  WorkerPool& operator=(const WorkerPool&) = delete;

  unsigned threads() const { return static_cast<unsigned>(helpers_.size()) + 1; }
  // How many threads were asked for, and why fewer run (empty when all run).
  unsigned requested() const { return requested_; }
  const std::string& shortfall() const { return shortfall_; }

  // Runs task(w) for every w in [0, workers) (at most threads()), worker 0 on the calling thread,
  // and returns when all have finished. An exception thrown by a task is rethrown here (the
  // first one, after every worker has stopped). Not re-entrant: one run at a time.
  void run(unsigned workers, const std::function<void(unsigned)>& task);

  // Calls f(i) for every i in [0, count), indices handed out one at a time to the workers.
  void for_each(std::size_t count, const std::function<void(std::size_t)>& f);

 private:
  void helper(unsigned index);

  std::vector<std::thread> helpers_;
  unsigned requested_ = 1;
  std::string shortfall_;
  std::mutex mutex_;
  std::condition_variable start_;
  std::condition_variable done_;
  std::uint64_t generation_ = 0;  // bumped by every run
  unsigned workers_ = 0;          // of the current run
  unsigned running_ = 0;          // helpers of the current run still working
  bool stopping_ = false;
  const std::function<void(unsigned)>* task_ = nullptr;
  std::exception_ptr failure_;
};

// A WorkerPool started on first use, for a member of a copyable class: a copy starts empty (its
// owner's copy starts its own threads when it first needs them), a move takes the threads along.
class LazyWorkerPool {
 public:
  LazyWorkerPool() = default;
  LazyWorkerPool(const LazyWorkerPool&) {}
  LazyWorkerPool& operator=(const LazyWorkerPool&) {
    pool_.reset();
    return *this;
  }
  LazyWorkerPool(LazyWorkerPool&&) noexcept = default;
  LazyWorkerPool& operator=(LazyWorkerPool&&) noexcept = default;

  // The pool, with `threads` workers asked for (restarted if it was asked for another number).
  WorkerPool& get(unsigned threads) {
    if (!pool_ || pool_->requested() != std::max(threads, 1u)) pool_ = std::make_unique<WorkerPool>(threads);
    return *pool_;
  }
  // The pool if it has started, else null.
  const WorkerPool* started() const { return pool_.get(); }

 private:
  std::unique_ptr<WorkerPool> pool_;
};

}  // namespace flatland
