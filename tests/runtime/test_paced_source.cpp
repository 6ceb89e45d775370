#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <limits>
#include <thread>
#include <vector>

#include "evpipe/runtime/paced_source.hpp"
#include "vector_source.hpp"

using namespace evpipe;

namespace {
using evpipe::testing::VectorSource;

EventBatchPtr batch(std::vector<std::int64_t> ts, bool disc = false, bool labelled = false) {
  auto b = std::make_shared<EventBatch>();
  for (auto t : ts) {
    b->events.push_back({t, 1, 2, true});
    if (labelled) b->labels.push_back(t % 2 ? Label::signal : Label::noise);
  }
  b->discontinuity_before = disc;
  return b;
}
}  // namespace

TEST(PacedSource, RecutsIntoChunksAndKeepsEveryEvent) {
  auto inner = std::make_unique<VectorSource>(std::vector<EventBatchPtr>{batch({0, 100, 999, 1000, 2500}, false, true),
                                                                         batch({2600, 9000}), batch({5, 7}, true)});
  runtime::PacedSource paced(std::move(inner), 1000.0, 1000);  // 1000x: 9 ms of events take ~9 us
  std::vector<std::vector<std::int64_t>> chunks;
  std::vector<bool> disc;
  std::size_t labelled_events = 0;
  while (auto b = paced.next()) {
    chunks.emplace_back();
    for (const auto& e : b->events) chunks.back().push_back(e.t_us);
    disc.push_back(b->discontinuity_before);
    labelled_events += b->labels.size();
    if (!b->labels.empty()) {
      EXPECT_EQ(b->labels.size(), b->events.size());
    }
  }
  EXPECT_TRUE(paced.finished());
  EXPECT_EQ(chunks, (std::vector<std::vector<std::int64_t>>{{0, 100, 999}, {1000}, {2500}, {2600}, {9000}, {5, 7}}));
  EXPECT_EQ(disc, (std::vector<bool>{false, false, false, false, false, true}));
  EXPECT_EQ(labelled_events, 5U);
}

TEST(PacedSource, PacesInRealTime) {
  // 200 ms of events at speed 2 → at least ~100 ms of wall time.
  auto inner = std::make_unique<VectorSource>(std::vector<EventBatchPtr>{batch({0, 50'000, 100'000, 200'000})});
  runtime::PacedSource paced(std::move(inner), 2.0);
  const auto t0 = std::chrono::steady_clock::now();
  std::size_t n = 0;
  while (auto b = paced.next()) n += b->size();
  const auto wall = std::chrono::steady_clock::now() - t0;
  EXPECT_EQ(n, 4U);
  // A lower bound only (never an upper one: machines are noisy): pacing must not deliver early.
  EXPECT_GE(wall, std::chrono::milliseconds(99));
}

TEST(PacedSource, StopEndsASleep) {
  auto inner = std::make_unique<VectorSource>(std::vector<EventBatchPtr>{batch({0, 60'000'000})});
  runtime::PacedSource paced(std::move(inner), 1.0);
  ASSERT_TRUE(paced.next());  // t = 0 is due at once
  std::thread stopper([&paced] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    paced.stop();
  });
  EXPECT_EQ(paced.next(), nullptr);  // would otherwise sleep a minute
  stopper.join();
  EXPECT_TRUE(paced.finished());
}

TEST(PacedSource, RejectsBadSpeed) {
  EXPECT_THROW(runtime::PacedSource(std::make_unique<VectorSource>(std::vector<EventBatchPtr>{}), 0.0),
               std::invalid_argument);
}

// Issue 17 row 2: sums of times near the ends of the int64 line overflowed (the chunk end start_t + chunk_us, the
// wait t - anchor, and the steady clock's nanoseconds). Events at the end of the line are delivered in order; a
// jump across the whole line is a (capped) wait that stop() ends.
TEST(PacedSource, TimesAtTheEndsOfTheTimeLine) {
  constexpr std::int64_t kMax = std::numeric_limits<std::int64_t>::max();
  constexpr std::int64_t kMin = std::numeric_limits<std::int64_t>::min();
  auto inner = std::make_unique<VectorSource>(std::vector<EventBatchPtr>{batch({kMax - 10, kMax - 5, kMax})});
  runtime::PacedSource paced(std::move(inner), 1000.0);
  std::vector<std::int64_t> seen;
  while (auto b = paced.next())
    for (const auto& e : b->events) seen.push_back(e.t_us);
  EXPECT_EQ(seen, (std::vector<std::int64_t>{kMax - 10, kMax - 5, kMax}));

  auto across = std::make_unique<VectorSource>(std::vector<EventBatchPtr>{batch({kMin, kMax})});
  runtime::PacedSource far(std::move(across), 1.0);
  ASSERT_TRUE(far.next());
  std::thread stopper([&far] {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    far.stop();
  });
  EXPECT_EQ(far.next(), nullptr);
  stopper.join();
}

namespace {
/// A camera-like inner source: reports its connection and reconnects, records stop().
class Device final : public EventSource {
 public:
  EventBatchPtr next() override { return stopped.load() ? nullptr : batch({t_us += 10}); }
  [[nodiscard]] bool finished() const override { return stopped.load(); }
  [[nodiscard]] const SourceInfo& info() const override { return info_; }
  [[nodiscard]] const SourceStats& stats() const override { return stats_; }
  [[nodiscard]] SourceConnection connection() const noexcept override { return SourceConnection::disconnected; }
  [[nodiscard]] std::uint64_t reconnects() const noexcept override { return 3; }
  void stop() noexcept override { stopped.store(true); }
  std::atomic<bool> stopped{false};

 private:
  std::int64_t t_us = 0;
  SourceInfo info_;
  SourceStats stats_;
};
}  // namespace

// What the pipeline asks of every source, through the pacer: the inner source's state, stop() passed on, and each
// chunk stamped with the host time it was released (the start of the latency figures).
TEST(PacedSource, ForwardsStateAndStopAndStampsReleaseTimes) {
  auto inner = std::make_unique<Device>();
  Device* device = inner.get();
  runtime::PacedSource paced(std::move(inner), 1000.0);
  EXPECT_EQ(paced.connection(), SourceConnection::disconnected);
  EXPECT_EQ(paced.reconnects(), 3u);
  std::chrono::steady_clock::time_point previous{};
  for (int i = 0; i < 3; ++i) {
    const auto before = std::chrono::steady_clock::now();
    const auto b = paced.next();
    ASSERT_TRUE(b);
    EXPECT_GE(b->read_at, before);
    EXPECT_GE(b->read_at, previous);
    previous = b->read_at;
  }
  paced.stop();
  EXPECT_TRUE(device->stopped.load());
  EXPECT_TRUE(paced.finished());
  EXPECT_EQ(paced.next(), nullptr);
}
