// SPSC ring, named queues (policies, statistics), histogram and the generic stage loop.

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "evpipe/runtime/histogram.hpp"
#include "evpipe/runtime/queue.hpp"
#include "evpipe/runtime/spsc_ring.hpp"
#include "evpipe/runtime/stage.hpp"

using namespace evpipe::runtime;
using namespace std::chrono_literals;

namespace {

// ---- SpscRing ----

TEST(SpscRing, CapacityIsRoundedUpToAPowerOfTwo) {
  EXPECT_EQ(SpscRing<int>(1).capacity(), 1u);
  EXPECT_EQ(SpscRing<int>(5).capacity(), 8u);
  EXPECT_EQ(SpscRing<int>(64).capacity(), 64u);
  EXPECT_THROW(SpscRing<int>(0), std::invalid_argument);
}

TEST(SpscRing, FullRingRefusesAndLeavesTheValueIntact) {
  SpscRing<std::shared_ptr<int>> ring(4);
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(ring.try_push(std::make_shared<int>(i)));
  auto extra = std::make_shared<int>(99);
  EXPECT_FALSE(ring.try_push(std::move(extra)));
  ASSERT_NE(extra, nullptr);  // not moved from on failure
  EXPECT_EQ(*extra, 99);
  EXPECT_EQ(ring.size(), 4u);
  std::shared_ptr<int> out;
  for (int i = 0; i < 4; ++i) {
    ASSERT_TRUE(ring.try_pop(out));
    EXPECT_EQ(*out, i);
  }
  EXPECT_FALSE(ring.try_pop(out));
  EXPECT_EQ(out.use_count(), 1);  // popped slots do not keep a copy alive
  EXPECT_TRUE(ring.empty());
  EXPECT_EQ(ring.pushed(), 4u);
  EXPECT_EQ(ring.popped(), 4u);
}

TEST(SpscRing, WrapsAroundManyTimesSingleThread) {
  SpscRing<std::uint64_t> ring(4);
  std::uint64_t next_in = 0;
  std::uint64_t next_out = 0;
  for (int round = 0; round < 1000; ++round) {
    const int n = round % 5;  // 0..4 pushes per round: the ring runs empty and full
    for (int i = 0; i < n; ++i) {
      if (ring.try_push(std::uint64_t{next_in})) ++next_in;
    }
    std::uint64_t v = 0;
    for (int i = 0; i < (round % 3) + 1; ++i) {
      if (ring.try_pop(v)) {
        EXPECT_EQ(v, next_out++);
      }
    }
  }
  std::uint64_t v = 0;
  while (ring.try_pop(v)) EXPECT_EQ(v, next_out++);
  EXPECT_EQ(next_out, next_in);
}

// Two threads, a million items: every item arrives once, in order.
void two_thread_sequence(std::size_t capacity) {
  constexpr std::uint64_t kItems = 1'000'000;
  SpscRing<std::uint64_t> ring(capacity);
  std::thread producer([&] {
    for (std::uint64_t i = 0; i < kItems; ++i) {
      while (!ring.try_push(std::uint64_t{i})) std::this_thread::yield();
    }
  });
  std::uint64_t expected = 0;
  std::uint64_t errors = 0;
  std::uint64_t v = 0;
  while (expected < kItems) {
    if (ring.try_pop(v)) {
      if (v != expected) ++errors;
      expected = v + 1;
    } else {
      std::this_thread::yield();
    }
  }
  producer.join();
  EXPECT_EQ(errors, 0u);
  EXPECT_FALSE(ring.try_pop(v));  // nothing duplicated at the end
  EXPECT_EQ(ring.pushed(), kItems);
  EXPECT_EQ(ring.popped(), kItems);
}

TEST(SpscRing, TwoThreadsMillionItemsSmallRing) {
  two_thread_sequence(4);
}
TEST(SpscRing, TwoThreadsMillionItemsLargeRing) {
  two_thread_sequence(1024);
}

// ---- NamedQueue ----

void expect_stats(const QueueStats& s, std::uint64_t pushed, std::uint64_t popped, std::uint64_t dropped,
                  std::size_t fill, std::size_t high_water) {
  EXPECT_EQ(s.pushed, pushed);
  EXPECT_EQ(s.popped, popped);
  EXPECT_EQ(s.dropped, dropped);
  EXPECT_EQ(s.fill, fill);
  EXPECT_EQ(s.high_water, high_water);
  EXPECT_EQ(s.pushed, s.popped + s.dropped + s.fill);
}

TEST(NamedQueue, DropNewestDropsThePushedItemAndCounts) {
  NamedQueue<int> q("live", 4, QueuePolicy::drop_newest);
  EXPECT_EQ(q.name(), "live");
  EXPECT_EQ(q.capacity(), 4u);
  std::vector<PushResult> results;
  for (int i = 0; i < 10; ++i) results.push_back(q.push(int{i}));
  for (int i = 0; i < 4; ++i) EXPECT_EQ(results[static_cast<std::size_t>(i)], PushResult::pushed);
  for (int i = 4; i < 10; ++i) EXPECT_EQ(results[static_cast<std::size_t>(i)], PushResult::dropped);
  expect_stats(q.stats(), 10, 0, 6, 4, 4);
  int v = -1;
  for (int i = 0; i < 4; ++i) {  // the oldest items survive, in order
    ASSERT_EQ(q.pop(v, 0ms), PopResult::item);
    EXPECT_EQ(v, i);
  }
  EXPECT_EQ(q.pop(v, 1ms), PopResult::timeout);
  EXPECT_EQ(q.push(10), PushResult::pushed);
  expect_stats(q.stats(), 11, 4, 6, 1, 4);
  EXPECT_EQ(q.stats().policy, QueuePolicy::drop_newest);
}

TEST(NamedQueue, LatestWinsReplacesTheUntakenItem) {
  NamedQueue<int> q("hand-off", 1, QueuePolicy::latest_wins);
  EXPECT_EQ(q.capacity(), 1u);
  EXPECT_EQ(q.push(1), PushResult::pushed);
  EXPECT_EQ(q.push(2), PushResult::replaced);
  EXPECT_EQ(q.push(3), PushResult::replaced);
  expect_stats(q.stats(), 3, 0, 2, 1, 1);
  int v = 0;
  ASSERT_EQ(q.pop(v, 0ms), PopResult::item);
  EXPECT_EQ(v, 3);
  EXPECT_EQ(q.pop(v, 1ms), PopResult::timeout);
  EXPECT_EQ(q.push(4), PushResult::pushed);
  expect_stats(q.stats(), 4, 1, 2, 1, 1);
  q.close();
  ASSERT_EQ(q.pop(v, 0ms), PopResult::item);
  EXPECT_EQ(v, 4);
  EXPECT_EQ(q.pop(v, 0ms), PopResult::closed);
}

TEST(NamedQueue, BlockWaitsForSpace) {
  NamedQueue<int> q("replay", 2, QueuePolicy::block);
  EXPECT_EQ(q.push(0), PushResult::pushed);
  EXPECT_EQ(q.push(1), PushResult::pushed);
  std::atomic<bool> returned{false};
  PushResult third = PushResult::dropped;
  std::thread producer([&] {
    third = q.push(2);
    returned = true;
  });
  std::this_thread::sleep_for(50ms);
  EXPECT_FALSE(returned.load());  // a lossless queue does not drop: the producer is still waiting
  EXPECT_EQ(q.fill(), 2u);
  int v = -1;
  ASSERT_EQ(q.pop(v, 0ms), PopResult::item);
  EXPECT_EQ(v, 0);
  producer.join();
  EXPECT_EQ(third, PushResult::pushed);
  for (int want : {1, 2}) {
    ASSERT_EQ(q.pop(v, 1s), PopResult::item);
    EXPECT_EQ(v, want);
  }
  expect_stats(q.stats(), 3, 3, 0, 0, 2);
}

TEST(NamedQueue, BlockedPushWakesOnInterrupt) {
  NamedQueue<int> q("replay", 1, QueuePolicy::block);
  ASSERT_EQ(q.push(0), PushResult::pushed);
  std::atomic<std::uint64_t> beat{0};
  WaitObserver obs{&beat, {}};
  PushResult r = PushResult::pushed;
  std::thread producer([&] { r = q.push(1, &obs, 5ms); });
  while (beat.load() == 0) std::this_thread::yield();  // it is waiting (and beating)
  q.interrupt_producer();
  producer.join();
  EXPECT_EQ(r, PushResult::stopped);
  EXPECT_GT(obs.waited.count(), 0);
  expect_stats(q.stats(), 2, 0, 1, 1, 1);
  EXPECT_EQ(q.push(2), PushResult::stopped);  // interrupted for good once full
}

TEST(NamedQueue, BlockedPushWakesWhenTheConsumerAbandons) {
  NamedQueue<int> q("replay", 1, QueuePolicy::block);
  ASSERT_EQ(q.push(0), PushResult::pushed);
  PushResult r = PushResult::pushed;
  std::thread producer([&] { r = q.push(1); });
  q.abandon();
  producer.join();
  EXPECT_TRUE(r == PushResult::stopped || r == PushResult::dropped);
  EXPECT_EQ(q.push(2), PushResult::dropped);
  expect_stats(q.stats(), 3, 0, 3, 0, 1);  // the queued item was discarded and counted
}

TEST(NamedQueue, CloseDeliversTheRestThenClosed) {
  NamedQueue<int> q("q", 8, QueuePolicy::block);
  for (int i = 0; i < 3; ++i) q.push(int{i});
  q.close();
  EXPECT_EQ(q.push(9), PushResult::dropped);
  int v = -1;
  for (int i = 0; i < 3; ++i) {
    ASSERT_EQ(q.pop(v, 0ms), PopResult::item);
    EXPECT_EQ(v, i);
  }
  EXPECT_EQ(q.pop(v, 10ms), PopResult::closed);
  expect_stats(q.stats(), 4, 3, 1, 0, 3);
}

TEST(NamedQueue, ClosedWakesASleepingConsumer) {
  NamedQueue<int> q("q", 8, QueuePolicy::block);
  PopResult r = PopResult::item;
  std::thread consumer([&] {
    int v = 0;
    r = q.pop(v, 10s);
  });
  std::this_thread::sleep_for(10ms);
  q.close();
  consumer.join();  // well before 10 s
  EXPECT_EQ(r, PopResult::closed);
}

// ---- weight budget (the source queue weighs a packet by its events) ----

std::uint64_t weight_of(const int& v) {
  return static_cast<std::uint64_t>(v);
}

TEST(NamedQueue, WeightBudgetDropsWhatDoesNotFitButNotIntoAnEmptyQueue) {
  NamedQueue<int> q("live", 8, QueuePolicy::drop_newest);
  q.set_weight_budget(10, weight_of);
  EXPECT_EQ(q.push(4), PushResult::pushed);
  EXPECT_EQ(q.push(5), PushResult::pushed);   // 9 queued
  EXPECT_EQ(q.push(2), PushResult::dropped);  // 11 > 10: counts as full although the ring has room
  EXPECT_EQ(q.push(1), PushResult::pushed);   // exactly the budget
  auto s = q.stats();
  EXPECT_EQ(s.weight_budget, 10u);
  EXPECT_EQ(s.weight_fill, 10u);
  EXPECT_EQ(s.weight_high_water, 10u);
  expect_stats(s, 4, 0, 1, 3, 3);
  int v = 0;
  ASSERT_EQ(q.pop(v, 0ms), PopResult::item);
  EXPECT_EQ(v, 4);
  EXPECT_EQ(q.stats().weight_fill, 6u);
  EXPECT_EQ(q.push(4), PushResult::pushed);
  for (int want : {5, 1, 4}) {
    ASSERT_EQ(q.pop(v, 0ms), PopResult::item);
    EXPECT_EQ(v, want);
  }
  EXPECT_EQ(q.stats().weight_fill, 0u);
  // A single item larger than the whole budget passes into an empty queue (it could never fit otherwise), and then
  // nothing joins it.
  EXPECT_EQ(q.push(50), PushResult::pushed);
  EXPECT_EQ(q.push(1), PushResult::dropped);
  s = q.stats();
  EXPECT_EQ(s.weight_fill, 50u);
  EXPECT_EQ(s.weight_high_water, 50u);
  expect_stats(s, 7, 4, 2, 1, 3);
}

TEST(NamedQueue, WeightBudgetMakesABlockingPushWait) {
  NamedQueue<int> q("replay", 8, QueuePolicy::block);
  q.set_weight_budget(10, weight_of);
  ASSERT_EQ(q.push(6), PushResult::pushed);
  std::atomic<bool> returned{false};
  PushResult second = PushResult::dropped;
  std::thread producer([&] {
    second = q.push(6);
    returned = true;
  });
  std::this_thread::sleep_for(50ms);
  EXPECT_FALSE(returned.load());  // the ring has room, the budget has not: lossless, so it waits
  int v = 0;
  ASSERT_EQ(q.pop(v, 0ms), PopResult::item);
  producer.join();
  EXPECT_EQ(second, PushResult::pushed);
  ASSERT_EQ(q.pop(v, 1s), PopResult::item);
  EXPECT_EQ(v, 6);
  const auto s = q.stats();
  expect_stats(s, 2, 2, 0, 0, 1);
  EXPECT_EQ(s.weight_fill, 0u);
  EXPECT_EQ(s.weight_high_water, 6u);
}

TEST(NamedQueue, WeightBudgetHoldsBetweenTwoThreadsAndDiscardAccountsForTheRest) {
  for (const QueuePolicy policy : {QueuePolicy::block, QueuePolicy::drop_newest}) {
    SCOPED_TRACE(std::string(policy_name(policy)));
    constexpr int kItems = 50'000;
    NamedQueue<int> q("stress", 64, policy);
    q.set_weight_budget(100, weight_of);
    std::thread producer([&] {
      for (int i = 0; i < kItems; ++i) q.push(1 + i % 37);
      q.close();
    });
    // Read from the consumer's thread and from a third one (as the publish thread reads the statistics).
    std::atomic<bool> done{false};
    std::atomic<std::uint64_t> third_violations{0};
    std::thread observer([&] {
      while (!done.load()) {
        if (q.stats().weight_fill > 100) third_violations.fetch_add(1);
      }
    });
    std::uint64_t got = 0;
    std::uint64_t violations = 0;
    int v = 0;
    for (;;) {
      const auto s = q.stats();
      if (s.weight_fill > 100) ++violations;
      const auto r = q.pop(v, 50ms);
      if (r == PopResult::closed) break;
      if (r == PopResult::item) ++got;
    }
    producer.join();
    done = true;
    observer.join();
    EXPECT_EQ(third_violations.load(), 0u);
    const auto s = q.stats();
    EXPECT_EQ(violations, 0u);
    EXPECT_LE(s.weight_high_water, 100u);
    EXPECT_EQ(s.weight_fill, 0u);
    EXPECT_EQ(s.pushed, s.popped + s.dropped);
    EXPECT_EQ(s.popped, got);
    if (policy == QueuePolicy::block) {
      EXPECT_EQ(got, static_cast<std::uint64_t>(kItems));
    }
  }
  NamedQueue<int> q("left", 8, QueuePolicy::block);
  q.set_weight_budget(100, weight_of);
  q.push(30);
  q.push(40);
  q.discard_queued();
  EXPECT_EQ(q.stats().weight_fill, 0u);
  NamedQueue<int> hand_off("hand-off", 1, QueuePolicy::latest_wins);
  EXPECT_THROW(hand_off.set_weight_budget(10, weight_of), std::invalid_argument);
}

// Two threads through each policy: order preserved, nothing duplicated, counters add up exactly.
void two_thread_policy(QueuePolicy policy, std::size_t capacity) {
  constexpr int kItems = 100'000;
  NamedQueue<int> q("stress", capacity, policy);
  std::thread producer([&] {
    for (int i = 0; i < kItems; ++i) q.push(int{i});
    q.close();
  });
  std::vector<int> got;
  int v = 0;
  for (;;) {
    const auto r = q.pop(v, 50ms);
    if (r == PopResult::closed) break;
    if (r == PopResult::item) got.push_back(v);
  }
  producer.join();
  for (std::size_t i = 1; i < got.size(); ++i) ASSERT_LT(got[i - 1], got[i]) << "at " << i;
  const auto s = q.stats();
  EXPECT_EQ(s.pushed, static_cast<std::uint64_t>(kItems));
  EXPECT_EQ(s.popped, got.size());
  EXPECT_EQ(s.pushed, s.popped + s.dropped);
  EXPECT_EQ(s.fill, 0u);
  EXPECT_LE(s.high_water, s.capacity);
  if (policy == QueuePolicy::block) {
    EXPECT_EQ(s.dropped, 0u);
    EXPECT_EQ(got.size(), static_cast<std::size_t>(kItems));
  }
  if (policy == QueuePolicy::latest_wins) {
    ASSERT_FALSE(got.empty());
    EXPECT_EQ(got.back(), kItems - 1);  // the freshest item always gets through
  }
}

TEST(NamedQueue, TwoThreadsBlock) {
  two_thread_policy(QueuePolicy::block, 16);
}
TEST(NamedQueue, TwoThreadsDropNewest) {
  two_thread_policy(QueuePolicy::drop_newest, 16);
}
TEST(NamedQueue, TwoThreadsLatestWins) {
  two_thread_policy(QueuePolicy::latest_wins, 1);
}

TEST(NamedQueue, StatsReadConcurrentlyStayConsistent) {
  NamedQueue<int> q("q", 8, QueuePolicy::drop_newest);
  std::atomic<bool> done{false};
  std::thread producer([&] {
    for (int i = 0; i < 50'000; ++i) q.push(int{i});
    q.close();
  });
  std::thread consumer([&] {
    int v = 0;
    while (q.pop(v, 10ms) != PopResult::closed) {
    }
    done = true;
  });
  std::uint64_t violations = 0;
  while (!done.load()) {
    const auto s = q.stats();
    if (s.popped + s.dropped > s.pushed) ++violations;
    if (s.fill > s.capacity || s.high_water > s.capacity) ++violations;
  }
  producer.join();
  consumer.join();
  EXPECT_EQ(violations, 0u);
}

// ---- Histogram ----

TEST(Histogram, ExactPercentilesOnSmallValues) {
  Histogram h;
  for (std::uint64_t v = 60; v >= 1; --v) h.record(v);  // order does not matter
  const auto s = h.summary();
  EXPECT_EQ(s.count, 60u);
  EXPECT_EQ(s.min, 1u);
  EXPECT_EQ(s.max, 60u);
  EXPECT_DOUBLE_EQ(s.mean, 30.5);
  EXPECT_EQ(s.p50, 30u);  // nearest rank: ceil(0.5 * 60) = 30th value
  EXPECT_EQ(s.p90, 54u);
  EXPECT_EQ(s.p99, 60u);
}

TEST(Histogram, LargeValuesReportTheirBucketUpperBound) {
  Histogram h;
  for (int i = 0; i < 900; ++i) h.record(1000);
  for (int i = 0; i < 100; ++i) h.record(5'000'000);
  const auto s = h.summary();
  EXPECT_EQ(Histogram::reported(1000), 1007u);  // [992, 1007]: bucket width 16 in the octave [512, 1024)
  EXPECT_EQ(s.p50, 1007u);
  EXPECT_EQ(s.p90, 1007u);
  EXPECT_EQ(s.p99, 5'000'000u);  // bucket upper bound clamped to the exact maximum
  EXPECT_EQ(s.max, 5'000'000u);
  EXPECT_EQ(s.min, 1000u);
  EXPECT_EQ(s.count, 1000u);
}

TEST(Histogram, SingleValueReadsBackExactly) {
  Histogram h;
  for (int i = 0; i < 7; ++i) h.record(12'345'678);
  const auto s = h.summary();
  EXPECT_EQ(s.p50, 12'345'678u);
  EXPECT_EQ(s.p99, 12'345'678u);
  EXPECT_EQ(Histogram{}.summary().p50, 0u);
}

TEST(Histogram, BucketsBoundTheRelativeError) {
  const std::uint32_t seed = 20261121;
  std::mt19937_64 rng(seed);
  SCOPED_TRACE("seed " + std::to_string(seed));
  for (int i = 0; i < 100'000; ++i) {
    const std::uint64_t v = rng() >> (rng() % 64);
    const std::size_t b = Histogram::bucket_of(v);
    ASSERT_LT(b, Histogram::kBuckets);
    const std::uint64_t up = Histogram::bucket_upper(b);
    ASSERT_GE(up, v);
    if (v < (std::uint64_t{1} << 47)) {
      ASSERT_LE(static_cast<double>(up - v), static_cast<double>(v) / 32.0) << v;
      ASSERT_EQ(Histogram::bucket_of(up), b) << v;
      if (b > 0) {
        ASSERT_LT(Histogram::bucket_upper(b - 1), v);
      }
    }
  }
}

TEST(Histogram, RecordOnOneThreadSnapshotOnAnother) {
  Histogram h;
  std::atomic<bool> done{false};
  std::thread writer([&] {
    for (std::uint64_t i = 0; i < 200'000; ++i) h.record(i % 1000);
    done = true;
  });
  std::uint64_t last = 0;
  std::uint64_t regressions = 0;
  while (!done.load()) {
    const auto s = h.snapshot();
    if (s.count() < last) ++regressions;
    last = s.count();
  }
  writer.join();
  EXPECT_EQ(regressions, 0u);
  EXPECT_EQ(h.snapshot().count(), 200'000u);
  EXPECT_EQ(h.summary().max, 999u);
}

// ---- StageRunner ----

class Collect final : public Stage<int> {
 public:
  void step(int&& v) override {
    if (v == throw_at) throw std::runtime_error("bad item " + std::to_string(v));
    got.push_back(v);
  }
  void finish() override { finished = true; }
  std::vector<int> got;
  bool finished = false;
  int throw_at = -1;
};

TEST(StageRunner, RunsUntilTheInputIsClosedAndDrained) {
  NamedQueue<int> in("in", 4, QueuePolicy::block);
  StageMetrics m("collect");
  Collect stage;
  CancelDeadline cancel;
  int exits = 0;
  StageRunner<int> runner(m, in, stage, cancel, {[&] { ++exits; }, {}}, 5ms);
  runner.start();
  for (int i = 0; i < 100; ++i) ASSERT_EQ(in.push(int{i}), PushResult::pushed);
  in.close();
  runner.join();
  ASSERT_EQ(stage.got.size(), 100u);
  for (int i = 0; i < 100; ++i) EXPECT_EQ(stage.got[static_cast<std::size_t>(i)], i);
  EXPECT_TRUE(stage.finished);
  EXPECT_EQ(exits, 1);
  const auto s = m.snapshot();
  EXPECT_EQ(s.name, "collect");
  EXPECT_EQ(s.state, StageState::finished);
  EXPECT_EQ(s.items_in, 100u);
  EXPECT_EQ(s.step_ns.count, 100u);
  EXPECT_GE(s.heartbeat, 100u);
}

TEST(StageRunner, AThrowingStepIsReportedAndAbandonsTheInput) {
  NamedQueue<int> in("in", 4, QueuePolicy::block);
  StageMetrics m("collect");
  Collect stage;
  stage.throw_at = 3;
  CancelDeadline cancel;
  std::string error;
  StageRunner<int> runner(m, in, stage, cancel,
                          {{}, [&](const std::string& name, const std::string& what) { error = name + ": " + what; }},
                          5ms);
  runner.start();
  int pushed = 0;
  for (int i = 0; i < 1000; ++i) {
    if (in.push(int{i}) == PushResult::pushed) ++pushed;
  }
  runner.join();  // no std::terminate, no hang: the producer stopped waiting when the stage failed
  EXPECT_EQ(error, "collect: bad item 3");
  EXPECT_EQ(stage.got, (std::vector<int>{0, 1, 2}));
  EXPECT_FALSE(stage.finished);
  EXPECT_EQ(m.snapshot().state, StageState::failed);
  EXPECT_LT(pushed, 1000);
}

TEST(StageRunner, IdleStageKeepsBeatingAndCancelStopsIt) {
  NamedQueue<int> in("in", 4, QueuePolicy::block);
  StageMetrics m("idle");
  Collect stage;
  CancelDeadline cancel;
  StageRunner<int> runner(m, in, stage, cancel, {}, 1ms);
  runner.start();
  const auto b0 = m.heartbeat.load();
  while (m.heartbeat.load() < b0 + 3) std::this_thread::yield();  // alive while waiting for input
  cancel.request_now();
  runner.join();
  EXPECT_EQ(m.snapshot().state, StageState::cancelled);
  EXPECT_FALSE(stage.finished);
  EXPECT_EQ(in.push(1), PushResult::dropped);  // abandoned
}

// ---- outlets: the same stage pushed to through a queue or driven in line ----

/// Forwards each item (doubled) to its outlet; ticks are counted; throws on `throw_at` (in its step or its tick).
class Forward final : public Stage<int> {
 public:
  void step(int&& v) override {
    if (v == throw_at && !throw_in_tick) throw std::runtime_error("bad item " + std::to_string(v));
    last = v;
    if (out) out->push(2 * v);
  }
  void tick(Clock::time_point /*now*/) override {
    ++ticks;
    if (last == throw_at && throw_in_tick) throw std::runtime_error("tick after " + std::to_string(last));
  }
  Outlet<int>* out = nullptr;
  int last = -1;
  int ticks = 0;
  int throw_at = -1;
  bool throw_in_tick = false;
};

TEST(Outlet, QueueOutletPushesUnderTheQueuesPolicy) {
  NamedQueue<int> q("q", 2, QueuePolicy::drop_newest);
  QueueOutlet<int> out(q, nullptr);
  EXPECT_EQ(out.push(1), PushResult::pushed);
  EXPECT_EQ(out.push(2), PushResult::pushed);
  EXPECT_EQ(out.push(3), PushResult::dropped);
  int v = 0;
  ASSERT_EQ(q.pop(v, 1ms), PopResult::item);
  EXPECT_EQ(v, 1);
}

TEST(Outlet, InlineOutletStepsTicksAndCountsTheNextStage) {
  StageMetrics m_a("a");
  StageMetrics m_b("b");
  Forward a;
  Collect b;
  InlineOutlet<int> to_b(m_b, b);
  InlineOutlet<int> to_a(m_a, a);
  a.out = &to_b;
  for (int i = 0; i < 5; ++i) EXPECT_EQ(to_a.push(int{i}), PushResult::pushed);
  EXPECT_EQ(b.got, (std::vector<int>{0, 2, 4, 6, 8}));
  EXPECT_EQ(a.ticks, 5);
  const auto sa = m_a.snapshot();
  EXPECT_EQ(sa.items_in, 5u);
  EXPECT_EQ(sa.step_ns.count, 5u);
  EXPECT_EQ(sa.heartbeat, 5u);
  EXPECT_EQ(m_b.snapshot().items_in, 5u);
}

TEST(Outlet, InlineOutletNamesTheStageThatThrewInItsStepOrTick) {
  for (const bool in_tick : {false, true}) {
    SCOPED_TRACE(in_tick ? "tick" : "step");
    StageMetrics m_a("a");
    StageMetrics m_b("b");
    Forward a;
    Forward b;  // the one that fails
    b.throw_at = 4;
    b.throw_in_tick = in_tick;
    InlineOutlet<int> to_b(m_b, b);
    InlineOutlet<int> to_a(m_a, a);
    a.out = &to_b;
    to_a.push(1);
    try {
      to_a.push(2);  // b gets 4
      ADD_FAILURE() << "no exception";
    } catch (const StageFailure& e) {
      EXPECT_EQ(e.stage(), "b");  // passed unchanged through a's outlet
      EXPECT_EQ(std::string(e.what()), in_tick ? "tick after 4" : "bad item 4");
    }
  }
}

}  // namespace
