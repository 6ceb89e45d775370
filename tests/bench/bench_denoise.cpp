// Throughput of the denoising baselines through the Filter interface (counter "Mev/s"), in the calling pattern of
// dv-processing's benchmark (denoise.md §8.5): a fresh filter per pass, pushes of 10 000 events, the decisions of
// each push consumed (kept events counted) before the next.
//   real:      the E-MLB demo recording (../shared/data/real/emlb-demo-01/demo-01.aedat4) tiled 16× end to end
//              (5.1 M events, 8.2 s); not registered when the file is absent.
//   synthetic: 346×260, 2 Hz/px uniform background activity plus four tilted bars sweeping at 400 px/s
//              (≈ 4.7 M events, 24 % noise, 6.3 s), generated at start-up with libs/sim (a few seconds).
//   synth10:   bench_curvature's 10 Mev/s stream (12 rotating bars with exact edge times plus 5 Hz/px background
//              activity, 0.3 s), for the pipeline default's 12 Mev/s goal (issue 18).
//   build-rel/tests/bench/bench_denoise [--benchmark_filter=knoise] [--benchmark_repetitions=3]
// tools/bench_denoise_vs_dv.py compares with dv-processing in one run on the same events.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "evpipe/denoise/registry.hpp"
#include "evpipe/io/reader.hpp"
#include "evpipe/sim/noise.hpp"
#include "evpipe/sim/recording.hpp"
#include "evpipe/sim/scene2d.hpp"
#include "rotating_bars.hpp"

namespace {

using namespace evpipe;
using Settings = std::vector<std::pair<std::string, std::string>>;

constexpr std::size_t kChunk = 10'000;

struct Dataset {
  std::string name;
  std::vector<Event> events;
  SensorGeometry geometry;
};

std::vector<Event> tile(const std::vector<Event>& once, int copies, std::int64_t period_us) {
  std::vector<Event> out;
  out.reserve(once.size() * static_cast<std::size_t>(copies));
  for (int k = 0; k < copies; ++k) {
    for (Event e : once) {
      e.t_us += period_us * k;
      out.push_back(e);
    }
  }
  return out;
}

bool load_real(Dataset& d) {
  const std::string path = EVPIPE_DEMO_RECORDING;
  if (!std::filesystem::exists(path)) {
    std::fprintf(stderr, "bench_denoise: %s absent: real-data benchmarks not registered\n", path.c_str());
    return false;
  }
  auto reader = io::open_reader(path);
  std::vector<Event> once;
  while (auto batch = reader->next()) {
    once.insert(once.end(), batch->events.begin(), batch->events.end());
  }
  d.name = "real";
  d.geometry = reader->info().geometry;
  d.events = tile(once, 16, once.back().t_us - once.front().t_us + 1);
  return true;
}

Dataset synthetic() {
  Dataset d;
  d.name = "synthetic";
  d.geometry = kDavis346;
  // Four bars 8 px wide, tilted by 0.3 rad, moving right at 400 px/s, spaced a quarter of a loop apart; each has a
  // copy one loop behind, so the scene after one loop equals the scene at its start and the loop tiles seamlessly.
  constexpr double kMargin = 80.0;
  const double loop_px = d.geometry.width + 2 * kMargin;
  const auto loop_us = static_cast<std::int64_t>(loop_px / 400.0 * 1e6);
  sim::Scene2D scene;
  scene.geometry = d.geometry;
  constexpr int kBars = 4;
  for (int i = 0; i < kBars; ++i) {
    for (int copy = 0; copy < 2; ++copy) {
      auto bar = sim::make_rectangle(8, 400);
      bar.cx_px = -kMargin + i * loop_px / kBars - copy * loop_px;
      bar.cy_px = d.geometry.height / 2.0;
      bar.angle0_rad = 0.3;
      bar.vx_px_s = 400.0;
      scene.shapes.push_back(bar);
    }
  }
  std::mt19937_64 rng(1);
  constexpr int kLoops = 5;
  const auto signal = tile(sim::render(scene, 0, loop_us, {}, rng), kLoops, loop_us);
  sim::NoiseOptions noise_options;
  noise_options.rate_hz_per_pixel = 2.0;
  const auto noise = sim::background_activity(d.geometry, 0, loop_us * kLoops, noise_options, rng);
  d.events.resize(signal.size() + noise.size());
  std::merge(signal.begin(), signal.end(), noise.begin(), noise.end(), d.events.begin(),
             [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  return d;
}

/// bench_curvature's synth10: 12 rotating bars at ≈ 9.5 Mev/s plus 5 Hz/px noise, 0.3 s.
Dataset synth10() {
  Dataset d;
  d.name = "synth10";
  d.geometry = kDavis346;
  const auto signal = testing::rotating_bar_events(testing::bar_grid(230.0), kDavis346, 0, 300'000);
  std::mt19937_64 rng(7);
  sim::NoiseOptions no;
  no.rate_hz_per_pixel = 5.0;
  const auto noise = sim::background_activity(kDavis346, 0, 300'000, no, rng);
  d.events = sim::merge_labelled(signal, noise).events;
  return d;
}

void run(benchmark::State& state, const Dataset* d, const std::string& filter, const Settings& settings) {
  std::size_t kept = 0;
  for (auto _ : state) {
    auto f = denoise::make_filter_chain(filter, settings, d->geometry);
    denoise::Decisions out;
    out.keep.reserve(kChunk);
    out.score.reserve(kChunk);
    kept = 0;
    for (std::size_t i = 0; i < d->events.size(); i += kChunk) {
      out.clear();
      f->push(EventSpan(d->events).subspan(i, std::min(kChunk, d->events.size() - i)), out);
      kept += denoise::count_kept(out);
    }
    out.clear();
    f->finish(out);  // a look-ahead filter's last decisions
    kept += denoise::count_kept(out);
    benchmark::DoNotOptimize(kept);
  }
  const auto n = static_cast<double>(d->events.size());
  state.counters["Mev/s"] = benchmark::Counter(n * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
  state.counters["kept_%"] = 100.0 * static_cast<double>(kept) / n;
  state.counters["events"] = n;
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  static std::vector<Dataset> datasets;
  datasets.reserve(3);
  Dataset real;
  if (load_real(real)) {
    datasets.push_back(std::move(real));
  }
  datasets.push_back(synthetic());
  datasets.push_back(synth10());
  const std::vector<std::pair<std::string, Settings>> filters = {
      {"baf", {}},
      {"baf", {{"duration_us", "10000"}}},
      {"knoise", {}},
      {"knoise", {{"variant", "cuke"}}},
      {"ynoise", {}},
      {"stcf", {}},
      {"dwf", {}},
      {"dwf", {{"variant", "jaer"}}},
      {"hotpixel", {}},
      {"significance", {}},
      {"significance", {{"exact_scores", "false"}}},  // as the pipeline runs it (same decisions)
      {"significance", {{"lookahead_us", "0"}}},      // the causal option
      {"significance", {{"surface", "false"}}},       // without the edge-surface test (its cost)
  };
  for (const Dataset& d : datasets) {
    std::fprintf(stderr, "bench_denoise: %s: %zu events, %.2f s\n", d.name.c_str(), d.events.size(),
                 static_cast<double>(d.events.back().t_us - d.events.front().t_us) * 1e-6);
    for (const auto& [filter, settings] : filters) {
      std::string name = "denoise/" + d.name + "/" + filter;
      for (const auto& [k, v] : settings) {
        name += "/" + k + "=" + v;
      }
      benchmark::RegisterBenchmark(name.c_str(), run, &d, filter, settings)
          ->Unit(benchmark::kMillisecond)
          ->UseRealTime();
    }
  }
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
