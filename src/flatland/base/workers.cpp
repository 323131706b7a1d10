#include "flatland/base/workers.hpp"

#include <cstdint>

#include "flatland/base/resources.hpp"

#include <algorithm>
#include <atomic>
#include <system_error>
#include <thread>

namespace flatland {

WorkerPool::WorkerPool(unsigned threads) : requested_(std::max(threads, 1u)) {
  unsigned helpers = requested_ - 1;
  // Under an address-space limit (ulimit -v) every thread's stack counts against it, and so does
  // the malloc arena a thread may get when it allocates while others do (glibc reserves 64 MiB of
  // address space for each, up to 8 per core): the helpers, with an arena each up to that count,
  // take at most half of what is left, so the work itself still has room. (Counting stacks alone
  // let the arenas of a busy start take the rest, and the work then ran out of memory.)
  if (const std::size_t left = address_space_left(); left != SIZE_MAX) {
    constexpr std::size_t kArenaBytes = std::size_t{64} << 20;
    const std::size_t arenas = 8 * std::size_t{std::max(1u, std::thread::hardware_concurrency())};
    std::size_t budget = left / 2;
    std::size_t room = 0;
    while (room < helpers) {
      const std::size_t cost = thread_stack_bytes() + (room < arenas ? kArenaBytes : 0);
      if (cost > budget) break;
      budget -= cost;
      ++room;
    }
    if (room < helpers) {
      helpers = static_cast<unsigned>(room);
      shortfall_ = "started " + std::to_string(helpers + 1) + " of the " + std::to_string(requested_) +
                   " threads asked for (the address-space limit, ulimit -v, leaves room for no more threads)";
    }
  }
  helpers_.reserve(helpers);
  for (unsigned i = 0; i < helpers; ++i) {
    try {
      helpers_.emplace_back(&WorkerPool::helper, this, i + 1);
    } catch (const std::exception& e) {
      // (std::system_error when the system refuses a thread; std::bad_alloc when a thread's state
      // does not fit.) The helpers started so far wait for work as in a pool of this size.
      const auto* refused = dynamic_cast<const std::system_error*>(&e);
      shortfall_ = "started " + std::to_string(helpers_.size() + 1) + " of the " + std::to_string(requested_) +
                   " threads asked for (the system refused more: " +
                   (refused != nullptr ? refused->code().message() : std::string("out of memory")) + ")";
      break;
    }
  }
}

WorkerPool::~WorkerPool() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  start_.notify_all();
  for (std::thread& thread : helpers_) thread.join();
}

void WorkerPool::run(unsigned workers, const std::function<void(unsigned)>& task) {
  workers = std::clamp(workers, 1u, threads());
  if (workers > 1) {
    std::lock_guard lock(mutex_);
    task_ = &task;
    workers_ = workers;
    running_ = workers - 1;
    failure_ = nullptr;
    ++generation_;
  }
  if (workers > 1) start_.notify_all();
  std::exception_ptr own;
  try {
    task(0);
  } catch (...) {
    own = std::current_exception();
  }
  if (workers == 1) {
    if (own) std::rethrow_exception(own);
    return;
  }
  std::unique_lock lock(mutex_);
  done_.wait(lock, [this] { return running_ == 0; });
  task_ = nullptr;
  if (own) std::rethrow_exception(own);
  if (failure_) std::rethrow_exception(failure_);
}

void WorkerPool::for_each(std::size_t count, const std::function<void(std::size_t)>& f) {
  std::atomic<std::size_t> next{0};
  const auto workers = static_cast<unsigned>(std::min<std::size_t>(threads(), count));
  run(workers, [&](unsigned) {
    for (std::size_t i = next.fetch_add(1); i < count; i = next.fetch_add(1)) f(i);
  });
}

void WorkerPool::helper(unsigned index) {
  std::uint64_t seen = 0;
  std::unique_lock lock(mutex_);
  for (;;) {
    start_.wait(lock, [&] { return stopping_ || generation_ != seen; });
    if (stopping_) return;
    seen = generation_;
    if (index >= workers_) continue;
    const std::function<void(unsigned)>* task = task_;
    lock.unlock();
    std::exception_ptr failure;
    try {
      (*task)(index);
    } catch (...) {
      failure = std::current_exception();
    }
    lock.lock();
    if (failure && !failure_) failure_ = failure;
    if (--running_ == 0) done_.notify_one();
  }
}

}  // namespace flatland
