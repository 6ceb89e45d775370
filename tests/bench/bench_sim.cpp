// Generation speed of the simulator (libs/sim): counters "events/s" (events generated per second of wall time)
// and "sim_s/s" (simulated seconds per second of wall time; > 1 is faster than real time), per call on 1 s of
// simulated time. The 3D scenes are those of tools/make_scenes.sh (planar target at 0.8 m, roadheader at
// 1.0 m, default views and motion, seed 1); the motion is generated once, outside the timed loop.
//   build-rel/tests/bench/bench_sim [--benchmark_format=json]

#include <benchmark/benchmark.h>

#include <cstdint>
#include <random>
#include <string>

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/sim/noise.hpp"
#include "evpipe/sim/scene2d.hpp"
#include "evpipe/sim/target3d.hpp"

namespace {

using namespace evpipe;

constexpr std::int64_t kSpan_us = 1'000'000;

void report(benchmark::State& state, std::size_t events_per_call) {
  const auto n = static_cast<double>(state.iterations());
  state.counters["events/s"] =
      benchmark::Counter(n * static_cast<double>(events_per_call), benchmark::Counter::kIsRate);
  state.counters["sim_s/s"] = benchmark::Counter(n * static_cast<double>(kSpan_us) * 1e-6, benchmark::Counter::kIsRate);
  state.counters["events"] = static_cast<double>(events_per_call);
}

sim::TargetScene target_scene(const std::string& model_file, double distance_m) {
  const std::string cfg = std::string(EVPIPE_SOURCE_DIR) + "/config/";
  sim::TargetScene scene;
  scene.camera = camera::load_camera(cfg + "davis346.yaml");
  scene.model = camera::load_line_model(cfg + model_file);
  sim::MotionOptions mo;
  mo.base = sim::facing_pose(scene.model, distance_m, sim::default_view(scene.model));
  mo.pivot_model_m = sim::bbox_centre(scene.model);
  std::mt19937_64 rng(1);
  scene.trajectory = sim::generate_motion(0, kSpan_us, mo, rng);
  return scene;
}

void BM_RenderTarget(benchmark::State& state, const std::string& model_file, double distance_m) {
  const auto scene = target_scene(model_file, distance_m);
  std::size_t events = 0;
  for (auto _ : state) {
    std::mt19937_64 rng(2);
    const auto ev = sim::render_target(scene, 0, kSpan_us, rng);
    events = ev.size();
    benchmark::DoNotOptimize(ev.data());
  }
  report(state, events);
}
BENCHMARK_CAPTURE(BM_RenderTarget, planar_0_8m, std::string("target-planar.yaml"), 0.8)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_RenderTarget, roadheader_1_0m, std::string("roadheader-wireframe.yaml"), 1.0)
    ->Unit(benchmark::kMillisecond);

void BM_Render2D(benchmark::State& state) {
  const auto scene = sim::named_scene("demo");
  std::size_t events = 0;
  for (auto _ : state) {
    std::mt19937_64 rng(1);
    const auto ev = sim::render(scene, 0, kSpan_us, {}, rng);
    events = ev.size();
    benchmark::DoNotOptimize(ev.data());
  }
  report(state, events);
}
BENCHMARK(BM_Render2D)->Name("BM_Render2D/demo")->Unit(benchmark::kMillisecond);

void BM_BackgroundActivity(benchmark::State& state) {
  sim::NoiseOptions o;
  o.rate_hz_per_pixel = static_cast<double>(state.range(0));
  std::size_t events = 0;
  for (auto _ : state) {
    std::mt19937_64 rng(3);
    const auto ev = sim::background_activity(kDavis346, 0, kSpan_us, o, rng);
    events = ev.size();
    benchmark::DoNotOptimize(ev.data());
  }
  report(state, events);
}
BENCHMARK(BM_BackgroundActivity)->ArgName("hz_per_pixel")->Arg(1)->Arg(10)->Unit(benchmark::kMillisecond);

}  // namespace
