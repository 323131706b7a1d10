// The persistent worker pool: every worker index runs once per run, every index of for_each is
// visited once, runs follow each other without lost wake-ups, failures come back to the caller,
// and a copied holder starts its own threads.
#include "flatland/base/workers.hpp"

#include <algorithm>
#include <atomic>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

namespace flatland {
namespace {

TEST(WorkerPool, EachWorkerRunsOncePerRun) {
  for (unsigned threads : {1u, 2u, 4u}) {
    WorkerPool pool(threads);
    EXPECT_EQ(pool.threads(), threads);
    for (unsigned workers = 1; workers <= threads + 2; ++workers) {
      std::vector<std::atomic<int>> calls(threads + 2);
      pool.run(workers, [&](unsigned w) { ++calls[w]; });
      const unsigned expected = std::min(workers, threads);  // clamped to the pool's size
      for (unsigned w = 0; w < calls.size(); ++w)
        EXPECT_EQ(calls[w].load(), w < expected ? 1 : 0) << threads << " " << workers << " " << w;
    }
  }
}

TEST(WorkerPool, WorkerZeroIsTheCaller) {
  WorkerPool pool(3);
  std::thread::id zero;
  std::set<std::thread::id> others;
  std::mutex mutex;
  pool.run(3, [&](unsigned w) {
    std::lock_guard lock(mutex);
    if (w == 0)
      zero = std::this_thread::get_id();
    else
      others.insert(std::this_thread::get_id());
  });
  EXPECT_EQ(zero, std::this_thread::get_id());
  EXPECT_EQ(others.size(), 2u);
  EXPECT_EQ(others.count(std::this_thread::get_id()), 0u);
}

TEST(WorkerPool, ForEachVisitsEveryIndexOnce) {
  for (unsigned threads : {1u, 2u, 3u}) {
    WorkerPool pool(threads);
    for (std::size_t count : {std::size_t{0}, std::size_t{1}, std::size_t{2}, std::size_t{1000}}) {
      std::vector<std::atomic<int>> visits(count);
      pool.for_each(count, [&](std::size_t i) { ++visits[i]; });
      for (std::size_t i = 0; i < count; ++i) ASSERT_EQ(visits[i].load(), 1) << threads << " " << count << " " << i;
    }
  }
}

// Many short runs in a row, alternating the number of workers: a helper that missed a wake-up or
// ran a stale task would change the sum or hang (ctest's timeout).
TEST(WorkerPool, ManyShortRunsInARow) {
  WorkerPool pool(3);
  std::atomic<long> sum{0};
  long expected = 0;
  for (int i = 0; i < 20000; ++i) {
    const unsigned workers = 1 + static_cast<unsigned>(i % 3);
    pool.run(workers, [&](unsigned w) { sum += static_cast<long>(w) + 1; });
    expected += static_cast<long>(workers) * (workers + 1) / 2;
  }
  EXPECT_EQ(sum.load(), expected);
}

TEST(WorkerPool, FailureReachesTheCallerAndThePoolGoesOn) {
  WorkerPool pool(2);
  EXPECT_THROW(pool.run(2,
                        [](unsigned w) {
                          if (w == 1) throw std::runtime_error("helper");
                        }),
               std::runtime_error);
  EXPECT_THROW(pool.run(2,
                        [](unsigned w) {
                          if (w == 0) throw std::runtime_error("caller");
                        }),
               std::runtime_error);
  std::atomic<int> calls{0};
  pool.run(2, [&](unsigned) { ++calls; });
  EXPECT_EQ(calls.load(), 2);
}

TEST(LazyWorkerPool, StartsOnFirstUseAndCopiesStartTheirOwn) {
  LazyWorkerPool a;
  WorkerPool& first = a.get(2);
  EXPECT_EQ(&a.get(2), &first);  // kept
  LazyWorkerPool b = a;          // a copy: its own pool when it needs one
  EXPECT_NE(&b.get(2), &first);
  LazyWorkerPool c = std::move(a);  // a move: the same threads
  EXPECT_EQ(&c.get(2), &first);
  EXPECT_EQ(c.get(3).threads(), 3u);  // another size restarts it
}

}  // namespace
}  // namespace flatland
