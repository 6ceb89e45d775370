// Significance filter: each term on hand-built event sets (isolated event, slow edge, hot pixel, burst, recency, an
// edge entering with no history and a corner for the look-ahead), the thresholds' noise model, the BA rate estimate,
// and stream = batch.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "evpipe/denoise/registry.hpp"
#include "evpipe/denoise/significance.hpp"

namespace evpipe::denoise {
namespace {

SignificanceOptions at_rate(double rate_hz) {
  SignificanceOptions o;
  o.initial_rate_hz = rate_hz;
  o.rate_period_us = 1'000'000'000;  // keep the initial rate for the whole test
  return o;
}

/// Uniform background activity at rate_hz per pixel over [0, duration_us] on the DAVIS346, time-sorted.
std::vector<Event> pure_noise(double rate_hz, std::int64_t duration_us, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  const auto n =
      static_cast<std::size_t>(rate_hz * kDavis346.width * kDavis346.height * static_cast<double>(duration_us) / 1e6);
  std::vector<Event> ev(n);
  std::uniform_int_distribution<int> x(0, kDavis346.width - 1), y(0, kDavis346.height - 1);
  std::uniform_int_distribution<std::int64_t> t(0, duration_us);
  std::bernoulli_distribution pol(0.5);
  for (auto& e : ev) e = {t(rng), static_cast<std::uint16_t>(x(rng)), static_cast<std::uint16_t>(y(rng)), pol(rng)};
  std::sort(ev.begin(), ev.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  return ev;
}

/// A straight edge moving along +x at `speed_px_s`: column x fires at t0 + x / speed, rows y0..y0+rows-1.
std::vector<Event> edge(double speed_px_s, int x0, int columns, int y0, int rows, std::int64_t t0_us) {
  std::vector<Event> ev;
  for (int c = 0; c < columns; ++c) {
    const auto t = t0_us + static_cast<std::int64_t>(std::llround(c / speed_px_s * 1e6));
    for (int r = 0; r < rows; ++r) {
      ev.push_back({t, static_cast<std::uint16_t>(x0 + c), static_cast<std::uint16_t>(y0 + r), true});
    }
  }
  return ev;
}

TEST(Significance, IsolatedEventIsDropped) {
  Significance f(kDavis346, at_rate(1.0));
  EXPECT_FALSE(f.accept({1'000'000, 100, 100, true}));
  EXPECT_LT(f.last_score(), 1.0F);
  // A lone neighbour a few ms earlier is what noise gives: still dropped (one neighbour is no line).
  EXPECT_FALSE(f.accept({1'003'000, 101, 100, true}));
}

TEST(Significance, SlowEdgeIsKeptOnceTwoColumnsAreBehindIt) {
  // 3 px/s: a column every 333 ms. From the third column on, every interior event has p − d and p − 2d on exact
  // lines behind it (and, along the edge, the rows above it at the same time).
  Significance f(kDavis346, at_rate(1.0));
  const auto ev = edge(3.0, 50, 5, 80, 10, 1'000'000);
  int kept_late = 0;
  int late = 0;
  for (std::size_t i = 0; i < ev.size(); ++i) {
    const bool k = f.accept(ev[i]);
    if (i == 0) {
      EXPECT_FALSE(k);  // no history at all
    }
    if (ev[i].x >= 52 && ev[i].y >= 82 && ev[i].y <= 87) {
      ++late;
      kept_late += k ? 1 : 0;
    }
  }
  EXPECT_EQ(kept_late, late);
}

TEST(Significance, SlowEdgeNeedsPolarityAndTiming) {
  // Two columns of a 3 px/s edge, then one event of the third column: kept when the lines through it are exact
  // (same polarity, times t − s and t − 2s); dropped when the middle column has the other polarity or is 80 ms
  // off (tolerance at s = 333 ms: 2 ms + 0.1 · 333 ms = 35 ms).
  for (const int variant : {0, 1, 2}) {
    Significance f(kDavis346, at_rate(1.0));
    auto ev = edge(3.0, 50, 2, 80, 10, 1'000'000);
    for (auto& e : ev) {
      if (e.x == 51 && variant == 1) e.polarity = false;
      if (e.x == 51 && variant == 2) e.t_us += 80'000;
    }
    for (const auto& e : ev) (void)f.accept(e);
    const bool kept = f.accept({1'000'000 + 666'667, 52, 84, true});
    EXPECT_EQ(kept, variant == 0) << "variant " << variant;
  }
}

TEST(Significance, HotPixelNeitherPassesNorSupports) {
  // A pixel firing at 200 Hz: its own events never support it, and one pixel cannot make a line for a neighbour.
  Significance f(kDavis346, at_rate(1.0));
  int kept = 0;
  for (int i = 0; i < 400; ++i) {
    kept += f.accept({1'000'000 + i * 5'000, 200, 150, i % 2 == 0}) ? 1 : 0;
  }
  EXPECT_EQ(kept, 0);
  EXPECT_FALSE(f.accept({3'001'000, 201, 150, true}));
  EXPECT_FALSE(f.accept({3'002'000, 202, 150, true}));
}

TEST(Significance, BurstAtOnePixelIsNotSupport) {
  // A burst of 8 events at one pixel (refractory-free flicker) followed by an event beside it.
  Significance f(kDavis346, at_rate(5.0));
  for (int i = 0; i < 8; ++i) {
    EXPECT_FALSE(f.accept({1'000'000 + i * 10, 60, 60, true}));
  }
  EXPECT_FALSE(f.accept({1'000'200, 61, 60, true}));
}

TEST(Significance, FastEdgeIsKept) {
  Significance f(kDavis346, at_rate(10.0));
  const auto ev = edge(200.0, 20, 20, 100, 20, 1'000'000);
  int kept = 0;
  for (const auto& e : ev) kept += f.accept(e) ? 1 : 0;
  // All but the first two columns (no history) and the border rows.
  EXPECT_GE(kept, 18 * 18);
}

TEST(Significance, ThresholdsFollowTheNoiseModel) {
  Significance f(kDavis346, at_rate(1.0));
  const auto low = f.line_thresholds_us();
  f.set_rate(10.0);
  const auto high = f.line_thresholds_us();
  for (std::size_t m = 0; m < 8; ++m) {
    EXPECT_LE(high[m], low[m]);  // more noise: shorter ages needed
    if (m > 0) {
      EXPECT_GE(low[m], low[m - 1]);
    }
  }
  EXPECT_LE(low[7], 500'000);  // capped at 1 / slowest speed
  // Recency test off by default; with a cap, its thresholds are at most the cap.
  SignificanceOptions o = at_rate(1.0);
  o.recency_max_us = 20'000;
  Significance g(kDavis346, o);
  for (const auto a : g.recency_thresholds_us()) EXPECT_LE(a, 20'000);
  EXPECT_GT(g.recency_thresholds_us()[7], 0);
}

TEST(Significance, RecencyTermKeepsDenseSupport) {
  SignificanceOptions o = at_rate(1.0);
  o.recency_max_us = 20'000;
  o.edge_line = false;
  Significance f(kDavis346, o);
  // All 8 neighbours fired within the last millisecond (different polarities, no line): improbable for noise.
  std::int64_t t = 1'000'000;
  for (const auto& [dx, dy] : {std::pair{-1, -1}, {0, -1}, {1, -1}, {-1, 0}, {1, 0}, {-1, 1}, {0, 1}, {1, 1}}) {
    (void)f.accept({t, static_cast<std::uint16_t>(100 + dx), static_cast<std::uint16_t>(100 + dy), (dx + dy) % 2 == 0});
    t += 100;
  }
  EXPECT_TRUE(f.accept({t, 100, 100, true}));
}

TEST(Significance, RateEstimateAndFalseAlarmsOnPureNoise) {
  // Uniform BA at 5 Hz/px over 2 s: the estimate converges to 5 and at most ~alpha of the events pass.
  const double rate = 5.0;
  const std::vector<Event> ev = pure_noise(rate, 2'000'000, 7);
  const std::size_t n = ev.size();
  SignificanceOptions o;
  Significance f(kDavis346, o);
  std::size_t kept = 0;
  for (const auto& e : ev) kept += f.accept(e) ? 1 : 0;
  EXPECT_NEAR(f.rate_hz(), rate, 0.5);
  EXPECT_LE(static_cast<double>(kept), 2.0 * o.alpha * static_cast<double>(n) + 10.0);
}

// r0 = lambda·exp(−8·lambda·T0) has two roots lambda_1 <= 12.5 Hz/px <= lambda_2; the share at T1 = 1 ms and the
// whole event rate pick the right one. Before, the smaller was always taken: 130 Hz/px of noise read as 0.08 Hz/px
// and the filter kept 83 % of it (tools/bench_pipeline.py's high-rate stream, docs/history.md).
TEST(Significance, RateEstimatePicksTheRootTheNoiseGives) {
  for (const double lambda : {0.1, 1.0, 5.0, 10.0, 20.0, 60.0, 130.0, 300.0}) {
    const double r0 = lambda * std::exp(-8.0 * lambda * 0.010);
    const double r1 = lambda * std::exp(-8.0 * lambda * 0.001);
    EXPECT_NEAR(Significance::rate_from_zero_support(r0, r1, lambda, 1e4), lambda, 1e-6 * lambda) << lambda << " Hz/px";
  }
  // Low noise under a busy scene: many signal events have neighbours 1-10 ms old (r1 >> r0), but the whole rate is
  // below 12.5 Hz/px, so the large root is impossible; and one above it but below the large root the same.
  EXPECT_NEAR(Significance::rate_from_zero_support(0.5, 5.0, 10.0, 1e4), 0.52, 0.01);
  EXPECT_NEAR(Significance::rate_from_zero_support(0.5, 5.0, 40.0, 1e4), 0.52, 0.01);
  EXPECT_EQ(Significance::rate_from_zero_support(0.0, 0.0, 0.0, 0.0), 0.0);
}

TEST(Significance, HeavyNoiseIsEstimatedAndRemoved) {
  // Uniform BA at 100 Hz/px over 0.5 s (4.5 M events): the estimate reaches 100 and at most ~alpha pass after it.
  const double rate = 100.0;
  const std::vector<Event> ev = pure_noise(rate, 500'000, 11);
  SignificanceOptions o;
  o.lookahead_us = 0;
  Significance f(kDavis346, o);
  std::size_t kept_late = 0, late = 0;
  for (const auto& e : ev) {
    const bool k = f.accept(e);
    if (e.t_us >= 250'000) {
      ++late;
      kept_late += k ? 1 : 0;
    }
  }
  EXPECT_NEAR(f.rate_hz(), rate, 10.0);
  EXPECT_LE(static_cast<double>(kept_late), 2.0 * o.alpha * static_cast<double>(late) + 10.0);
}

// From the very first event: no period has measured the rate yet (none can count zero-support events before T0), so
// the filter assumes the larger of initial_rate_hz and the whole event rate so far. Before, the first period read as
// 0 Hz/px and the second ran with the loosest thresholds: 130 Hz/px of noise from the start kept 75 000 of the first
// 30 ms's 350 000 events (tools/bench_pipeline.py's high-rate stream).
TEST(Significance, HeavyNoiseFromTheFirstEventIsRemoved) {
  const std::vector<Event> ev = pure_noise(130.0, 60'000, 13);
  const double bound = 2.0 * SignificanceOptions{}.alpha * static_cast<double>(ev.size()) + 10.0;
  for (const std::int64_t lookahead_us : {std::int64_t{0}, SignificanceOptions{}.lookahead_us}) {
    auto f = make_filter("significance", {{"lookahead_us", std::to_string(lookahead_us)}}, kDavis346);
    const auto d = run_filter(*f, ev);
    EXPECT_LE(static_cast<double>(count_kept(d)), bound) << "lookahead_us " << lookahead_us;
  }
}

TEST(Significance, StreamEqualsBatchAndSurvivesARebase) {
  std::mt19937_64 rng(3);
  std::vector<Event> ev;
  // Noise plus an edge, then a jump of 10 minutes (forces a rebase of the 32-bit times), then the same again.
  for (const std::int64_t base : {std::int64_t{0}, std::int64_t{600'000'000}}) {
    auto e = edge(40.0, 30, 30, 40, 30, base + 100'000);
    std::uniform_int_distribution<int> x(0, 345), y(0, 259);
    std::uniform_int_distribution<std::int64_t> t(base, base + 1'000'000);
    for (int i = 0; i < 50'000; ++i) {
      e.push_back({t(rng), static_cast<std::uint16_t>(x(rng)), static_cast<std::uint16_t>(y(rng)), i % 3 == 0});
    }
    std::sort(e.begin(), e.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
    ev.insert(ev.end(), e.begin(), e.end());
  }
  auto batch = make_filter("significance", {}, kDavis346);
  auto stream = make_filter("significance", {}, kDavis346);
  const auto a = run_filter(*batch, ev);
  const auto b = run_filter(*stream, ev, 777);
  EXPECT_EQ(a.keep, b.keep);
  EXPECT_EQ(a.score, b.score);
  EXPECT_GT(count_kept(a), 1000U);  // the edges survive, after the jump too
  std::size_t late = 0;
  for (std::size_t i = ev.size() / 2; i < ev.size(); ++i) late += a.keep[i];
  EXPECT_GT(late, 500U);
}

using Settings = std::vector<std::pair<std::string, std::string>>;

/// Decisions and scores of the filter with the edge-line kernel EVPIPE_SIGNIFICANCE_KERNEL names ("" = the CPU's).
Decisions run_kernel(const std::string& kernel, const Settings& settings, const std::vector<Event>& ev) {
  if (kernel.empty()) {
    unsetenv("EVPIPE_SIGNIFICANCE_KERNEL");
  } else {
    setenv("EVPIPE_SIGNIFICANCE_KERNEL", kernel.c_str(), 1);
  }
  auto f = make_filter("significance", settings, kDavis346);
  unsetenv("EVPIPE_SIGNIFICANCE_KERNEL");
  return run_filter(*f, ev, 1000);
}

TEST(Significance, VectorKernelsDecideAndScoreExactlyAsTheScalarWalk) {
  // Noise at 1-20 Hz/px, edges of both polarities at 3-400 px/s in several directions, bursts of equal
  // timestamps, and a 10-minute jump (a rebase): every kernel must give the scalar walk's decisions and the same
  // score bits, for several option sets.
  std::mt19937_64 rng(11);
  std::vector<Event> ev;
  std::int64_t base = 0;
  for (const double rate : {1.0, 20.0, 5.0}) {
    std::vector<Event> part;
    for (const double speed : {3.0, 15.0, 60.0, 400.0}) {
      auto e =
          edge(speed, 20 + static_cast<int>(speed) % 200, 40, 30 + static_cast<int>(speed) % 150, 20, base + 10'000);
      for (auto& x : e) x.polarity = speed > 20.0;
      part.insert(part.end(), e.begin(), e.end());
    }
    const auto n = static_cast<std::size_t>(rate * 346 * 260 * 0.4);
    std::uniform_int_distribution<int> x(0, 345), y(0, 259);
    std::uniform_int_distribution<std::int64_t> t(base, base + 400'000);
    for (std::size_t i = 0; i < n; ++i) {
      const Event e{t(rng), static_cast<std::uint16_t>(x(rng)), static_cast<std::uint16_t>(y(rng)), i % 2 == 0};
      part.push_back(e);
      if (i % 97 == 0) part.push_back({e.t_us, e.x, static_cast<std::uint16_t>((e.y + 1) % 260), e.polarity});
    }
    std::sort(part.begin(), part.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
    ev.insert(ev.end(), part.begin(), part.end());
    base += rate == 20.0 ? 600'000'000 : 500'000;
  }
  const std::vector<Settings> option_sets = {
      {},
      {{"slowest_speed_px_s", "0.5"}, {"edge_precision_px", "0.5"}, {"timing_jitter_us", "500"}},
      {{"edge_precision_px", "0"}, {"timing_jitter_us", "0"}},
      {{"recency_max_us", "20000"}, {"alpha", "0.01"}},
      {{"rate_period_us", "1000000000"}, {"initial_rate_hz", "0.5"}},
  };
  for (const auto& settings : option_sets) {
    const Decisions ref = run_kernel("scalar", settings, ev);
    ASSERT_EQ(ref.size(), ev.size());
    EXPECT_GT(count_kept(ref), 1000U);
    for (const std::string kernel : {"sse4", ""}) {
      const Decisions d = run_kernel(kernel, settings, ev);
      EXPECT_EQ(d.keep, ref.keep) << "kernel '" << kernel << "'";
      ASSERT_EQ(d.score.size(), ref.score.size());
      EXPECT_EQ(std::memcmp(d.score.data(), ref.score.data(), d.score.size() * sizeof(float)), 0)
          << "kernel '" << kernel << "'";
    }
  }
}

TEST(Significance, VectorKernelsKeepTheWalksRunningLowerBound) {
  // The scalar walk's second pointer never moves back: an entry of p − 2d skipped as too young for a newer entry
  // of p − d is not reconsidered for an older one. The lower bound (2 − ε)s − δ₀ = 2s − (int)(ε·s) only decreases
  // with s through float rounding, beyond 2^25 µs with ε = 1: find such an s, put entries of p − d at ages s and
  // s + 1, one of p − 2d at the lower bound for s + 1 (below the one for s), and the walk finds no line there.
  const auto lower = [](std::int32_t age) {
    return 2 * age - static_cast<std::int32_t>(1.0F * static_cast<float>(age));
  };
  std::int32_t s = std::int32_t{1} << 25;
  while (lower(s) <= lower(s + 1)) ++s;
  ASSERT_LT(s, (std::int32_t{1} << 25) + 1000);
  const std::int64_t t = 200'000'000;
  const std::uint16_t x = 100;
  const std::uint16_t y = 100;
  std::vector<Event> ev = {{t - s - 1, x - 1, y, true},         // p − d, age s + 1
                           {t - s, x - 1, y, true},             // p − d, age s
                           {t - lower(s + 1), x - 2, y, true},  // p − 2d
                           {t, x, y, true}};                    // p
  std::sort(ev.begin(), ev.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  const Settings settings = {{"initial_rate_hz", "0"},
                             {"rate_period_us", "1000000000"},
                             {"slowest_speed_px_s", "0.01"},
                             {"edge_precision_px", "1"},
                             {"timing_jitter_us", "0"}};
  const Decisions ref = run_kernel("scalar", settings, ev);
  ASSERT_EQ(ref.size(), 4U);
  EXPECT_EQ(ref.keep[3], 0);
  for (const std::string kernel : {"sse4", ""}) {
    const Decisions d = run_kernel(kernel, settings, ev);
    EXPECT_EQ(d.keep, ref.keep) << "kernel '" << kernel << "'";
    EXPECT_EQ(d.score, ref.score) << "kernel '" << kernel << "'";
  }
}

// --- The joint (look-ahead) edge-line test -------------------------------------------------------------------------

std::unique_ptr<Filter> lookahead_filter(double rate_hz, std::int64_t lookahead_us) {
  SignificanceOptions o = at_rate(rate_hz);
  o.lookahead_us = lookahead_us;
  return make_significance(kDavis346, o);
}

TEST(SignificanceLookahead, EdgeEnteringWithNoHistoryIsKept) {
  // A slightly tilted 120 px/s edge entering the view at column 50: column c, row r fires at c / 120 s + r · 3 ms.
  // At 5 Hz/px one past line (along the edge, 3 ms) is not enough (U_1 < 1 ms) and column 51 has no second one, so
  // the causal test drops it; with the 20 ms look-ahead the lines ahead (along the row, along the edge) join.
  std::vector<Event> ev;
  for (int c = 0; c < 6; ++c) {
    for (int r = 0; r < 10; ++r) {
      ev.push_back({1'000'000 + std::llround(c / 120.0 * 1e6) + r * 3'000, static_cast<std::uint16_t>(50 + c),
                    static_cast<std::uint16_t>(80 + r), true});
    }
  }
  std::stable_sort(ev.begin(), ev.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  const auto causal = run_filter(*lookahead_filter(5.0, 0), ev);
  const auto ahead = run_filter(*lookahead_filter(5.0, 20'000), ev);
  ASSERT_EQ(ahead.size(), ev.size());
  int entering_causal = 0;
  int entering_ahead = 0;
  for (std::size_t i = 0; i < ev.size(); ++i) {
    if (ev[i].x == 51 && ev[i].y >= 82 && ev[i].y <= 87) {
      entering_causal += causal.keep[i];
      entering_ahead += ahead.keep[i];
    }
    if (causal.keep[i] != 0) {
      EXPECT_EQ(ahead.keep[i], 1);  // the causal decisions stand
    }
    if (ahead.keep[i] != 0) {
      EXPECT_GE(ahead.score[i], 1.0F);
    }
  }
  EXPECT_EQ(entering_causal, 0);
  EXPECT_EQ(entering_ahead, 6);
  EXPECT_GT(count_kept(ahead), count_kept(causal));
}

TEST(SignificanceLookahead, CornerWithOneLineBehindAndOneAheadIsKept) {
  // One row of a 120 px/s edge (one line through each pixel along the row): at 5 Hz/px one past line at 8.3 ms is
  // not enough (U_1 < 1 ms), one past + one future line is (V_2 > 8.3 ms).
  SignificanceOptions o = at_rate(5.0);
  const Significance probe(kDavis346, o);
  ASSERT_LT(probe.line_thresholds_us()[0], 8'333);
  ASSERT_GT(probe.joint_thresholds_us()[1], 8'334);
  const auto ev = edge(120.0, 50, 6, 80, 1, 1'000'000);
  const auto causal = run_filter(*lookahead_filter(5.0, 0), ev);
  const auto ahead = run_filter(*lookahead_filter(5.0, 20'000), ev);
  EXPECT_EQ(count_kept(causal), 0U);
  // Column 52 (2 behind, 2 ahead) and 53 (3 behind, 2 ahead: 16.7 ms ahead is within L); 50/51 have one line at most.
  EXPECT_EQ(ahead.keep, (std::vector<std::uint8_t>{0, 0, 1, 1, 0, 0}));
}

TEST(SignificanceLookahead, IsolatedHotPixelAndBurstAreDropped) {
  std::vector<Event> ev;
  ev.push_back({1'000'000, 100, 100, true});                                                  // isolated
  for (int i = 0; i < 400; ++i) ev.push_back({1'100'000 + i * 5'000, 200, 150, i % 2 == 0});  // hot pixel
  for (int i = 0; i < 8; ++i) ev.push_back({3'200'000 + i * 10, 60, 60, true});               // burst
  ev.push_back({3'200'200, 61, 60, true});
  ev.push_back({3'200'300, 201, 150, true});  // beside the hot pixel
  std::sort(ev.begin(), ev.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  const auto d = run_filter(*lookahead_filter(5.0, 20'000), ev);
  EXPECT_EQ(count_kept(d), 0U);
}

TEST(SignificanceLookahead, SlowEdgeKeptAsByTheCausalTest) {
  const auto ev = edge(3.0, 50, 5, 80, 10, 1'000'000);
  const auto causal = run_filter(*lookahead_filter(1.0, 0), ev);
  const auto ahead = run_filter(*lookahead_filter(1.0, 20'000), ev);
  for (std::size_t i = 0; i < ev.size(); ++i) {
    if (causal.keep[i] != 0) {
      EXPECT_EQ(ahead.keep[i], 1);
    }
  }
  EXPECT_GE(count_kept(ahead), count_kept(causal));
  EXPECT_GT(count_kept(causal), 20U);
}

TEST(SignificanceLookahead, DecidesWithinTheLookaheadAndStreamEqualsBatch) {
  std::mt19937_64 rng(11);
  auto ev = edge(120.0, 30, 60, 40, 40, 100'000);
  const auto e2 = edge(60.0, 200, 30, 150, 20, 300'000);
  ev.insert(ev.end(), e2.begin(), e2.end());
  std::uniform_int_distribution<int> x(0, 345), y(0, 259);
  std::uniform_int_distribution<std::int64_t> t(0, 1'000'000);
  for (int i = 0; i < 60'000; ++i) {
    ev.push_back({t(rng), static_cast<std::uint16_t>(x(rng)), static_cast<std::uint16_t>(y(rng)), i % 2 == 0});
  }
  std::stable_sort(ev.begin(), ev.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  auto batch = make_filter("significance", {}, kDavis346);
  EXPECT_EQ(batch->latency_us(), 20'000);
  const auto a = run_filter(*batch, ev);
  for (const std::size_t chunk : {std::size_t{1}, std::size_t{7}, std::size_t{1000}}) {
    auto stream = make_filter("significance", {}, kDavis346);
    const auto b = run_filter(*stream, ev, chunk);
    EXPECT_EQ(a.keep, b.keep) << chunk;
    EXPECT_EQ(a.score, b.score) << chunk;
  }
  // Pushed one at a time, an event is decided once an event later than its t + L arrives: never more than L waits.
  auto live = make_filter("significance", {}, kDavis346);
  Decisions d;
  for (std::size_t i = 0; i < ev.size(); ++i) {
    live->push(EventSpan(&ev[i], 1), d);
    const std::size_t waiting = i + 1 - d.size();
    if (waiting > 0) {
      EXPECT_LE(ev[i].t_us - ev[d.size()].t_us, 20'000) << i;
    }
    EXPECT_EQ(waiting, live->pending());
  }
  live->finish(d);
  EXPECT_EQ(d.keep, a.keep);
  EXPECT_GT(count_kept(a), 2000U);
}

TEST(SignificanceLookahead, CausalOptionIsTheCausalTestAlone) {
  std::mt19937_64 rng(5);
  auto ev = edge(120.0, 30, 60, 40, 40, 100'000);
  std::uniform_int_distribution<int> x(0, 345), y(0, 259);
  std::uniform_int_distribution<std::int64_t> t(0, 1'000'000);
  for (int i = 0; i < 30'000; ++i) {
    ev.push_back({t(rng), static_cast<std::uint16_t>(x(rng)), static_cast<std::uint16_t>(y(rng)), i % 2 == 0});
  }
  std::stable_sort(ev.begin(), ev.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  // The causal filter runs the edge-surface test at once (surface=false: the causal edge-line test alone).
  auto causal = make_filter("significance", {{"lookahead_us", "0"}, {"surface", "false"}}, kDavis346);
  EXPECT_EQ(causal->latency_us(), 0);
  const auto d = run_filter(*causal, ev);
  SignificanceOptions o;
  o.lookahead_us = 20'000;  // the causal test's thresholds do not depend on whether the look-ahead runs
  Significance f(kDavis346, o);
  for (std::size_t i = 0; i < ev.size(); ++i) ASSERT_EQ(d.keep[i], f.accept(ev[i]) ? 1 : 0) << i;
  // With the edge-surface test (the default) it keeps the same events and more: the edge-line thresholds do not
  // depend on it, and it only adds kept events.
  auto with_surface = make_filter("significance", {{"lookahead_us", "0"}}, kDavis346);
  const auto s = run_filter(*with_surface, ev);
  for (std::size_t i = 0; i < ev.size(); ++i) {
    if (d.keep[i] != 0) {
      ASSERT_EQ(s.keep[i], 1) << i;
    }
  }
}

TEST(SignificanceLookahead, JointThresholdsFollowTheNoiseModel) {
  SignificanceOptions o = at_rate(1.0);
  Significance f(kDavis346, o);
  const auto low = f.joint_thresholds_us();
  f.set_rate(10.0);
  const auto high = f.joint_thresholds_us();
  for (std::size_t m = 0; m < 16; ++m) {
    EXPECT_LE(high[m], low[m]);
    EXPECT_LE(low[m], 500'000);
    if (m > 0) {
      EXPECT_GE(low[m], low[m - 1]);
    }
    if (m < 8) {
      EXPECT_LE(high[m], f.line_thresholds_us()[m]);  // 16 half-lines: stricter than 8 for the same m
    }
  }
  o.lookahead_us = 0;
  const Significance g(kDavis346, o);
  for (const auto v : g.joint_thresholds_us()) EXPECT_EQ(v, 0);
}

TEST(SignificanceLookahead, FalseAlarmsOnPureNoise) {
  const double rate = 5.0;
  const std::vector<Event> ev = pure_noise(rate, 2'000'000, 9);
  const std::size_t n = ev.size();
  auto f = make_filter("significance", {}, kDavis346);
  const auto d = run_filter(*f, ev);
  EXPECT_LE(static_cast<double>(count_kept(d)), 2.0 * SignificanceOptions{}.alpha * static_cast<double>(n) + 10.0);
}

TEST(SignificanceLookahead, BoundDecidesAsTheFullJointTest) {
  // exact_scores = false: a pending event the 3x3 bound (Significance::joint_may_pass) rejects is dropped without the
  // full future walk. The decisions must be those of the full joint test, with every kernel, from 5 to 130 Hz/px
  // (where the bound drops most events) with edges at 3-400 px/s of both polarities; a kept event keeps its score,
  // a dropped one at most its exact score (the causal one).
  std::vector<Event> ev;
  std::int64_t base = 0;
  std::uint64_t seed = 21;
  for (const double rate : {5.0, 130.0, 20.0}) {
    auto part = pure_noise(rate, rate > 100.0 ? 60'000 : 300'000, seed++);
    for (auto& e : part) e.t_us += base;
    for (const double speed : {3.0, 15.0, 60.0, 400.0}) {
      auto e =
          edge(speed, 20 + static_cast<int>(speed) % 200, 30, 30 + static_cast<int>(speed) % 150, 20, base + 5'000);
      for (auto& x : e) x.polarity = speed > 20.0;
      part.insert(part.end(), e.begin(), e.end());
    }
    std::stable_sort(part.begin(), part.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
    base = part.back().t_us + 1;
    ev.insert(ev.end(), part.begin(), part.end());
  }
  for (const std::string kernel : {"scalar", "sse4", ""}) {
    const Decisions exact = run_kernel(kernel, {{"initial_rate_hz", "5"}}, ev);
    const Decisions bound = run_kernel(kernel, {{"initial_rate_hz", "5"}, {"exact_scores", "false"}}, ev);
    ASSERT_EQ(bound.size(), ev.size());
    EXPECT_EQ(bound.keep, exact.keep) << "kernel '" << kernel << "'";
    EXPECT_GT(count_kept(exact), 1000U);
    ASSERT_EQ(bound.score.size(), exact.score.size());
    std::size_t lower = 0;
    for (std::size_t i = 0; i < ev.size(); ++i) {
      if (exact.keep[i] != 0) {
        EXPECT_EQ(bound.score[i], exact.score[i]) << i;
      } else {
        EXPECT_LE(bound.score[i], exact.score[i]) << i;
        lower += bound.score[i] < exact.score[i] ? 1 : 0;
      }
    }
    EXPECT_GT(lower, 0U);  // the bound did drop events without their joint margin
  }
  // It drops most events at 130 Hz/px (~90 %): the count is in the filter's report.
  auto f = make_filter("significance", {{"initial_rate_hz", "130"}, {"exact_scores", "false"}}, kDavis346);
  const auto noise = pure_noise(130.0, 60'000, 5);
  (void)run_filter(*f, noise);
  double drops = 0.0;
  for (const auto& r : f->report())
    if (r.key == "lookahead_bound_drops") drops = r.value;
  EXPECT_GT(drops, 0.8 * static_cast<double>(noise.size()));
}

// --- The edge-surface test ----------------------------------------------------------------------------------------

/// A slow, tilted edge: pixel (x, y) fires at t0 + gx·(x − x0) + gy·(y − y0) (gx, gy in s/px), polarity on; the
/// pixels with x0 − 2 <= x <= x0 + 2, y0 − 2 <= y <= y0 + 2 that fire in [t0 − T, t0) (T = 0.5 s), time-sorted.
std::vector<Event> tilted_block(int x0, int y0, std::int64_t t0_us, double gx, double gy) {
  std::vector<Event> ev;
  for (int dy = -2; dy <= 2; ++dy) {
    for (int dx = -2; dx <= 2; ++dx) {
      const double tau = gx * dx + gy * dy;
      if (tau >= 0.0 || tau < -0.5) continue;
      ev.push_back({t0_us + std::llround(tau * 1e6), static_cast<std::uint16_t>(x0 + dx),
                    static_cast<std::uint16_t>(y0 + dy), true});
    }
  }
  std::sort(ev.begin(), ev.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  return ev;
}

TEST(SignificanceSurface, SlowEdgeTheLinesMissIsKeptOnTheKeptEventsPlane) {
  // A 3.3 px/s edge (0.3 s/px along x), tilted (0.1 s/px along y), at 2 Hz/px: the event at (100, 100) has two
  // lines behind it at 0.1 s and 0.2 s (along the edge, across it), above U_1 and U_2, so the edge-line test drops
  // it. Its 9 predecessors in the 5×5 block were kept (e.g. by the edge-line test when they had more support): the
  // plane through them predicts the event's 9 slots, all filled; under 2 Hz/px that is P(Poisson(~0.5) >= 9) ~ 1e-9.
  SignificanceOptions o = at_rate(2.0);
  o.lookahead_us = 0;
  Significance f(kDavis346, o);
  ASSERT_LT(f.line_thresholds_us()[1], 200'000);
  const auto block = tilted_block(100, 100, 2'000'000, 0.3, 0.1);
  ASSERT_EQ(block.size(), 9U);
  for (const auto& e : block) {
    (void)f.accept(e);
    f.mark_kept(e);
  }
  const Event on{2'000'000, 100, 100, true};
  EXPECT_GE(f.surface_ratio(on, 0), 1.0F);
  // Off the plane by 50 ms (slot tolerance at 0.1 s: 12 ms): not kept; the other polarity: not kept.
  EXPECT_LT(f.surface_ratio({2'050'000, 100, 100, true}, 0), 1.0F);
  EXPECT_LT(f.surface_ratio({1'950'000, 100, 100, true}, 0), 1.0F);
  EXPECT_LT(f.surface_ratio({2'000'000, 100, 100, false}, 0), 1.0F);
  // The same block, but nothing kept: no motion prior, no decision from this test.
  Significance g(kDavis346, o);
  for (const auto& e : block) (void)g.accept(e);
  EXPECT_EQ(g.surface_ratio(on, 0), 0.0F);
  // Without the surface test the event is dropped; with it (causal filter: at once) kept.
  SignificanceOptions no = o;
  no.surface = false;
  Significance lines_only(kDavis346, no);
  for (const auto& e : block) (void)lines_only.accept(e);
  EXPECT_FALSE(lines_only.accept(on));
  EXPECT_TRUE(f.accept(on));
  EXPECT_GE(f.last_score(), 1.0F);
}

TEST(SignificanceSurface, IsolatedEventAndHotPixelAreNotPromoted) {
  SignificanceOptions o = at_rate(1.0);
  o.lookahead_us = 0;
  Significance f(kDavis346, o);
  EXPECT_FALSE(f.accept({1'000'000, 100, 100, true}));
  EXPECT_EQ(f.surface_ratio({1'000'000, 100, 100, true}, 0), 0.0F);
  // A hot pixel's own kept events never support it (own pixel excluded from the prior and the slots).
  for (int i = 0; i < 50; ++i) {
    const Event e{2'000'000 + i * 10'000, 200, 150, true};
    f.mark_kept(e);
    EXPECT_FALSE(f.accept(e)) << i;
  }
}

TEST(SignificanceSurface, FalseAlarmRateHonouredOnPureNoise) {
  // Pure BA at 5 Hz/px over 2 s: what the edge-surface test adds is at most its share of alpha (alpha / 4 with
  // the look-ahead, alpha / 2 causal), with a margin for the count's spread.
  const double rate = 5.0;
  const std::vector<Event> ev = pure_noise(rate, 2'000'000, 21);
  const auto n = static_cast<double>(ev.size());
  const double alpha = SignificanceOptions{}.alpha;
  for (const std::string lookahead : {"20000", "0"}) {
    auto f = make_filter("significance", {{"lookahead_us", lookahead}}, kDavis346);
    const auto d = run_filter(*f, ev);
    double surface = -1.0;
    for (const auto& item : f->report()) {
      if (item.key == "kept_surface") surface = item.value;
    }
    ASSERT_GE(surface, 0.0) << lookahead;
    const double share = lookahead == "0" ? alpha / 2 : alpha / 4;
    EXPECT_LE(surface, 2.0 * share * n + 5.0) << lookahead;
    EXPECT_LE(static_cast<double>(count_kept(d)), 2.0 * alpha * n + 10.0) << lookahead;
  }
}

TEST(SignificanceSurface, SlowTiltedEdgeInNoiseStreamEqualsBatch) {
  // A 5 px/s edge tilted 0.2 rad (pixel (x, y) fires at (x − 0.2·y) / 5 s), 60 rows × 8 columns, in 3 Hz/px of BA
  // around it: the surface test keeps part of what the edge-line and joint tests drop, and its decisions do not
  // depend on how the stream is pushed.
  std::mt19937_64 rng(31);
  std::vector<Event> ev;
  for (int y = 60; y < 120; ++y) {
    for (int x = 100; x < 108; ++x) {
      const double t_s = 0.2 + ((x - 100) + 0.2 * (y - 60)) / 5.0;
      ev.push_back({std::llround(t_s * 1e6), static_cast<std::uint16_t>(x), static_cast<std::uint16_t>(y), true});
    }
  }
  const std::size_t signal = ev.size();
  std::uniform_int_distribution<int> x(80, 130), y(40, 140);
  std::uniform_int_distribution<std::int64_t> t(0, 5'000'000);
  const int noise = static_cast<int>(3.0 * 51 * 101 * 5.0);
  for (int i = 0; i < noise; ++i) {
    ev.push_back({t(rng), static_cast<std::uint16_t>(x(rng)), static_cast<std::uint16_t>(y(rng)), i % 2 == 0});
  }
  std::vector<std::uint8_t> is_signal(ev.size(), 0);
  std::fill(is_signal.begin(), is_signal.begin() + static_cast<std::ptrdiff_t>(signal), 1);
  std::vector<std::size_t> order(ev.size());
  for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return ev[a].t_us < ev[b].t_us; });
  std::vector<Event> sorted;
  std::vector<std::uint8_t> label;
  for (const std::size_t i : order) {
    sorted.push_back(ev[i]);
    label.push_back(is_signal[i]);
  }
  const Settings rate = {{"initial_rate_hz", "3"}, {"rate_period_us", "1000000000"}};
  auto batch = make_filter("significance", rate, kDavis346);
  const auto a = run_filter(*batch, sorted);
  for (const std::size_t chunk : {std::size_t{1}, std::size_t{7}, std::size_t{1000}}) {
    auto stream = make_filter("significance", rate, kDavis346);
    const auto b = run_filter(*stream, sorted, chunk);
    EXPECT_EQ(a.keep, b.keep) << chunk;
    EXPECT_EQ(a.score, b.score) << chunk;
  }
  Settings off = rate;
  off.emplace_back("surface", "false");
  auto lines = make_filter("significance", off, kDavis346);
  const auto c = run_filter(*lines, sorted);
  std::size_t kept_with = 0, kept_without = 0, noise_with = 0, noise_without = 0;
  for (std::size_t i = 0; i < sorted.size(); ++i) {
    (label[i] != 0 ? kept_with : noise_with) += a.keep[i];
    (label[i] != 0 ? kept_without : noise_without) += c.keep[i];
  }
  double surface = 0.0;
  for (const auto& item : batch->report()) {
    if (item.key == "kept_surface") surface = item.value;
  }
  EXPECT_GT(surface, 0.0);
  EXPECT_GT(kept_with, kept_without);
  // What it adds is mostly signal: the noise it keeps lies on the edge's surface (within the slot tolerance of the
  // crossing; measured +31 signal, +9 noise of 77 000).
  EXPECT_LT(2 * (noise_with - std::min(noise_with, noise_without)), kept_with - kept_without);
}

TEST(SignificanceSurface, EveryKernelScansTheKeptBlockAsTheScalarScan) {
  // The edge-surface test's scan of the 5×5 kept block (scalar, or AVX2 with per-lane plane sums) must give the same
  // plane, decisions and score bits: slow tilted edges of both polarities in 3 Hz/px of BA (the test keeps events
  // there), then the same at 130 Hz/px (it fits planes and rejects), with and without exact scores.
  std::mt19937_64 rng(41);
  std::vector<Event> ev;
  std::int64_t base = 0;
  for (const double rate : {3.0, 130.0}) {
    std::vector<Event> part;
    const std::int64_t span_us = rate > 100.0 ? 150'000 : 2'000'000;
    for (int k = 0; k < 4; ++k) {
      const double speed = 3.0 + 4.0 * k;  // px/s
      const double tilt = 0.1 * (k - 1.5);
      const int x0 = 40 + 70 * k;
      for (int y = 50; y < 110; ++y) {
        for (int x = x0; x < x0 + 8; ++x) {
          const double t_s = 0.05 + ((x - x0) + tilt * (y - 50)) / speed;
          const auto t = base + std::llround(t_s * 1e6);
          if (t < base || t > base + span_us) continue;
          part.push_back({t, static_cast<std::uint16_t>(x), static_cast<std::uint16_t>(y), k % 2 == 0});
        }
      }
    }
    const auto n = static_cast<std::size_t>(rate * 346 * 120 * static_cast<double>(span_us) * 1e-6);
    std::uniform_int_distribution<int> x(0, 345), y(20, 139);
    std::uniform_int_distribution<std::int64_t> t(base, base + span_us);
    for (std::size_t i = 0; i < n; ++i) {
      part.push_back({t(rng), static_cast<std::uint16_t>(x(rng)), static_cast<std::uint16_t>(y(rng)), i % 2 == 0});
    }
    std::stable_sort(part.begin(), part.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
    base = part.back().t_us + 1;
    ev.insert(ev.end(), part.begin(), part.end());
  }
  for (const std::string exact : {"true", "false"}) {
    const Settings settings = {{"initial_rate_hz", "3"}, {"exact_scores", exact}};
    const Decisions ref = run_kernel("scalar", settings, ev);
    ASSERT_EQ(ref.size(), ev.size());
    for (const std::string kernel : {"sse4", ""}) {
      const Decisions d = run_kernel(kernel, settings, ev);
      EXPECT_EQ(d.keep, ref.keep) << "kernel '" << kernel << "', exact_scores " << exact;
      ASSERT_EQ(d.score.size(), ref.score.size());
      EXPECT_EQ(std::memcmp(d.score.data(), ref.score.data(), d.score.size() * sizeof(float)), 0)
          << "kernel '" << kernel << "', exact_scores " << exact;
    }
  }
  // The edge-surface test did keep events here (what the scans must agree on).
  auto f = make_filter("significance", {{"initial_rate_hz", "3"}}, kDavis346);
  (void)run_filter(*f, ev, 1000);
  double surface = 0.0;
  for (const auto& item : f->report()) {
    if (item.key == "kept_surface") surface = item.value;
  }
  EXPECT_GT(surface, 10.0);
}

TEST(Significance, ListedWithItsParameters) {
  const FilterSpec* s = find_filter("significance");
  ASSERT_NE(s, nullptr);
  const auto params = describe(*s);
  EXPECT_TRUE(std::any_of(params.begin(), params.end(), [](const ParamInfo& p) { return p.key == "alpha"; }));
  EXPECT_THROW((void)make_filter("significance", {{"alpha", "0"}}, kDavis346), std::invalid_argument);
  EXPECT_THROW((void)make_filter("significance", {{"alpha", "0.9"}}, kDavis346), std::invalid_argument);
  EXPECT_THROW((void)make_filter("significance", {{"lookahead_us", "-1"}}, kDavis346), std::invalid_argument);
}

}  // namespace
}  // namespace evpipe::denoise
