#include <gtest/gtest.h>

#include <limits>
#include <map>
#include <random>

#include "evpipe/core/slicer.hpp"
#include "evpipe/core/stream_stats.hpp"

using evpipe::Event;
using evpipe::EventBatch;
using evpipe::EventBatchPtr;
using evpipe::EventWindow;
using evpipe::TimeSlicer;

namespace {

std::vector<Event> random_stream(std::mt19937_64& rng, std::size_t n, std::int64_t mean_gap_us) {
  std::vector<Event> ev;
  std::int64_t t = 1000;
  std::exponential_distribution<double> gap(1.0 / static_cast<double>(mean_gap_us));
  std::uniform_int_distribution<int> xy(0, 300);
  std::bernoulli_distribution burst_gap(0.002);
  for (std::size_t i = 0; i < n; ++i) {
    t += static_cast<std::int64_t>(gap(rng));
    if (burst_gap(rng)) t += 500'000;  // occasional long silence
    ev.push_back({t, static_cast<std::uint16_t>(xy(rng)), static_cast<std::uint16_t>(xy(rng)), (i % 3) == 0});
  }
  return ev;
}

std::vector<EventBatchPtr> cut(const std::vector<Event>& ev, std::mt19937_64& rng) {
  std::vector<EventBatchPtr> out;
  std::uniform_int_distribution<std::size_t> len(1, 700);
  for (std::size_t i = 0; i < ev.size();) {
    const std::size_t n = std::min(len(rng), ev.size() - i);
    auto b = std::make_shared<EventBatch>();
    b->events.assign(ev.begin() + static_cast<std::ptrdiff_t>(i), ev.begin() + static_cast<std::ptrdiff_t>(i + n));
    out.push_back(b);
    i += n;
  }
  return out;
}

// Brute force: every grid window [t0 + k*hop, + window) that holds events.
std::map<std::int64_t, std::vector<Event>> reference(const std::vector<Event>& ev, std::int64_t window,
                                                     std::int64_t hop) {
  std::map<std::int64_t, std::vector<Event>> out;
  const std::int64_t origin = ev.front().t_us;
  for (const auto& e : ev) {
    // all k with origin + k*hop <= t < origin + k*hop + window
    const std::int64_t k_max = (e.t_us - origin) / hop;
    for (std::int64_t k = k_max; k >= 0 && origin + k * hop + window > e.t_us; --k) out[origin + k * hop].push_back(e);
  }
  return out;
}

}  // namespace

TEST(TimeSlicer, RejectsBadOptions) {
  EXPECT_THROW(TimeSlicer({0, 10, std::nullopt}, [](const EventWindow&) {}), std::invalid_argument);
  EXPECT_THROW(TimeSlicer({10, -1, std::nullopt}, [](const EventWindow&) {}), std::invalid_argument);
}

TEST(TimeSlicer, MatchesBruteForceForFixedAndSlidingWindows) {
  for (const auto& [window, hop] : std::vector<std::pair<std::int64_t, std::int64_t>>{
           {30'000, 30'000}, {30'000, 10'000}, {30'000, 7'000}, {1'000, 1'000}, {50'000, 49'999}}) {
    const std::uint64_t seed = 1234 + static_cast<std::uint64_t>(window + hop);
    SCOPED_TRACE(testing::Message() << "window=" << window << " hop=" << hop << " seed=" << seed);
    std::mt19937_64 rng(seed);
    const auto ev = random_stream(rng, 20'000, 37);
    const auto expected = reference(ev, window, hop);
    std::map<std::int64_t, std::vector<Event>> got;
    std::size_t max_retained = 0;
    const std::int64_t window_us = window;  // a structured binding cannot be captured before clang 16
    TimeSlicer slicer({window, hop, std::nullopt}, [&](const EventWindow& w) {
      EXPECT_EQ(w.t1_us - w.t0_us, window_us);
      EXPECT_FALSE(got.count(w.t0_us)) << "window emitted twice";
      got[w.t0_us] = w.contiguous();
      EXPECT_EQ(w.size(), got[w.t0_us].size());
    });
    for (const auto& b : cut(ev, rng)) {
      slicer.accept(b);
      max_retained = std::max(max_retained, slicer.retained_batches());
    }
    slicer.flush();
    ASSERT_EQ(got.size(), expected.size());
    for (const auto& [t0, events] : expected) {
      ASSERT_TRUE(got.count(t0)) << "missing window at " << t0;
      EXPECT_EQ(got[t0], events) << "window at " << t0;
    }
    // Memory bounded by the window: a few hundred events per batch, ~800 events per window.
    EXPECT_LT(max_retained, 60U);
  }
}

TEST(TimeSlicer, DiscontinuityRestartsTheGrid) {
  std::vector<EventWindow> windows;
  std::vector<std::int64_t> starts;
  std::vector<bool> segment;
  TimeSlicer slicer({10, 10, std::nullopt}, [&](const EventWindow& w) {
    starts.push_back(w.t0_us);
    segment.push_back(w.starts_segment);
  });
  auto a = std::make_shared<EventBatch>();
  a->events = {{100, 0, 0, true}, {105, 0, 0, true}, {112, 0, 0, true}};
  auto b = std::make_shared<EventBatch>();
  b->events = {{3, 0, 0, true}, {14, 0, 0, true}};
  b->discontinuity_before = true;
  slicer.accept(a);
  slicer.accept(b);
  slicer.flush();
  EXPECT_EQ(starts, (std::vector<std::int64_t>{100, 110, 3, 13}));
  EXPECT_EQ(segment, (std::vector<bool>{true, false, true, false}));
}

TEST(TimeSlicer, StartOptionSetsTheGridOrigin) {
  std::vector<std::int64_t> starts;
  TimeSlicer slicer({10, 10, 0}, [&](const EventWindow& w) { starts.push_back(w.t0_us); });
  auto a = std::make_shared<EventBatch>();
  a->events = {{25, 0, 0, true}, {31, 0, 0, true}, {49, 0, 0, false}};
  slicer.accept(a);
  slicer.flush();
  EXPECT_EQ(starts, (std::vector<std::int64_t>{20, 30, 40}));
}

TEST(StreamStats, CountsRatesAndOnShare) {
  evpipe::StreamStats st(1000);
  std::vector<Event> ev;
  // 10 events in the first ms, then 1 per ms for 9 ms.
  for (int i = 0; i < 10; ++i) ev.push_back({i * 10, 0, 0, i < 4});
  for (int i = 1; i <= 9; ++i) ev.push_back({i * 1000 + 5, 0, 0, false});
  st.add(ev);
  EXPECT_EQ(st.events(), 19U);
  EXPECT_EQ(st.on_events(), 4U);
  EXPECT_EQ(*st.first_t_us(), 0);
  EXPECT_EQ(*st.last_t_us(), 9005);
  EXPECT_EQ(st.duration_us(), 9005);
  EXPECT_DOUBLE_EQ(st.peak_rate_hz(), 10.0 * 1e6 / 1000.0);
  EXPECT_NEAR(st.mean_rate_hz(), 19.0 / 0.009005, 1e-6);
  EXPECT_NEAR(st.on_share(), 4.0 / 19.0, 1e-12);
}

TEST(StreamStats, EmptyStream) {
  evpipe::StreamStats st;
  EXPECT_EQ(st.events(), 0U);
  EXPECT_FALSE(st.first_t_us());
  EXPECT_EQ(st.mean_rate_hz(), 0.0);
  EXPECT_EQ(st.peak_rate_hz(), 0.0);
}

// Issue 17 row 2: with t0 + window past INT64_MAX (a huge window, or a recording stamped near the end of the time
// line) the sums wrapped and emit_ready spun for ever. Every sum is now overflow-safe: the grid ends there.
TEST(TimeSlicer, TimesNearTheEndOfTheTimeLineEndTheGridInsteadOfWrapping) {
  constexpr std::int64_t kMax = std::numeric_limits<std::int64_t>::max();
  const auto batch_of = [](std::vector<std::int64_t> times, bool discontinuity = false) {
    auto b = std::make_shared<EventBatch>();
    for (const auto t : times) b->events.push_back({t, 1, 1, true});
    b->discontinuity_before = discontinuity;
    return EventBatchPtr(b);
  };
  for (const std::int64_t window : {std::int64_t{30'000}, kMax}) {
    for (const std::int64_t hop : {std::int64_t{30'000}, kMax / 2, kMax}) {
      SCOPED_TRACE(std::to_string(window) + " / " + std::to_string(hop));
      std::vector<std::pair<std::int64_t, std::int64_t>> windows;
      TimeSlicer slicer({window, hop, std::nullopt},
                        [&](const EventWindow& w) { windows.emplace_back(w.t0_us, w.t1_us); });
      slicer.accept(batch_of({kMax - 50'000, kMax - 40'000, kMax - 10}));
      slicer.accept(batch_of({kMax - 5, kMax}));
      slicer.flush();
      ASSERT_FALSE(windows.empty());
      ASSERT_LT(windows.size(), 10U);
      for (const auto& [t0, t1] : windows) EXPECT_LE(t0, t1);
      EXPECT_EQ(windows.front().first, kMax - 50'000);
      // A discontinuity restarts the grid at the next event.
      windows.clear();
      slicer.accept(batch_of({100, 200}, true));
      slicer.flush();
      ASSERT_FALSE(windows.empty());
      EXPECT_EQ(windows.front().first, 100);
    }
  }
}

// The jump over an empty stretch from the far negative end to the far positive end of the time line.
TEST(TimeSlicer, JumpAcrossTheWholeTimeLine) {
  constexpr std::int64_t kMax = std::numeric_limits<std::int64_t>::max();
  constexpr std::int64_t kMin = std::numeric_limits<std::int64_t>::min();
  std::vector<std::int64_t> starts;
  TimeSlicer slicer({30'000, 30'000, std::nullopt}, [&](const EventWindow& w) { starts.push_back(w.t0_us); });
  auto b = std::make_shared<EventBatch>();
  b->events = {{kMin + 1, 1, 1, true}, {kMax - 1, 1, 1, true}};
  slicer.accept(b);
  slicer.flush();
  ASSERT_EQ(starts.size(), 2U);
  EXPECT_EQ(starts[0], kMin + 1);
  EXPECT_LE(starts[1], kMax - 1);
  EXPECT_GT(starts[1], kMax - 1 - 30'000);
}

namespace {

EventBatchPtr batch_at(std::initializer_list<std::int64_t> times) {
  auto b = std::make_shared<EventBatch>();
  for (auto t : times) b->events.push_back({t, 1, 1, true});
  return b;
}

struct Cut {
  std::int64_t t0_us;
  std::size_t events;
};

}  // namespace

// A still target under a filter that keeps nothing: windows are still cut while the stream's time passes, within
// max_empty_span_us of the newest event; a longer silence is jumped over as without the option.
TEST(TimeSlicer, EmptyWindowsWithinTheSpanAreEmittedWhenAnEventCompletesThem) {
  std::vector<Cut> cuts;
  TimeSlicer s({30'000, 30'000, std::nullopt, 100'000}, [&](const EventWindow& w) {
    cuts.push_back({w.t0_us, w.size()});
  });
  s.accept(batch_at({0, 10'000, 29'000}));
  s.accept(batch_at({200'000}));
  s.flush();
  // [0,30) with 3; [30,60) [60,90) [90,120) empty (end <= 29 ms + 100 ms); [120,150) is not (ends at 150 > 129):
  // the grid jumps to the window holding 200 ms, [180,210).
  ASSERT_EQ(cuts.size(), 5U);
  const std::int64_t t0s[] = {0, 30'000, 60'000, 90'000, 180'000};
  const std::size_t ns[] = {3, 0, 0, 0, 1};
  for (std::size_t i = 0; i < cuts.size(); ++i) {
    EXPECT_EQ(cuts[i].t0_us, t0s[i]) << i;
    EXPECT_EQ(cuts[i].events, ns[i]) << i;
  }
}

TEST(TimeSlicer, AdvanceCompletesEmptyWindowsOnlyWithTheOption) {
  for (const std::int64_t span : {std::int64_t{0}, std::int64_t{100'000}}) {
    std::vector<Cut> cuts;
    TimeSlicer s({30'000, 30'000, std::nullopt, span}, [&](const EventWindow& w) {
      cuts.push_back({w.t0_us, w.size()});
    });
    s.advance(1'000'000);  // before any event: nothing to cut
    EXPECT_TRUE(cuts.empty());
    s.accept(batch_at({0, 29'000}));
    s.advance(30'000);  // completes [0,30)
    ASSERT_EQ(cuts.size(), span ? 1U : 0U) << span;
    s.advance(100'000);     // [30,60) and [60,90) are complete and empty; [90,120) is not complete
    s.advance(10'000'000);  // far ahead: only up to 29 ms + span
    if (span == 0) {
      EXPECT_TRUE(cuts.empty());
      continue;
    }
    ASSERT_EQ(cuts.size(), 4U);
    EXPECT_EQ(cuts[1].t0_us, 30'000);
    EXPECT_EQ(cuts[2].t0_us, 60'000);
    EXPECT_EQ(cuts[3].t0_us, 90'000);
    EXPECT_EQ(cuts[3].events, 0U);
    s.accept(batch_at({125'000}));  // the next event lands in [120,150): cut once complete
    s.advance(150'000);
    ASSERT_EQ(cuts.size(), 5U);
    EXPECT_EQ(cuts[4].t0_us, 120'000);
    EXPECT_EQ(cuts[4].events, 1U);
  }
}
