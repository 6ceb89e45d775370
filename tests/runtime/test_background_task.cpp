// BackgroundTask: one job at a time on a worker thread, never blocking the owner (runs under TSan in CI).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <future>
#include <stdexcept>
#include <string>
#include <thread>
#include <utility>

#include <pthread.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include "evpipe/runtime/background_task.hpp"

using evpipe::runtime::BackgroundTask;
using namespace std::chrono_literals;

TEST(BackgroundTask, RunsOneJobAtATimeAndHandsOverItsResultOnce) {
  BackgroundTask<int> task("test");
  EXPECT_FALSE(task.pending());
  EXPECT_FALSE(task.poll().has_value());  // nothing submitted

  std::promise<void> release;
  std::shared_future<void> go = release.get_future().share();
  ASSERT_TRUE(task.submit([go] {
    go.wait();
    return 42;
  }));
  EXPECT_TRUE(task.pending());
  EXPECT_FALSE(task.submit([] { return 7; }));  // busy: refused, not queued
  EXPECT_FALSE(task.poll().has_value());        // still running: the owner does not wait
  release.set_value();
  task.wait();
  EXPECT_TRUE(task.pending());  // finished but not collected
  EXPECT_FALSE(task.submit([] { return 7; }));
  const auto r = task.poll();
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(*r, 42);
  EXPECT_FALSE(task.pending());
  EXPECT_FALSE(task.poll().has_value());  // once

  ASSERT_TRUE(task.submit([] { return 7; }));  // free again: the same thread runs the next job
  task.wait();
  EXPECT_EQ(task.poll().value_or(0), 7);
  EXPECT_EQ(task.submitted(), 2u);
}

TEST(BackgroundTask, AJobThatThrowsRethrowsOnTheOwnersPoll) {
  BackgroundTask<std::string> task("test");
  ASSERT_TRUE(task.submit([]() -> std::string { throw std::runtime_error("solver failed"); }));
  task.wait();
  EXPECT_THROW(
      {
        try {
          (void)task.poll();
        } catch (const std::runtime_error& e) {
          EXPECT_STREQ(e.what(), "solver failed");
          throw;
        }
      },
      std::runtime_error);
  EXPECT_FALSE(task.pending());  // the error was handed over: the worker is free
  ASSERT_TRUE(task.submit([] { return std::string("ok"); }));
  task.wait();
  EXPECT_EQ(task.poll().value_or(""), "ok");
}

TEST(BackgroundTask, DestructorWaitsForTheRunningJob) {
  std::atomic<bool> finished{false};
  std::atomic<bool> started{false};
  {
    BackgroundTask<int> task("test");
    ASSERT_TRUE(task.submit([&] {
      started = true;
      std::this_thread::sleep_for(50ms);
      finished = true;
      return 1;
    }));
    while (!started) std::this_thread::yield();
  }  // joins here
  EXPECT_TRUE(finished);
}

TEST(BackgroundTask, OwnerKeepsWorkingWhileTheJobRuns) {
  // The pattern of the pose stage: poll every "window", never wait, submit the next job once one is collected.
  BackgroundTask<int> task("test");
  int collected = 0, polls = 0, next = 0;
  std::atomic<int> shared_with_jobs{0};
  while (collected < 5) {
    if (!task.pending()) {
      ASSERT_TRUE(task.submit([&shared_with_jobs, n = next++] {
        std::this_thread::sleep_for(2ms);
        shared_with_jobs.fetch_add(1);
        return n;
      }));
    }
    if (const auto r = task.poll()) {
      EXPECT_EQ(*r, collected);  // results come back in submission order, each once
      ++collected;
    }
    ++polls;
    std::this_thread::sleep_for(200us);
  }
  EXPECT_EQ(shared_with_jobs.load(), 5);
  EXPECT_GT(polls, 5);  // the owner went on while the jobs ran
}

TEST(BackgroundTask, TheWorkerRunsNamedAndAtALowerPriority) {
  const auto nice_of_this_thread = [] { return getpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid))); };
  const int owner = nice_of_this_thread();
  BackgroundTask<std::pair<int, std::string>> task("evpipe-init", 5);
  ASSERT_TRUE(task.submit([&] {
    char name[16] = {};
    pthread_getname_np(pthread_self(), name, sizeof name);
    return std::make_pair(nice_of_this_thread(), std::string(name));
  }));
  task.wait();
  const auto r = task.poll();
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->first, std::min(owner + 5, 19));  // nice values stop at 19
  EXPECT_EQ(r->second, "evpipe-init");
  EXPECT_EQ(nice_of_this_thread(), owner);  // per thread: the owner is untouched
}
