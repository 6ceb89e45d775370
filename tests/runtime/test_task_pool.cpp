// TaskPool: the tasks of one run() on the workers and the caller, all returned before run() returns, the first
// exception rethrown, many runs in a row (runs under TSan in CI).
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <mutex>
#include <set>
#include <stdexcept>
#include <thread>
#include <vector>

#include "evpipe/runtime/task_pool.hpp"

using evpipe::runtime::TaskPool;

TEST(TaskPool, RunsEveryTaskOnceAndSpreadsThemOverThreads) {
  TaskPool pool(2, "test-");
  EXPECT_EQ(pool.threads(), 3);
  for (const int count : {1, 2, 3, 7, 40}) {
    std::vector<int> ran(static_cast<std::size_t>(count), 0);  // each slot written by one task only
    pool.run(count, [&](int k) { ++ran[static_cast<std::size_t>(k)]; });
    for (int k = 0; k < count; ++k) EXPECT_EQ(ran[static_cast<std::size_t>(k)], 1) << count << " tasks, task " << k;
  }
  // Three tasks that wait for each other can only finish if three threads run them at once.
  std::atomic<int> arrived{0};
  std::mutex mu;
  std::set<std::thread::id> ids;
  pool.run(3, [&](int) {
    {
      const std::lock_guard lock(mu);
      ids.insert(std::this_thread::get_id());
    }
    ++arrived;
    // A pool that ran them one after another would never get here: give up after 10 s (a failure, not a hang).
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (arrived.load() < 3 && std::chrono::steady_clock::now() < deadline) std::this_thread::yield();
  });
  EXPECT_EQ(arrived.load(), 3);
  EXPECT_EQ(ids.size(), 3U);
  EXPECT_TRUE(ids.count(std::this_thread::get_id()) == 1) << "the caller runs task work too";
}

TEST(TaskPool, ManyRunsInARowAndResultsVisibleAfterRun) {
  TaskPool pool(1, "test-");
  std::vector<long> partial(2, 0);
  long total = 0;
  for (int run = 0; run < 2000; ++run) {
    pool.run(2, [&](int k) { partial[static_cast<std::size_t>(k)] = run * 10 + k; });
    total += partial[0] + partial[1];  // written by the worker: visible once run() has returned
  }
  long want = 0;
  for (int run = 0; run < 2000; ++run) want += 2 * run * 10 + 1;
  EXPECT_EQ(total, want);
}

TEST(TaskPool, TheFirstExceptionIsRethrownAfterEveryTaskReturned) {
  TaskPool pool(2, "test-");
  std::atomic<int> returned{0};
  try {
    pool.run(6, [&](int k) {
      ++returned;
      if (k == 4 || k == 5) throw std::runtime_error("task failed");  // one of them is rethrown
    });
    ADD_FAILURE() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_STREQ(e.what(), "task failed");
  }
  EXPECT_EQ(returned.load(), 6);
  // The pool is usable again.
  std::atomic<int> n{0};
  pool.run(4, [&](int) { ++n; });
  EXPECT_EQ(n.load(), 4);
}

TEST(TaskPool, NoWorkersRunsEverythingOnTheCaller) {
  TaskPool pool(0, "test-");
  std::vector<std::thread::id> ids(5);
  pool.run(5, [&](int k) { ids[static_cast<std::size_t>(k)] = std::this_thread::get_id(); });
  for (const auto& id : ids) EXPECT_EQ(id, std::this_thread::get_id());
  EXPECT_THROW(TaskPool(-1, "bad"), std::invalid_argument);
}
