// The paper's curvature filter end to end: exact densities on hand-made streams, singular fits, frames /
// stream / causal semantics, grid == FLANN == one batch run over the whole recording (random and real data,
// any cutting into pushes), parameters, the adaptive threshold, and the paper's Table 1 protocol.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <numeric>
#include <random>
#include <stdexcept>
#include <thread>

#include "evpipe/denoise/curvature.hpp"
#include "evpipe/denoise/registry.hpp"
#include "evpipe/denoise/selection.hpp"
#include "evpipe/io/reader.hpp"
#include "evpipe/sim/noise.hpp"
#include "evpipe/sim/recording.hpp"
#include "evpipe_test_data.hpp"
#include "rotating_bars.hpp"

namespace evpipe::denoise {
namespace {

struct Outcome {
  Decisions d;
  CurvatureTrace trace;
  std::vector<ReportItem> report;
};

double report_value(const std::vector<ReportItem>& items, std::string_view key) {
  for (const auto& i : items)
    if (i.key == key) return i.value;
  ADD_FAILURE() << "no report item " << key;
  return -1;
}

/// Runs a filter over `ev` cut into pushes by `cuts` (positions where a new push starts; empty = one push),
/// optionally split into `tasks` run by `runner`.
Outcome run(const CurvatureOptions& o, const std::vector<Event>& ev, const std::vector<std::size_t>& cuts = {},
            bool with_sites = false, int tasks = 1, const TaskRunner& runner = {}) {
  Outcome r;
  r.trace.with_sites = with_sites;
  CurvatureFilter f(o, kDavis346);
  f.set_trace(&r.trace);
  f.set_parallelism(tasks, runner);
  std::size_t start = 0;
  for (const std::size_t c : cuts) {
    f.push(EventSpan(ev).subspan(start, c - start), r.d);
    start = c;
  }
  f.push(EventSpan(ev).subspan(start), r.d);
  f.finish(r.d);
  r.report = f.report();
  return r;
}

Outcome batch(const CurvatureOptions& o, const std::vector<Event>& ev, bool with_sites = false) {
  Outcome r;
  r.trace.with_sites = with_sites;
  r.d = curvature_batch(ev, o, kDavis346, &r.trace);
  return r;
}

std::vector<std::size_t> random_cuts(std::size_t n, std::mt19937_64& rng, std::size_t max_push) {
  std::vector<std::size_t> cuts;
  std::size_t pos = 0;
  while (true) {
    pos += rng() % (max_push + 1);  // empty pushes included
    if (pos >= n) return cuts;
    cuts.push_back(pos);
  }
}

/// Pushes that each cover `hop_us` of sensor time (sliding-window feeding).
std::vector<std::size_t> time_cuts(const std::vector<Event>& ev, std::int64_t hop_us) {
  std::vector<std::size_t> cuts;
  if (ev.empty()) return cuts;
  std::int64_t next = ev.front().t_us + hop_us;
  for (std::size_t i = 0; i < ev.size(); ++i) {
    while (ev[i].t_us >= next) {
      cuts.push_back(i);
      next += hop_us;
    }
  }
  cuts.erase(std::unique(cuts.begin(), cuts.end()), cuts.end());
  return cuts;
}

void expect_same(const Outcome& a, const Outcome& b, const std::string& what) {
  ASSERT_EQ(a.d.keep.size(), b.d.keep.size()) << what;
  ASSERT_EQ(a.trace.rho.size(), b.trace.rho.size()) << what;
  for (std::size_t i = 0; i < a.d.keep.size(); ++i) {
    ASSERT_EQ(a.trace.rho[i], b.trace.rho[i]) << what << ": event " << i;
    ASSERT_EQ(a.trace.status[i], b.trace.status[i]) << what << ": event " << i;
    // Bitwise: both backends feed the same integers to the same arithmetic.
    ASSERT_EQ(std::memcmp(&a.trace.curvature[i], &b.trace.curvature[i], sizeof(double)), 0)
        << what << ": event " << i << " " << a.trace.curvature[i] << " vs " << b.trace.curvature[i];
    ASSERT_EQ(a.d.keep[i], b.d.keep[i]) << what << ": event " << i;
    ASSERT_EQ(a.d.score[i], b.d.score[i]) << what << ": event " << i;
  }
  ASSERT_EQ(a.trace.counts, b.trace.counts) << what;
  ASSERT_EQ(a.trace.sums_dt, b.trace.sums_dt) << what;
}

void sort_by_time(std::vector<Event>& ev) {
  std::stable_sort(ev.begin(), ev.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
}

/// Dense random events in two corners of the sensor (borders exercised), many timestamp ties, exact-boundary
/// partners (Δt = ±hw and ±(hw + 1) at every kind of site), duplicates, and a few events outside the sensor.
std::vector<Event> random_stream(std::uint64_t seed, std::size_t n, std::int64_t span_us) {
  std::mt19937_64 rng(seed);
  std::vector<Event> ev;
  std::uniform_int_distribution<std::int64_t> t(0, span_us);
  for (std::size_t i = 0; i < n; ++i) {
    std::int64_t ti = t(rng) + 1'000'000;
    if (rng() % 3 == 0) ti -= ti % 1000;  // ties
    const bool corner = rng() % 2 == 0;
    const int x = corner ? static_cast<int>(rng() % 10) : 346 - 1 - static_cast<int>(rng() % 10);
    const int y = corner ? static_cast<int>(rng() % 8) : 260 - 1 - static_cast<int>(rng() % 8);
    ev.push_back({ti, static_cast<std::uint16_t>(x), static_cast<std::uint16_t>(y), rng() % 2 == 0});
  }
  const std::vector<std::array<std::int64_t, 3>> partners = {
      {0, 0, 20'000}, {0, 0, 20'001}, {1, 0, 17'320}, {0, 1, 17'321}, {1, 1, 14'142}, {-1, 1, 14'143},
      {2, 0, 0},      {0, 2, 0},      {2, 0, 1},      {0, 0, 0},      {0, 0, 19'999}, {1, 0, 17'319}};
  const std::size_t base = ev.size();
  for (std::size_t i = 0; i < base / 5; ++i) {
    const Event& e = ev[rng() % base];
    const auto& p = partners[rng() % partners.size()];
    const int sx = rng() % 2 ? 1 : -1, sy = rng() % 2 ? 1 : -1, st = rng() % 2 ? 1 : -1;
    const int x = e.x + sx * static_cast<int>(p[0]), y = e.y + sy * static_cast<int>(p[1]);
    if (x < 0 || y < 0 || x >= 346 || y >= 260) continue;
    ev.push_back({e.t_us + st * p[2], static_cast<std::uint16_t>(x), static_cast<std::uint16_t>(y), true});
  }
  ev.push_back({1'000'500, 400, 10, true});  // outside the sensor
  ev.push_back({1'000'700, 5, 300, false});
  sort_by_time(ev);
  return ev;
}

// ----------------------------------------------------------------------------------------- exact densities

TEST(Curvature, ExactDensityOnAHandMadeStream) {
  // The centre event (100, 100) at t = 1 s and candidates around it; each comment says whether it is inside.
  const std::int64_t t0 = 1'000'000;
  std::vector<Event> ev = {
      {t0, 100, 100, true},           // the query
      {t0, 102, 100, false},          // (2, 0), Δt = 0: inside only when inclusive
      {t0, 100, 98, true},            // (0, −2), Δt = 0: same
      {t0 + 1, 98, 100, true},        // (−2, 0), Δt = 1: outside
      {t0 + 17'320, 101, 100, true},  // edge site at its exact half-width: inside
      {t0 - 17'321, 99, 100, true},   // one µs beyond: outside
      {t0 - 14'142, 101, 101, true},  // diagonal at its half-width: inside
      {t0 + 14'143, 99, 99, true},    // beyond: outside
      {t0 + 20'000, 100, 100, true},  // own pixel at the reach: inside
      {t0 - 20'001, 100, 100, true},  // beyond: outside
      {t0 + 5, 102, 101, true},       // (2, 1): never inside r = 2
      {t0, 100, 100, false},          // a duplicate at the same pixel and time: inside
  };
  sort_by_time(ev);
  std::size_t q = 0;
  while (!(ev[q].t_us == t0 && ev[q].x == 100 && ev[q].y == 100 && ev[q].polarity)) ++q;
  CurvatureOptions o;
  for (const auto mode : {CurvatureMode::stream, CurvatureMode::frames}) {
    o.mode = mode;
    o.window_us = 10'000'000;  // one block holds everything: frames and stream agree
    o.inclusive_radius = true;
    Outcome r = run(o, ev);
    // Inside: self, (2,0), (0,−2), +17320 edge, −14142 diagonal, +20000 own pixel, the duplicate.
    EXPECT_EQ(r.trace.rho[q], 7) << to_string(mode);
    o.inclusive_radius = false;
    r = run(o, ev);
    // Strict: the Δt = 0 far sites and the exact-boundary events drop out: self, duplicate, and the
    // 17320 (17320² + 10⁸ < 4·10⁸) and 14142 ones stay; the centre's reach is 19 999 so +20000 is out.
    EXPECT_EQ(r.trace.rho[q], 4) << to_string(mode);
  }
  o.mode = CurvatureMode::causal;
  o.inclusive_radius = true;
  const Outcome r = run(o, ev);
  // Causal: only events before the query in input order: (−17321 edge out, −14142 diag in, −20001 out).
  // The stable sort put the query first among the t0 events, so the Δt = 0 ones come after it.
  EXPECT_EQ(r.trace.rho[q], 2);
}

TEST(Curvature, FramesTruncateAtTheBlockBorderStreamDoesNot) {
  CurvatureOptions o;
  o.density_threshold = 1;
  const std::vector<Event> ev = {{29'990, 50, 50, true}, {30'005, 51, 50, true}, {30'010, 50, 50, false}};
  o.mode = CurvatureMode::frames;
  Outcome r = run(o, ev);
  EXPECT_EQ(r.trace.rho, (std::vector<std::int32_t>{1, 2, 2}));
  o.mode = CurvatureMode::stream;
  r = run(o, ev);
  EXPECT_EQ(r.trace.rho, (std::vector<std::int32_t>{3, 3, 3}));
  o.mode = CurvatureMode::causal;
  r = run(o, ev);
  EXPECT_EQ(r.trace.rho, (std::vector<std::int32_t>{1, 2, 3}));
}

TEST(Curvature, CausalUsesOnlyThePastAndDecidesOnArrival) {
  CurvatureOptions o;
  o.mode = CurvatureMode::causal;
  o.density_threshold = 3;
  CurvatureFilter f(o, kDavis346);
  EXPECT_EQ(f.latency_us(), 0);
  CurvatureTrace trace;
  f.set_trace(&trace);
  Decisions d;
  const std::vector<Event> ev = {
      {1000, 50, 50, true}, {2000, 51, 50, true}, {2000, 50, 51, true}, {2000, 49, 50, true}, {50'000, 50, 50, true}};
  for (std::size_t i = 0; i < ev.size(); ++i) {
    f.push(EventSpan(ev).subspan(i, 1), d);
    EXPECT_EQ(d.keep.size(), i + 1);
    EXPECT_EQ(f.pending(), 0U);
  }
  EXPECT_EQ(trace.rho, (std::vector<std::int32_t>{1, 2, 3, 4, 1}));
  // The third and fourth pass density; their fits are singular (cross sites only) → dropped.
  EXPECT_EQ(trace.status[2], CurvatureStatus::undefined);
  EXPECT_EQ(d.keep, (std::vector<std::uint8_t>{0, 0, 0, 0, 0}));
}

TEST(Curvature, CausalRegionDoesNotShrinkFromBlockToBlock) {
  // Each block is judged against the previous block's consistency region, which must be cut from ALL of that
  // block's fitted events: cut from the events that survived the judgement before it, the region would shrink by
  // keep_fraction per block and the filter would end up dropping nearly everything (it did: 77 % of the fitted
  // events of this recording instead of ~20 %).
  EVPIPE_REQUIRE_REAL(path, "emlb-demo-01/demo-01.aedat4");
  const auto ev = io::read_all(path).events;
  CurvatureOptions o;
  o.mode = CurvatureMode::causal;
  o.keep_fraction = 1.0;
  CurvatureFilter fitted_only(o, kDavis346);
  const std::size_t fitted = count_kept(run_filter(fitted_only, ev));
  o.keep_fraction = 0.8;
  CurvatureFilter share(o, kDavis346);
  const std::size_t kept = count_kept(run_filter(share, ev));
  const double ratio = static_cast<double>(kept) / static_cast<double>(fitted);
  // ~20 % of the fitted events go, give or take the change of the region from one block to the next.
  EXPECT_GT(ratio, 0.7) << "kept " << kept << " of " << fitted << " fitted events";
  EXPECT_LT(ratio, 0.9) << "kept " << kept << " of " << fitted << " fitted events";
}

TEST(Curvature, LatencyAndPendingPerMode) {
  CurvatureOptions o;
  o.mode = CurvatureMode::stream;
  CurvatureFilter s(o, kDavis346);
  EXPECT_EQ(s.latency_us(), 30'000 + 20'000);
  o.mode = CurvatureMode::frames;
  CurvatureFilter fr(o, kDavis346);
  EXPECT_EQ(fr.latency_us(), 30'000);
  Decisions d;
  const std::vector<Event> ev = {{1000, 10, 10, true},
                                 {29'999, 10, 10, true},
                                 {30'000, 10, 10, true},
                                 {49'999, 10, 10, true},
                                 {50'000, 10, 10, true}};
  s.push(EventSpan(ev).subspan(0, 3), d);
  fr.push(EventSpan(ev).subspan(0, 3), d);
  EXPECT_EQ(d.keep.size(), 2U);  // frames decided block 0 when t = 30000 arrived; stream waits
  EXPECT_EQ(s.pending(), 3U);
  EXPECT_EQ(fr.pending(), 1U);
  Decisions ds;
  s.push(EventSpan(ev).subspan(3, 1), ds);
  EXPECT_EQ(ds.keep.size(), 0U);  // 49999 < 30000 + 20000
  s.push(EventSpan(ev).subspan(4, 1), ds);
  EXPECT_EQ(ds.keep.size(), 2U);  // 50000 ≥ block end + reach: block 0 is final
  s.finish(ds);
  EXPECT_EQ(ds.keep.size(), 5U);
  EXPECT_EQ(s.pending(), 0U);
}

// ------------------------------------------------------------------------------------------ singular fits

TEST(Curvature, HotPixelPassesDensityButHasNoCurvature) {
  std::vector<Event> ev;
  for (int i = 0; i < 40; ++i) ev.push_back({10'000 + 500 * i, 200, 100, i % 2 == 0});
  CurvatureOptions o;
  Outcome r = run(o, ev);
  EXPECT_EQ(report_value(r.report, "density_passed"), 40);
  EXPECT_EQ(report_value(r.report, "curvature_undefined"), 40);
  EXPECT_EQ(count_kept(r.d), 0U);
  o.singular = SingularPolicy::keep;
  r = run(o, ev);
  EXPECT_EQ(count_kept(r.d), 40U);
  EXPECT_EQ(report_value(r.report, "curvature_dropped"), 0);
}

TEST(Curvature, LineCrossAndParallelLinesAreUndefined) {
  // Status of the first event at the centre pixel when the ball's occupied sites are `sites`.
  const auto status_at = [](const std::vector<std::pair<int, int>>& sites) {
    std::vector<Event> ev;
    for (int rep = 0; rep < 6; ++rep) {
      for (const auto& [dx, dy] : sites) {
        ev.push_back(
            {100'000 + rep * 100, static_cast<std::uint16_t>(100 + dx), static_cast<std::uint16_t>(100 + dy), true});
      }
    }
    sort_by_time(ev);
    CurvatureOptions o;
    const Outcome r = run(o, ev);
    for (std::size_t i = 0; i < ev.size(); ++i) {
      if (ev[i].x == 100 && ev[i].y == 100) return r.trace.status[i];
    }
    return CurvatureStatus::outside;
  };
  const auto fitted = [](CurvatureStatus s) {
    return s == CurvatureStatus::selected || s == CurvatureStatus::not_selected;
  };
  EXPECT_EQ(status_at({{0, 0}}), CurvatureStatus::undefined);                                            // one pixel
  EXPECT_EQ(status_at({{-2, 0}, {-1, 0}, {0, 0}, {1, 0}, {2, 0}}), CurvatureStatus::undefined);          // one line
  EXPECT_EQ(status_at({{0, 0}, {1, 0}, {-1, 0}, {0, 1}, {0, -1}}), CurvatureStatus::undefined);          // u·v = 0
  EXPECT_EQ(status_at({{0, -1}, {0, 0}, {0, 1}, {1, -1}, {1, 0}, {1, 1}}), CurvatureStatus::undefined);  // u² = u
  EXPECT_EQ(status_at({{0, 0}, {1, 1}, {-1, 1}, {1, -1}, {-1, -1}}), CurvatureStatus::undefined);        // 5 sites
  EXPECT_TRUE(fitted(status_at({{0, 0}, {-1, -1}, {-1, 0}, {-1, 1}, {1, -1}, {1, 0}, {1, 1}})));         // 3 columns
  EXPECT_TRUE(fitted(status_at({{0, 0}, {1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}})));
}

TEST(Curvature, MovingEdgeIsFlat) {
  // A straight edge sweeping at 400 px/s: t(x, y) = (x·cos θ + y·sin θ)/v, rounded to µs. Every fitted event
  // sees a plane up to ±0.5 µs of rounding, so |4ab − c²| is tiny.
  std::vector<Event> ev;
  const double th = 0.4, v = 400.0;
  for (int y = 60; y < 120; ++y) {
    for (int x = 60; x < 120; ++x) {
      const double t = 1e6 * ((x - 60) * std::cos(th) + (y - 60) * std::sin(th)) / v;
      ev.push_back({200'000 + std::llround(t), static_cast<std::uint16_t>(x), static_cast<std::uint16_t>(y), true});
    }
  }
  sort_by_time(ev);
  CurvatureOptions o;
  o.density_threshold = 5;
  const Outcome r = run(o, ev);
  std::size_t fitted = 0;
  double worst = 0;
  for (std::size_t i = 0; i < ev.size(); ++i) {
    if (r.trace.status[i] == CurvatureStatus::selected || r.trace.status[i] == CurvatureStatus::not_selected) {
      ++fitted;
      worst = std::max(worst, std::abs(r.trace.curvature[i]));
    }
  }
  EXPECT_GT(fitted, ev.size() * 9 / 10);
  EXPECT_LT(worst, 1e-7);  // noise balls give |c| of order 1 in these units
}

TEST(Curvature, CurvedSurfaceGivesItsDeterminant) {
  // t = 100 x² + 60 y² + 40 xy + ... µs around (150, 150): a = 0.01, b = 0.006, c = 0.004 → 4ab − c² =
  // 2.24e-4 at every fully surrounded event (the far sites carry Δt = 0 only when the surface allows it).
  std::vector<Event> ev;
  for (int y = 140; y <= 160; ++y) {
    for (int x = 140; x <= 160; ++x) {
      const int u = x - 150, w = y - 150;
      ev.push_back({500'000 + 100 * u * u + 60 * w * w + 40 * u * w + 3000 * u, static_cast<std::uint16_t>(x),
                    static_cast<std::uint16_t>(y), true});
    }
  }
  sort_by_time(ev);
  CurvatureOptions o;
  const Outcome r = run(o, ev);
  std::size_t checked = 0;
  for (std::size_t i = 0; i < ev.size(); ++i) {
    if (ev[i].x < 142 || ev[i].x > 158 || ev[i].y < 142 || ev[i].y > 158) continue;
    if (r.trace.status[i] != CurvatureStatus::selected && r.trace.status[i] != CurvatureStatus::not_selected) continue;
    EXPECT_NEAR(r.trace.curvature[i], 4 * 0.01 * 0.006 - 0.004 * 0.004, 1e-12) << ev[i].x << "," << ev[i].y;
    ++checked;
  }
  EXPECT_GT(checked, 200U);
}

// ------------------------------------------------------------------------ backends, batch, push invariance

TEST(Curvature, GridFlannAndBatchAgreeOnRandomStreams) {
  for (const std::uint64_t seed : {1ULL, 2ULL, 3ULL, 4ULL, 5ULL}) {
    const auto ev = random_stream(seed, 3000, 300'000);
    std::mt19937_64 rng(seed * 7919);
    for (const auto mode : {CurvatureMode::stream, CurvatureMode::frames, CurvatureMode::causal}) {
      for (const bool inclusive : {true, false}) {
        CurvatureOptions o;
        o.mode = mode;
        o.inclusive_radius = inclusive;
        o.window_us = seed == 3 ? 10'000 : 30'000;
        const std::string what = "seed " + std::to_string(seed) + " mode " + std::string(to_string(mode)) +
                                 " inclusive " + std::to_string(inclusive);
        o.backend = NeighbourhoodBackend::grid;
        const Outcome grid = run(o, ev, {}, true);
        o.backend = NeighbourhoodBackend::flann;
        const Outcome flann = run(o, ev, random_cuts(ev.size(), rng, 400), true);
        const Outcome ref = batch(o, ev, true);
        expect_same(grid, flann, what + " grid vs flann");
        expect_same(grid, ref, what + " grid vs batch");
        EXPECT_GT(report_value(grid.report, "density_passed"), 100) << what;
      }
    }
  }
}

TEST(Curvature, GridEqualsFlannWhenWindowsHoldManyEvents) {
  // A 5×5 patch at ~2 events per pixel per ms: each per-site window holds 30–80 entries, so the ends of a window
  // move by more than the 8 entries one compare covers (the index's long path) at each pixel's first query and
  // whenever a pixel's events are far apart; with ties. Mutating either long path fails this test.
  for (const std::uint64_t seed : {11ULL, 12ULL}) {
    std::mt19937_64 rng(seed);
    std::vector<Event> ev;
    for (int i = 0; i < 4000; ++i) {
      const std::int64_t t = 2'000'000 + static_cast<std::int64_t>(rng() % 80'000);
      ev.push_back({rng() % 4 == 0 ? t - t % 50 : t, static_cast<std::uint16_t>(100 + rng() % 5),
                    static_cast<std::uint16_t>(50 + rng() % 5), rng() % 2 == 0});
    }
    sort_by_time(ev);
    std::mt19937_64 cut_rng(seed * 31);
    for (const auto mode : {CurvatureMode::stream, CurvatureMode::frames}) {
      CurvatureOptions o;
      o.mode = mode;
      const std::string what = "seed " + std::to_string(seed) + " mode " + std::string(to_string(mode));
      o.backend = NeighbourhoodBackend::grid;
      const Outcome grid = run(o, ev, random_cuts(ev.size(), cut_rng, 700), true);
      o.backend = NeighbourhoodBackend::flann;
      const Outcome flann = run(o, ev, {}, true);
      expect_same(grid, flann, what + " grid vs flann");
      const auto max_count = *std::max_element(grid.trace.counts.begin(), grid.trace.counts.end());
      EXPECT_GT(max_count, 40) << what;
    }
  }
}

// The runners a caller may pass: tasks in reverse order on this thread (any order must do), and one thread per
// task (what the pipeline does, with a pool).
void reversed_runner(int n, const std::function<void(int)>& task) {
  for (int k = n - 1; k >= 0; --k) task(k);
}
void thread_runner(int n, const std::function<void(int)>& task) {
  std::vector<std::thread> threads;
  for (int k = 1; k < n; ++k) threads.emplace_back(task, k);
  task(0);
  for (auto& t : threads) t.join();
}

void expect_same_counters(const Outcome& a, const Outcome& b, const std::string& what) {
  for (const char* key : {"density_passed", "curvature_undefined", "curvature_dropped", "blocks"}) {
    EXPECT_EQ(report_value(a.report, key), report_value(b.report, key)) << what << ": " << key;
  }
}

TEST(Curvature, RowBandTasksGiveTheSameDecisions) {
  // The random streams put events in rows 0-7 and 252-259 only: 3 and 5 bands cut inside them, so balls reach
  // across band borders.
  for (const std::uint64_t seed : {1ULL, 2ULL, 3ULL}) {
    const auto ev = random_stream(seed, 3000, 300'000);
    std::mt19937_64 rng(seed * 31);
    for (const auto mode : {CurvatureMode::stream, CurvatureMode::frames}) {
      CurvatureOptions o;
      o.mode = mode;
      o.window_us = seed == 3 ? 10'000 : 30'000;
      const Outcome one = run(o, ev, {}, true);
      for (const int tasks : {2, 3, 5}) {
        const std::string what =
            "seed " + std::to_string(seed) + " " + std::string(to_string(mode)) + " tasks " + std::to_string(tasks);
        int calls = 0;  // the split really happens: the runner gets the tasks
        const TaskRunner counting = [&](int n, const std::function<void(int)>& task) {
          EXPECT_EQ(n, tasks);
          ++calls;
          reversed_runner(n, task);
        };
        const Outcome rev = run(o, ev, random_cuts(ev.size(), rng, 700), true, tasks, counting);
        EXPECT_GT(calls, 5) << what;
        expect_same(rev, one, what + " reversed");
        expect_same_counters(rev, one, what + " reversed");
        const Outcome thr = run(o, ev, random_cuts(ev.size(), rng, 700), true, tasks, thread_runner);
        expect_same(thr, one, what + " threads");
        expect_same_counters(thr, one, what + " threads");
      }
    }
  }
}

TEST(Curvature, ParallelismReachesTheCurvatureStageOfAChainOnly) {
  const auto ev = random_stream(9, 3000, 300'000);
  int calls = 0;
  const TaskRunner counting = [&](int n, const std::function<void(int)>& task) {
    ++calls;
    reversed_runner(n, task);
  };
  Decisions d;
  auto chain = make_filter_chain("hotpixel,curvature", {}, kDavis346);
  chain->set_parallelism(2, counting);
  chain->push(ev, d);
  chain->finish(d);
  EXPECT_GT(calls, 5);
  // Causal mode and the FLANN backend stay in one task.
  for (const auto& [mode, backend] : {std::pair{CurvatureMode::causal, NeighbourhoodBackend::grid},
                                      std::pair{CurvatureMode::stream, NeighbourhoodBackend::flann}}) {
    CurvatureOptions o;
    o.mode = mode;
    o.backend = backend;
    calls = 0;
    const Outcome two = run(o, ev, {}, false, 2, counting);
    EXPECT_EQ(calls, 0);
    ASSERT_EQ(two.d.keep, run(o, ev).d.keep);
  }
}

TEST(Curvature, RowBandTasksOnRealRecordingsAndWithTheAdaptiveThreshold) {
  CurvatureOptions o;
  {
    // Adaptive: every period's failures are counted before the next period's threshold, whatever the tasks.
    std::mt19937_64 rng(4243);
    sim::NoiseOptions no;
    no.rate_hz_per_pixel = 5.0;
    const auto ev = sim::background_activity(kDavis346, 0, 3'000'000, no, rng);
    CurvatureOptions a = o;
    a.adaptive = true;
    a.adaptive_period_us = 700'000;
    const Outcome one = run(a, ev, time_cuts(ev, 20'000));
    const Outcome two = run(a, ev, time_cuts(ev, 20'000), false, 2, thread_runner);
    expect_same(two, one, "adaptive, 2 tasks");
    expect_same_counters(two, one, "adaptive, 2 tasks");
    EXPECT_EQ(report_value(two.report, "noise_rate_hz"), report_value(one.report, "noise_rate_hz"));
    EXPECT_EQ(report_value(two.report, "adaptive_periods"), 4);  // 3 s in periods of 0.7 s
  }
  for (const std::string rel : {"emlb-demo-01/demo-01.aedat4", "davis346-faery/davis346.aedat4"}) {
    EVPIPE_REQUIRE_REAL(path, rel);
    const EventBatch b = io::read_all(path);
    const std::vector<Event>& ev = b.events;
    const Outcome one = run(o, ev, time_cuts(ev, 30'000));
    const Outcome two = run(o, ev, time_cuts(ev, 5'000), false, 2, thread_runner);
    ASSERT_EQ(two.d.keep, one.d.keep) << rel;
    ASSERT_EQ(two.d.score, one.d.score) << rel;
    expect_same_counters(two, one, rel);
  }
}

TEST(Curvature, StreamEqualsBatchWhateverThePushes) {
  for (const std::uint64_t seed : {11ULL, 12ULL, 13ULL}) {
    const auto ev = random_stream(seed, 4000, 400'000);
    std::mt19937_64 rng(seed);
    for (const std::int64_t window : {30'000, 10'000, 55'000}) {
      CurvatureOptions o;
      o.window_us = window;
      const Outcome ref = batch(o, ev);
      const std::string what = "seed " + std::to_string(seed) + " window " + std::to_string(window);
      expect_same(run(o, ev, random_cuts(ev.size(), rng, 50)), ref, what + " random pushes ≤ 50");
      expect_same(run(o, ev, random_cuts(ev.size(), rng, 2000)), ref, what + " random pushes ≤ 2000");
      for (const std::int64_t hop : {1'000, 10'000, 33'333}) {
        expect_same(run(o, ev, time_cuts(ev, hop)), ref, what + " hop " + std::to_string(hop));
      }
      std::vector<std::size_t> ones(ev.size() - 1);
      std::iota(ones.begin(), ones.end(), std::size_t{1});
      expect_same(run(o, ev, ones), ref, what + " one event per push");
    }
  }
}

TEST(Curvature, RealRecordingsGridEqualsFlannEqualsBatch) {
  for (const std::string rel : {"emlb-demo-01/demo-01.aedat4", "davis346-faery/davis346.aedat4"}) {
    EVPIPE_REQUIRE_REAL(path, rel);
    const EventBatch b = io::read_all(path);
    const std::vector<Event>& ev = b.events;
    ASSERT_GT(ev.size(), 10'000U);
    CurvatureOptions o;
    const Outcome grid = run(o, ev, time_cuts(ev, 7'000), true);
    o.backend = NeighbourhoodBackend::flann;
    const Outcome flann = run(o, ev, time_cuts(ev, 45'000), true);
    const Outcome ref = batch(o, ev);
    expect_same(grid, flann, rel + " grid vs flann");
    ASSERT_EQ(grid.d.keep, ref.d.keep) << rel;
    ASSERT_EQ(grid.d.score, ref.d.score) << rel;
    std::printf("[ info ] %s: %zu events, kept %.2f %%, density passed %.0f, undefined %.0f, dropped %.0f\n",
                rel.c_str(), ev.size(), 100.0 * count_kept(grid.d) / ev.size(),
                report_value(grid.report, "density_passed"), report_value(grid.report, "curvature_undefined"),
                report_value(grid.report, "curvature_dropped"));
    for (const auto mode : {CurvatureMode::frames, CurvatureMode::causal}) {
      o.mode = mode;
      o.backend = NeighbourhoodBackend::grid;
      const Outcome g = run(o, ev, time_cuts(ev, 3'000));
      const Outcome bref = batch(o, ev);
      ASSERT_EQ(g.d.keep, bref.d.keep) << rel << " " << to_string(mode);
      ASSERT_EQ(g.d.score, bref.d.score) << rel << " " << to_string(mode);
    }
  }
}

// ------------------------------------------------------------------------------------------- options

TEST(Curvature, KeepFractionOneAndCurvatureOff) {
  const auto ev = random_stream(21, 3000, 300'000);
  CurvatureOptions o;
  o.keep_fraction = 1.0;
  o.singular = SingularPolicy::keep;
  const Outcome all = run(o, ev);
  o.curvature = false;
  const Outcome off = run(o, ev);
  EXPECT_EQ(all.d.keep, off.d.keep);
  EXPECT_EQ(report_value(off.report, "curvature_undefined"), 0);
  // Density only: kept iff ρ ≥ 5, with ρ the score's integer part.
  for (std::size_t i = 0; i < ev.size(); ++i) {
    ASSERT_EQ(off.d.keep[i] != 0, off.trace.rho[i] >= 5) << i;
    ASSERT_EQ(off.d.score[i], static_cast<float>(off.trace.rho[i]));
  }
  // keep_fraction 1 with singular = reject drops exactly the undefined ones.
  o.curvature = true;
  o.singular = SingularPolicy::reject;
  const Outcome rej = run(o, ev);
  EXPECT_EQ(count_kept(off.d) - count_kept(rej.d),
            static_cast<std::size_t>(report_value(rej.report, "curvature_undefined")));
}

TEST(Curvature, EachBlockKeepsItsShareOfTheFittedEvents) {
  const auto ev = random_stream(22, 5000, 300'000);
  for (const auto rule : {CurvatureRule::median, CurvatureRule::shortest, CurvatureRule::flattest}) {
    CurvatureOptions o;
    o.rule = rule;
    o.keep_fraction = 0.7;
    const Outcome r = run(o, ev);
    std::map<std::int64_t, std::pair<std::size_t, std::size_t>> per_block;  // fitted, selected
    for (std::size_t i = 0; i < ev.size(); ++i) {
      auto& b = per_block[ev[i].t_us / o.window_us];
      const auto st = r.trace.status[i];
      if (st == CurvatureStatus::selected || st == CurvatureStatus::not_selected) ++b.first;
      if (st == CurvatureStatus::selected) {
        ++b.second;
        ASSERT_EQ(r.d.keep[i], 1);
        ASSERT_GT(r.d.score[i], static_cast<float>(r.trace.rho[i]));
        ASSERT_LT(r.d.score[i], static_cast<float>(r.trace.rho[i] + 1));
      }
    }
    for (const auto& [blk, fs] : per_block)
      EXPECT_EQ(fs.second, keep_count(fs.first, 0.7)) << blk << " " << to_string(rule);
  }
}

TEST(Curvature, RegistryAndParameterRejection) {
  auto f = make_filter("curvature", {}, kDavis346);
  ASSERT_NE(f, nullptr);
  EXPECT_EQ(f->name(), "curvature");
  EXPECT_TRUE(f->has_score());
  const auto params = describe(*find_filter("curvature"));
  for (const char* key : {"radius", "lt_us", "inclusive_radius", "density_threshold", "curvature", "keep_fraction",
                          "rule", "singular", "window_us", "mode", "backend", "adaptive", "target_noise_pass",
                          "adaptive_period_us", "adaptive_max_threshold"}) {
    EXPECT_TRUE(std::any_of(params.begin(), params.end(), [&](const ParamInfo& p) { return p.key == key; })) << key;
  }
  const auto rejects = [](const std::string& key, const std::string& value) {
    try {
      (void)make_filter("curvature", {{key, value}}, kDavis346);
    } catch (const std::invalid_argument& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find("curvature"), std::string::npos) << msg;
      EXPECT_NE(msg.find(key), std::string::npos) << msg;
      return;
    }
    ADD_FAILURE() << key << "=" << value << " was accepted";
  };
  rejects("radius", "-2");
  rejects("radius", "0");
  rejects("radius", "4.5");
  rejects("radius", "abc");
  rejects("lt_us", "0");
  rejects("keep_fraction", "0");
  rejects("keep_fraction", "1.5");
  rejects("keep_fraction", "-0.1");
  rejects("rule", "mean");
  rejects("mode", "sliding");
  rejects("backend", "nanoflann");
  rejects("singular", "lstsq");
  rejects("window_us", "0");
  rejects("window_us", "-30000");
  rejects("density_threshold", "0");
  rejects("target_noise_pass", "1");
  rejects("adaptive_period_us", "0");
  rejects("adaptive_max_threshold", "1");
  rejects("adaptive_max_threshold", "-5");
  rejects("no_such_key", "1");
  CurvatureOptions o;
  o.keep_fraction = 2;
  EXPECT_THROW(CurvatureFilter(o, kDavis346), std::invalid_argument);
  EXPECT_THROW(curvature_batch({}, o, kDavis346), std::invalid_argument);
  CurvatureOptions cap;
  cap.adaptive_max_threshold = 1;
  EXPECT_THROW(CurvatureFilter(cap, kDavis346), std::invalid_argument);
  // Accepted values build.
  EXPECT_NE(make_filter("curvature", {{"radius", "4"}, {"mode", "causal"}, {"backend", "flann"}}, kDavis346), nullptr);
}

TEST(Curvature, LargerRadiusGridEqualsFlann) {
  const auto ev = random_stream(31, 2500, 200'000);
  for (const double radius : {1.0, 1.5, 3.0, 4.0}) {
    CurvatureOptions o;
    o.radius_px = radius;
    o.lt_us = 7'000;
    const Outcome grid = run(o, ev, {}, true);
    o.backend = NeighbourhoodBackend::flann;
    expect_same(grid, run(o, ev, {}, true), "radius " + std::to_string(radius));
  }
}

TEST(Curvature, OutOfOrderAndOutsideEventsAreHandled) {
  std::vector<Event> ev = {{1000, 10, 10, true}, {900, 11, 10, true}, {1100, 500, 10, true}, {1200, 10, 11, true}};
  CurvatureOptions o;
  o.density_threshold = 1;
  const Outcome r = run(o, ev);
  ASSERT_EQ(r.d.keep.size(), 4U);
  EXPECT_EQ(r.d.keep[2], 0);
  EXPECT_EQ(r.trace.status[2], CurvatureStatus::outside);
  EXPECT_EQ(r.trace.rho[1], 3);  // 900 is treated as 1000
}

TEST(Curvature, MemoryIsBoundedByTheWindow) {
  std::mt19937_64 rng(5);
  CurvatureFilter f(CurvatureOptions{}, kDavis346);
  Decisions d;
  std::size_t total = 0;
  std::size_t worst = 0;
  for (int k = 0; k < 100; ++k) {
    const auto ev = sim::uniform_noise(kDavis346, k * 10'000, 10'000, 2000, rng);
    f.push(ev, d);
    total += ev.size();
    worst = std::max(worst, f.pending());
  }
  EXPECT_LE(worst, 2000U * 9);  // at most window + reach + one push of 10 ms worth
  f.finish(d);
  EXPECT_EQ(d.keep.size(), total);
}

// ------------------------------------------------------------------------------------------- adaptive

TEST(Curvature, AdaptiveEstimatesTheNoiseRateAndStaysPushInvariant) {
  const std::uint64_t seed = 4242;
  std::mt19937_64 rng(seed);
  sim::NoiseOptions no;
  no.rate_hz_per_pixel = 5.0;
  const auto ev = sim::background_activity(kDavis346, 0, 3'000'000, no, rng);
  CurvatureOptions o;
  o.adaptive = true;
  o.adaptive_period_us = 1'000'000;  // 3 periods: the first observed, two adapted
  o.curvature = false;
  const Outcome a = run(o, ev, time_cuts(ev, 20'000));
  const double rate = report_value(a.report, "noise_rate_hz");
  std::printf("[ info ] adaptive on 5 Hz/px noise: estimate %.3f Hz/px, threshold %.0f (seed %llu)\n", rate,
              report_value(a.report, "density_threshold_used"), static_cast<unsigned long long>(seed));
  EXPECT_NEAR(rate, 5.0, 0.25) << "seed " << seed;
  EXPECT_EQ(report_value(a.report, "density_threshold_used"), 7) << "seed " << seed;
  EXPECT_EQ(report_value(a.report, "adaptive_periods"), 2);
  expect_same(a, batch(o, ev), "adaptive stream vs batch");
  std::mt19937_64 cut_rng(seed);
  expect_same(a, run(o, ev, random_cuts(ev.size(), cut_rng, 5000)), "adaptive random pushes");
  // The pass rate of noise in the periods after the first is near the target (1 %).
  std::size_t late = 0, late_kept = 0;
  for (std::size_t i = 0; i < ev.size(); ++i) {
    if (ev[i].t_us < 1'000'000) continue;
    ++late;
    late_kept += a.d.keep[i];
  }
  EXPECT_LT(static_cast<double>(late_kept) / late, 0.01) << "seed " << seed;
  // Frames and causal estimate with their own exposure.
  for (const auto mode : {CurvatureMode::frames, CurvatureMode::causal}) {
    o.mode = mode;
    const Outcome m = run(o, ev, time_cuts(ev, 20'000));
    EXPECT_NEAR(report_value(m.report, "noise_rate_hz"), 5.0, 0.35) << to_string(mode) << " seed " << seed;
    expect_same(m, batch(o, ev), std::string("adaptive ") + std::string(to_string(mode)) + " vs batch");
  }
}

TEST(Curvature, AdaptiveMaxThresholdCapsOnlyTheRise) {
  // The cap keeps the paper's 5 where the estimate would raise it (5 Hz/px: 7) and leaves the lowering where the
  // noise is low (0.2 Hz/px: 3); the rate estimate is the same model either way.
  const std::uint64_t seed = 977;
  for (const double hz : {5.0, 0.2}) {
    std::mt19937_64 rng(seed);
    sim::NoiseOptions no;
    no.rate_hz_per_pixel = hz;
    const auto ev = sim::background_activity(kDavis346, 0, 2'000'000, no, rng);
    CurvatureOptions o;
    o.adaptive = true;
    o.adaptive_period_us = 500'000;
    o.curvature = false;
    const Outcome free = run(o, ev, time_cuts(ev, 20'000));
    o.adaptive_max_threshold = 5;
    const Outcome capped = run(o, ev, time_cuts(ev, 20'000));
    const double th_free = report_value(free.report, "density_threshold_used");
    const double th_capped = report_value(capped.report, "density_threshold_used");
    std::printf("[ info ] %.1f Hz/px: threshold %.0f free, %.0f capped at 5; estimate %.2f / %.2f Hz/px (seed %llu)\n",
                hz, th_free, th_capped, report_value(free.report, "noise_rate_hz"),
                report_value(capped.report, "noise_rate_hz"), static_cast<unsigned long long>(seed));
    EXPECT_NEAR(report_value(capped.report, "noise_rate_hz"), hz, hz * 0.1) << "seed " << seed;
    expect_same(capped, batch(o, ev), "capped stream vs batch");
    if (hz > 1.0) {
      EXPECT_EQ(th_free, 7) << "seed " << seed;
      EXPECT_EQ(th_capped, 5) << "seed " << seed;
      // Capped at the paper's threshold, every period decides as the fixed filter does.
      o.adaptive = false;
      expect_same(capped, run(o, ev, time_cuts(ev, 20'000)), "capped at 5 vs fixed 5");
    } else {
      EXPECT_EQ(th_free, 3) << "seed " << seed;
      EXPECT_EQ(th_capped, 3) << "seed " << seed;
      expect_same(capped, free, "below the cap");
    }
  }
  // A cap below the initial threshold applies from the first period on.
  CurvatureOptions o;
  o.adaptive = true;
  o.adaptive_max_threshold = 3;
  std::mt19937_64 rng(seed);
  const auto ev = sim::uniform_noise(kDavis346, 0, 30'000, 3000, rng);
  const Outcome r = run(o, ev);
  o.adaptive = false;
  o.density_threshold = 3;
  expect_same(r, run(o, ev), "first period at the cap");
}

// ----------------------------------------------------------------------------------------- Table 1

TEST(Curvature, PaperTable1ResidualNoise) {
  // The paper's protocol (section 4.1): N uniform noise events in 30 ms on 346×260, paper parameters.
  const std::array<std::size_t, 4> n = {500, 3000, 6000, 9000};
  const std::array<double, 4> paper = {0, 2, 6, 67};
  constexpr int kSeeds = 10;
  for (std::size_t k = 0; k < n.size(); ++k) {
    double residual = 0, density_only = 0;
    for (int seed = 0; seed < kSeeds; ++seed) {
      std::mt19937_64 rng(static_cast<std::uint64_t>(seed));
      const auto ev = sim::uniform_noise(kDavis346, 0, 30'000, n[k], rng);
      CurvatureOptions o;
      const Outcome r = run(o, ev);
      residual += static_cast<double>(count_kept(r.d));
      o.mode = CurvatureMode::frames;
      EXPECT_EQ(run(o, ev).d.keep, r.d.keep) << "one 30 ms frame: frames == stream, seed " << seed;
      o.curvature = false;
      density_only += static_cast<double>(count_kept(run(o, ev).d));
    }
    residual /= kSeeds;
    density_only /= kSeeds;
    std::printf("[ info ] Table 1, N = %zu: mean residual %.2f (density only %.2f), paper %.0f, seeds 0-%d\n", n[k],
                residual, density_only, paper[k], kSeeds - 1);
    EXPECT_LE(residual, paper[k]) << "N = " << n[k];
  }
}

}  // namespace
}  // namespace evpipe::denoise

namespace evpipe::denoise {
namespace {

// ------------------------------------------------------------------------------------ labelled quality

struct Quality {
  double signal_kept = 0, noise_kept = 0, f1 = 0;
};

Quality quality(const Decisions& d, const std::vector<Label>& labels) {
  double tp = 0, fp = 0, fn = 0, signal = 0, noise = 0;
  for (std::size_t i = 0; i < labels.size(); ++i) {
    const bool sig = labels[i] == Label::signal;
    (sig ? signal : noise) += 1;
    if (d.keep[i] != 0) {
      (sig ? tp : fp) += 1;
    } else if (sig) {
      fn += 1;
    }
  }
  return {tp / signal, fp / noise, 2 * tp / (2 * tp + fp + fn)};
}

TEST(Curvature, ModesOnALabelledSceneWithNoise) {
  // 12 bars rotating at 20 rad/s (≈ 0.9 Mev/s of edges) + 5 Hz/px background activity for 1 s.
  const std::uint64_t seed = 99;
  const auto signal = testing::rotating_bar_events(testing::bar_grid(20.0), kDavis346, 0, 1'000'000);
  std::mt19937_64 rng(seed);
  sim::NoiseOptions no;
  no.rate_hz_per_pixel = 5.0;
  const auto noise = sim::background_activity(kDavis346, 0, 1'000'000, no, rng);
  const sim::LabelledEvents rec = sim::merge_labelled(signal, noise);
  struct Case {
    const char* name;
    CurvatureMode mode;
    bool curvature;
    SingularPolicy singular;
    bool adaptive;
  };
  const std::vector<Case> cases = {
      {"stream", CurvatureMode::stream, true, SingularPolicy::reject, false},
      {"stream density only", CurvatureMode::stream, false, SingularPolicy::reject, false},
      {"frames", CurvatureMode::frames, true, SingularPolicy::reject, false},
      {"causal", CurvatureMode::causal, true, SingularPolicy::reject, false},
      {"causal singular=keep", CurvatureMode::causal, true, SingularPolicy::keep, false},
      {"causal density only", CurvatureMode::causal, false, SingularPolicy::reject, false},
      {"stream adaptive", CurvatureMode::stream, true, SingularPolicy::reject, true},
  };
  std::map<std::string, Quality> q;
  for (const auto& c : cases) {
    CurvatureOptions o;
    o.mode = c.mode;
    o.curvature = c.curvature;
    o.singular = c.singular;
    o.adaptive = c.adaptive;
    o.adaptive_period_us = 250'000;
    const Outcome r = run(o, rec.events, time_cuts(rec.events, 10'000));
    q[c.name] = quality(r.d, rec.labels);
    std::printf("[ info ] labelled bars + 5 Hz/px, %-22s signal kept %5.1f %%, noise kept %5.2f %%, F1 %.3f%s\n",
                c.name, 100 * q[c.name].signal_kept, 100 * q[c.name].noise_kept, q[c.name].f1,
                c.adaptive ? (" (threshold " +
                              std::to_string(static_cast<int>(report_value(r.report, "density_threshold_used"))) +
                              ", rate " + std::to_string(report_value(r.report, "noise_rate_hz")) + " Hz/px)")
                                 .c_str()
                           : "");
  }
  // Sanity bounds (the printed figures are the measurement). The bars sweep two thirds of the sensor, so
  // much noise lands next to signal and passes the density test. The curvature stage keeps ≈ 80 % of the
  // fitted signal and removes part of that noise; the causal half-ball is often rank-deficient on moving
  // edges, so causal with singular = reject loses more than half of the signal (measured: 40.8 % kept).
  EXPECT_GT(q["stream density only"].signal_kept, 0.99) << "seed " << seed;
  EXPECT_GT(q["stream"].signal_kept, 0.7) << "seed " << seed;
  EXPECT_LT(q["stream"].noise_kept, q["stream density only"].noise_kept * 0.7) << "seed " << seed;
  EXPECT_LT(q["causal"].signal_kept, 0.6) << "seed " << seed;
  EXPECT_GT(q["causal singular=keep"].signal_kept, q["causal"].signal_kept + 0.3) << "seed " << seed;
}

}  // namespace
}  // namespace evpipe::denoise

namespace evpipe::denoise {
namespace {

TEST(Curvature, CausalRingsGrowWithoutReadingStaleTimes) {
  // Bursts of 5 … 80 events per pixel within a few ms (rings start at 8 timestamps and must grow), separated
  // by quiet gaps longer than the reach (old entries must stop counting), on a 5×5 patch; grid == batch.
  const std::uint64_t seed = 123;
  std::mt19937_64 rng(seed);
  std::vector<Event> ev;
  std::int64_t t = 1'000'000;
  for (int burst = 0; burst < 40; ++burst) {
    const int n = 5 + static_cast<int>(rng() % 76);
    for (int k = 0; k < n * 25; ++k) {
      t += static_cast<std::int64_t>(rng() % 40);
      ev.push_back({t, static_cast<std::uint16_t>(100 + rng() % 5), static_cast<std::uint16_t>(100 + rng() % 5), true});
    }
    t += burst % 3 == 0 ? 25'000 : 3'000;  // sometimes beyond the reach, sometimes within it
  }
  for (const auto singular : {SingularPolicy::reject, SingularPolicy::keep}) {
    CurvatureOptions o;
    o.mode = CurvatureMode::causal;
    o.singular = singular;
    const Outcome ref = batch(o, ev, true);
    std::mt19937_64 cut_rng(seed);
    expect_same(run(o, ev, random_cuts(ev.size(), cut_rng, 300), true), ref, "causal bursts, seed 123");
    o.mode = CurvatureMode::stream;
    expect_same(run(o, ev, random_cuts(ev.size(), cut_rng, 300), true), batch(o, ev, true), "stream bursts, seed 123");
  }
}

}  // namespace
}  // namespace evpipe::denoise
