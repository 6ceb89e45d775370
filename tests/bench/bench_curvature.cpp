// Throughput of the paper's curvature filter (libs/denoise): Mev/s per backend (grid / flann), mode
// (frames / stream / causal) and curvature stage (on / off), one thread, pushes of 8192 events (a reader's
// batch), decisions included, file I/O excluded.
//   build-rel/tests/bench/bench_curvature [--benchmark_filter=stream] [--benchmark_format=json]
// Data: the E-MLB demo recording (EVPIPE_BENCH_DEMO=path, default ../shared/data/real/emlb-demo-01/
// demo-01.aedat4; skipped when absent) and a synthetic 10 Mev/s stream: 12 rotating bars (exact edge times,
// tests/support/rotating_bars.hpp) plus 5 Hz/pixel background activity from libs/sim. Goals (issue 4):
// grid ≥ 20× flann, stream with curvature ≥ 12 Mev/s on one core.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "evpipe/denoise/curvature.hpp"
#include "evpipe/denoise/neighbourhood.hpp"
#include "evpipe/denoise/sphere.hpp"
#include "evpipe/io/reader.hpp"
#include "evpipe/runtime/task_pool.hpp"
#include "evpipe/sim/noise.hpp"
#include "evpipe/sim/recording.hpp"
#include "rotating_bars.hpp"

namespace {

using namespace evpipe;
using namespace evpipe::denoise;

const std::vector<Event>& demo_events() {
  static const std::vector<Event> ev = [] {
    const char* env = std::getenv("EVPIPE_BENCH_DEMO");
    const std::string path =
        env != nullptr ? env : std::string(EVPIPE_SHARED_DATA_DIR) + "/emlb-demo-01/demo-01.aedat4";
    if (!std::filesystem::exists(path)) return std::vector<Event>{};
    return io::read_all(path).events;
  }();
  return ev;
}

/// `seconds` of 12 rotating bars at ≈ 9.5 Mev/s plus 5 Hz/px noise (≈ 0.45 Mev/s).
std::vector<Event> synthetic(double omega_rad_s, std::int64_t span_us) {
  const auto signal = testing::rotating_bar_events(testing::bar_grid(omega_rad_s), kDavis346, 0, span_us);
  std::mt19937_64 rng(7);
  sim::NoiseOptions no;
  no.rate_hz_per_pixel = 5.0;
  const auto noise = sim::background_activity(kDavis346, 0, span_us, no, rng);
  return sim::merge_labelled(signal, noise).events;
}

const std::vector<Event>& synth10_events() {
  static const std::vector<Event> ev = synthetic(230.0, 300'000);
  return ev;
}

void BM_Curvature(benchmark::State& state, const std::vector<Event>& (*data)(), NeighbourhoodBackend backend,
                  CurvatureMode mode, bool curvature, int threads) {
  const std::vector<Event>& ev = data();
  if (ev.empty()) {
    state.SkipWithError("recording not available (set EVPIPE_BENCH_DEMO)");
    return;
  }
  CurvatureOptions o;
  o.backend = backend;
  o.mode = mode;
  o.curvature = curvature;
  std::size_t kept = 0;
  Decisions d;
  d.keep.reserve(ev.size());
  d.score.reserve(ev.size());
  // threads > 1: each block's row bands on a pool (as evpipe's denoise stage runs it; wall-clock rate).
  runtime::TaskPool pool(threads - 1, "bench-");
  // One filter for all iterations, reset between them: what a long-running pipeline sees (the rank table of
  // occupancy masks, filled on first use, stays warm).
  CurvatureFilter f(o, kDavis346);
  if (threads > 1) f.set_parallelism(threads, pool.runner());
  for (auto _ : state) {
    f.reset();
    d.clear();
    constexpr std::size_t kPush = 8192;
    for (std::size_t i = 0; i < ev.size(); i += kPush) {
      f.push(EventSpan(ev).subspan(i, std::min(kPush, ev.size() - i)), d);
    }
    f.finish(d);
    kept = count_kept(d);
    benchmark::DoNotOptimize(d.keep.data());
  }
  const double duration_s = static_cast<double>(ev.back().t_us - ev.front().t_us) * 1e-6;
  state.counters["Mev/s"] = benchmark::Counter(
      static_cast<double>(ev.size()) * 1e-6 * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["input_Mev/s"] = static_cast<double>(ev.size()) * 1e-6 / duration_s;
  state.counters["kept_%"] = 100.0 * static_cast<double>(kept) / static_cast<double>(ev.size());
}

/// The neighbourhood index alone — the "fast index vs FLANN" ratio, without the fit and selection both
/// backends share: per 30 ms block (indexed with the stream mode's margins of one reach on each side, as the filter
/// indexes it), the per-site ball statistics (n_s, ΣΔt_s) of every event of the block. Grid: GridBlockIndex build +
/// query; FLANN: FlannBallIndex build + ball() + accumulate_ball(). The two must agree on Σρ and ΣΔt (checked: a
/// mismatch fails the benchmark).
struct IndexChecksum {
  std::int64_t rho = 0;
  std::int64_t sum_dt = 0;
};

void BM_Index(benchmark::State& state, const std::vector<Event>& (*data)(), NeighbourhoodBackend backend) {
  const std::vector<Event>& raw = data();
  if (raw.empty()) {
    state.SkipWithError("recording not available (set EVPIPE_BENCH_DEMO)");
    return;
  }
  std::vector<Event> ev;  // time order and inside the sensor, as the filter hands events to its index
  for (const Event& e : raw)
    if (kDavis346.contains(e.x, e.y)) ev.push_back(e);
  std::stable_sort(ev.begin(), ev.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  const Sphere sphere(2.0, 10'000, true);  // the paper's ball
  const std::int64_t window_us = 30'000;
  const std::int64_t reach_us = sphere.reach_us();
  GridBlockIndex grid(sphere, kDavis346);
  FlannBallIndex flann(sphere);
  std::vector<std::uint32_t> members;
  std::int32_t counts[kMaxSphereSites + 1] = {};
  std::int64_t sums[kMaxSphereSites + 1] = {};
  IndexChecksum sum;
  const auto lower = [&](std::int64_t t) {
    return static_cast<std::size_t>(
        std::lower_bound(ev.begin(), ev.end(), t, [](const Event& e, std::int64_t v) { return e.t_us < v; }) -
        ev.begin());
  };
  for (auto _ : state) {
    sum = {};
    const std::int64_t t_end = ev.back().t_us + 1;
    for (std::int64_t t0 = ev.front().t_us - ev.front().t_us % window_us; t0 < t_end; t0 += window_us) {
      const std::size_t m0 = lower(t0 - reach_us), b0 = lower(t0), b1 = lower(t0 + window_us),
                        m1 = lower(t0 + window_us + reach_us + 1);
      if (b0 == b1) continue;
      const EventSpan span = EventSpan(ev).subspan(m0, m1 - m0);
      if (backend == NeighbourhoodBackend::grid) {
        grid.build(span);
        grid.query(b0 - m0, b1 - m0, std::numeric_limits<std::int64_t>::min() / 4,
                   std::numeric_limits<std::int64_t>::max() / 4,
                   [&](std::size_t, std::int64_t, std::int32_t rho, std::uint64_t, const std::int32_t*,
                       const double* sums_dt) {
                     sum.rho += rho;
                     for (int s = 0; s < sphere.size(); ++s) sum.sum_dt += static_cast<std::int64_t>(sums_dt[s]);
                   });
      } else {
        flann.build(span, kDavis346);
        for (std::size_t i = b0 - m0; i < b1 - m0; ++i) {
          flann.ball(span[i], members);
          accumulate_ball(
              sphere, span, i, members, [](std::size_t) { return false; }, counts, sums);
          for (int s = 0; s < sphere.size(); ++s) sum.rho += counts[s], sum.sum_dt += sums[s];
        }
      }
    }
    benchmark::DoNotOptimize(sum);
  }
  // Both backends on one dataset must agree (the tests prove it event by event; this guards the benchmark itself).
  static std::map<std::string, IndexChecksum> seen;
  const std::string key = std::to_string(reinterpret_cast<std::uintptr_t>(data));
  if (const auto it = seen.find(key); it != seen.end()) {
    if (it->second.rho != sum.rho || it->second.sum_dt != sum.sum_dt) state.SkipWithError("grid and flann disagree");
  } else {
    seen[key] = sum;
  }
  state.counters["Mev/s"] = benchmark::Counter(
      static_cast<double>(ev.size()) * 1e-6 * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["mean_rho"] = static_cast<double>(sum.rho) / static_cast<double>(ev.size());
}

void register_all() {
  struct Data {
    const char* name;
    const std::vector<Event>& (*get)();
  };
  for (const Data data : {Data{"demo", demo_events}, Data{"synth10", synth10_events}}) {
    for (const auto backend : {NeighbourhoodBackend::grid, NeighbourhoodBackend::flann}) {
      auto* b = benchmark::RegisterBenchmark(
          (std::string("index/") + data.name + (backend == NeighbourhoodBackend::grid ? "/grid" : "/flann")).c_str(),
          BM_Index, data.get, backend);
      b->Unit(benchmark::kMillisecond);
      if (backend == NeighbourhoodBackend::flann) b->Iterations(1);
    }
    for (const auto backend : {NeighbourhoodBackend::grid, NeighbourhoodBackend::flann}) {
      for (const auto mode : {CurvatureMode::stream, CurvatureMode::frames, CurvatureMode::causal}) {
        for (const bool curvature : {true, false}) {
          const std::string name = std::string("curvature/") + data.name + "/" +
                                   (backend == NeighbourhoodBackend::grid ? "grid" : "flann") + "/" +
                                   std::string(to_string(mode)) + (curvature ? "/curv" : "/density");
          auto* b = benchmark::RegisterBenchmark(name.c_str(), BM_Curvature, data.get, backend, mode, curvature, 1);
          b->Unit(benchmark::kMillisecond);
          if (backend == NeighbourhoodBackend::flann) b->Iterations(1);
          if (backend == NeighbourhoodBackend::grid && mode == CurvatureMode::stream && curvature) {
            benchmark::RegisterBenchmark((name + "/2threads").c_str(), BM_Curvature, data.get, backend, mode, curvature,
                                         2)
                ->Unit(benchmark::kMillisecond)
                ->UseRealTime();
          }
        }
      }
    }
  }
}

const int registered = (register_all(), 0);

}  // namespace
