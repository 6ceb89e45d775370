// Pose solver speed: OPnL full solve (the three pre-rotated algebraic solves + selection + Ceres refinement; the
// fallback enabled but not triggered on these scenes) for n = 4, 10, 20 lines, and its parts: the algebraic solve
// alone, the refinement alone, and the 24-start LM fallback alone. Scenes: protocol of pose.md §6.1 (640×480,
// f = 800, depth 4-8 m, σ = 1 px), 32 per size, generated once outside the timed loop (seed 1) and cycled.
// Issue 5 goal: full solve <= 2 ms.
//   build-rel/tests/bench/bench_pose [--benchmark_format=json]

#include <benchmark/benchmark.h>

#include <Eigen/Geometry>

#include <random>
#include <vector>

#include "evpipe/pose/line_refine.hpp"
#include "evpipe/pose/opnl.hpp"

namespace {

using namespace evpipe;

struct Scene {
  std::vector<pose::LineCorrespondence> lines;
  camera::Pose T_gt;
};

std::vector<Scene> make_scenes(int n, int count) {
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(0.0, 640.0);
  std::uniform_real_distribution<double> v(0.0, 480.0);
  std::uniform_real_distribution<double> depth(4.0, 8.0);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Scene> out;
  for (int k = 0; k < count; ++k) {
    Scene s;
    s.T_gt.q_cam_model = Eigen::Quaterniond(g(rng), g(rng), g(rng), g(rng)).normalized();
    std::vector<Eigen::Vector2d> px;
    std::vector<Eigen::Vector3d> X;
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int i = 0; i < 2 * n; ++i) {
      px.emplace_back(u(rng), v(rng));
      X.push_back(depth(rng) * Eigen::Vector3d((px.back().x() - 320.0) / 800.0, (px.back().y() - 240.0) / 800.0, 1.0));
      c += X.back() / (2.0 * n);
    }
    s.T_gt.t_cam_model_m = c;
    const Eigen::Matrix3d Rt = s.T_gt.rotation().transpose();
    for (int i = 0; i < n; ++i) {
      pose::LineCorrespondence lc;
      const auto a = static_cast<std::size_t>(2 * i);
      lc.model.a_m = Rt * (X[a] - c);
      lc.model.b_m = Rt * (X[a + 1] - c);
      const Eigen::Vector2d pa = px[a] + Eigen::Vector2d(g(rng), g(rng));
      const Eigen::Vector2d pb = px[a + 1] + Eigen::Vector2d(g(rng), g(rng));
      lc.image.a_n = (pa - Eigen::Vector2d(320.0, 240.0)) / 800.0;
      lc.image.b_n = (pb - Eigen::Vector2d(320.0, 240.0)) / 800.0;
      s.lines.push_back(lc);
    }
    out.push_back(s);
  }
  return out;
}

void run_opnl(benchmark::State& state, const pose::OpnlOptions& options) {
  const std::vector<Scene> scenes = make_scenes(static_cast<int>(state.range(0)), 32);
  std::size_t k = 0;
  std::size_t fallbacks = 0;
  for (auto _ : state) {
    const pose::OpnlResult r = pose::solve_opnl(scenes[k % scenes.size()].lines, options);
    fallbacks += r.used_fallback ? 1 : 0;
    benchmark::DoNotOptimize(r);
    ++k;
  }
  state.counters["fallback_share"] = static_cast<double>(fallbacks) / static_cast<double>(k);
}

void BM_OpnlFull(benchmark::State& state) {
  pose::OpnlOptions o;
  o.fallback_rms_n = 3.0 / 800.0;
  run_opnl(state, o);
}
BENCHMARK(BM_OpnlFull)->Arg(4)->Arg(10)->Arg(20)->Unit(benchmark::kMicrosecond);

void BM_OpnlAlgebraicOnly(benchmark::State& state) {
  pose::OpnlOptions o;
  o.refine = false;
  o.fallback = false;
  run_opnl(state, o);
}
BENCHMARK(BM_OpnlAlgebraicOnly)->Arg(4)->Arg(10)->Arg(20)->Unit(benchmark::kMicrosecond);

void BM_OpnlFallbackOnly(benchmark::State& state) {
  pose::OpnlOptions o;
  o.algebraic = false;
  run_opnl(state, o);
}
BENCHMARK(BM_OpnlFallbackOnly)->Arg(4)->Arg(10)->Arg(20)->Unit(benchmark::kMicrosecond);

void BM_RefineFromTruth(benchmark::State& state) {
  const std::vector<Scene> scenes = make_scenes(static_cast<int>(state.range(0)), 32);
  std::size_t k = 0;
  for (auto _ : state) {
    const Scene& s = scenes[k % scenes.size()];
    benchmark::DoNotOptimize(pose::refine_pose_lines(s.lines, s.T_gt));
    ++k;
  }
}
BENCHMARK(BM_RefineFromTruth)->Arg(4)->Arg(10)->Arg(20)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
