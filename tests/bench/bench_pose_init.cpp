// Pose initialisation speed on a typical window: detect_lines (event frame + LSD + merging + refit) and
// initialise_pose (detection + hypotheses + RANSAC with OPnL + support scoring) on 30 ms windows of the planar
// target and the roadheader wireframe at 0.8 m with 1 Hz/px background activity (tests/pose/pose_scenes.hpp,
// seed 1), the prior 10 cm / 20° off. Counters: lines, hypotheses (OPnL solves on minimal sets), events.
//   build-rel/tests/bench/bench_pose_init [--benchmark_format=json]

#include <benchmark/benchmark.h>

#include <random>
#include <string>

#include "evpipe/pose/initialiser.hpp"
#include "evpipe/pose/line_detector.hpp"
#include "pose_scenes.hpp"

namespace {

using namespace evpipe;

const pose_test::Window& window(const std::string& file) {
  static const pose_test::Window planar = [] {
    pose_test::WindowSpec s;
    s.noise_hz = 1.0;
    return pose_test::make_window(s);
  }();
  static const pose_test::Window roadheader = [] {
    pose_test::WindowSpec s;
    s.model_file = "roadheader-wireframe.yaml";
    s.noise_hz = 1.0;
    return pose_test::make_window(s);
  }();
  return file == "planar" ? planar : roadheader;
}

void BM_DetectLines(benchmark::State& state, const std::string& which) {
  const auto& w = window(which);
  pose::LineDetectorOptions o;
  o.camera = w.cam;
  std::size_t lines = 0;
  for (auto _ : state) {
    const auto det = pose::detect_lines(w.events, SensorGeometry{w.cam.width, w.cam.height}, o);
    lines = det.size();
    benchmark::DoNotOptimize(det.data());
  }
  state.counters["lines"] = static_cast<double>(lines);
  state.counters["events"] = static_cast<double>(w.events.size());
}

void BM_InitialisePose(benchmark::State& state, const std::string& which) {
  const auto& w = window(which);
  std::mt19937_64 rng(1);
  camera::PosePrior prior;
  prior.pose = sim::perturb_pose(w.truth, 0.10, 20.0, rng);
  pose::InitialiserOptions o;
  pose::InitResult r;
  for (auto _ : state) {
    r = pose::initialise_pose(w.events, w.cam, w.model, prior, o);
    benchmark::DoNotOptimize(r.T_cam_model.t_cam_model_m.data());
  }
  state.counters["ok"] = r.ok ? 1.0 : 0.0;
  state.counters["lines"] = static_cast<double>(r.lines_detected);
  state.counters["hypotheses"] = static_cast<double>(r.hypotheses);
  state.counters["error_mm"] = camera::translation_distance_m(r.T_cam_model, w.truth) * 1000.0;
  state.counters["error_deg"] = camera::rotation_angle_deg(r.T_cam_model, w.truth);
}

BENCHMARK_CAPTURE(BM_DetectLines, planar, std::string("planar"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_DetectLines, roadheader, std::string("roadheader"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_InitialisePose, planar, std::string("planar"))->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(BM_InitialisePose, roadheader, std::string("roadheader"))->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
