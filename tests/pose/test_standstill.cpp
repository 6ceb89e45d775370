// The standstill monitor (standstill.hpp): the hold's pose bound (pose_change_per_px, what one pixel of motion across
// the held model's edges can stand for in the pose) and the background rate.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <numbers>
#include <random>
#include <vector>

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/pose/projection.hpp"
#include "evpipe/pose/standstill.hpp"
#include "evpipe/sim/target3d.hpp"
#include "evpipe_test_data.hpp"

using namespace evpipe;

// Every pose change (seeded, up to 1 deg / 10 mm) moves the held model's edges across themselves by at least its
// rotation angle / rotation_deg_per_px and its translation / translation_m_per_px pixels RMS (to first order), and
// the planar board's weakest direction (its tilt) is several times weaker than the 3D roadheader's.
TEST(StandstillMonitor, PoseChangePerPixelBoundsEveryPoseChange) {
  const auto cfg = evpipe::testing::source_dir() / "config";
  const camera::CameraModel camera = camera::load_camera((cfg / "davis346.yaml").string());
  double per_px_deg[2] = {0.0, 0.0};
  int k = 0;
  for (const char* file : {"target-planar.yaml", "roadheader-wireframe.yaml"}) {
    SCOPED_TRACE(file);
    const camera::LineModel model = camera::load_line_model((cfg / file).string());
    const camera::Pose T = sim::facing_pose(model, 1.0, sim::default_view(model));
    const pose::PoseChangePerPx per_px = pose::pose_change_per_px(camera, model, T);
    const double deg_per_px = per_px.rotation_deg, m_per_px = per_px.translation_m;
    ASSERT_TRUE(std::isfinite(deg_per_px) && std::isfinite(m_per_px));
    per_px_deg[k++] = deg_per_px;
    std::cout << file << " at 1 m: 1 px RMS across the edges stands for up to " << deg_per_px << " deg / "
              << 1000.0 * m_per_px << " mm\n";
    const auto segs = pose::project_model(camera, model, T);
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    double tightest_rot = 0.0, tightest_trans = 0.0;  // the largest (bound ratio) seen: 1 when attained
    for (int trial = 0; trial < 300; ++trial) {
      const Eigen::Vector3d w =
          Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized() * (std::abs(u(rng)) * 1e-3 * 17.45);
      const Eigen::Vector3d dt = Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized() * (std::abs(u(rng)) * 0.01);
      camera::Pose T1;
      T1.q_cam_model = (Eigen::Quaterniond(Eigen::AngleAxisd(w.norm(), w.normalized())) * T.q_cam_model).normalized();
      T1.t_cam_model_m = T.t_cam_model_m + dt;
      double sum2 = 0.0, n = 0.0;
      for (const auto& s : segs) {
        const Eigen::Vector2d a = camera.normalised_to_pixel(s.a_n), b = camera.normalised_to_pixel(s.b_n);
        const Eigen::Vector2d normal = Eigen::Vector2d(-(b - a).y(), (b - a).x()).normalized();
        for (int i = 0; i < 50; ++i) {
          const Eigen::Vector3d P = s.a_m + (i + 0.5) / 50.0 * (s.b_m - s.a_m);
          const auto p0 = camera.project(T.apply(P)), p1 = camera.project(T1.apply(P));
          if (!p0 || !p1) continue;
          const double d = normal.dot(*p1 - *p0);
          sum2 += d * d * s.length_px;  // weighted by length: the monitor's mean is over edge pixels
          n += s.length_px;
        }
      }
      const double rms_px = std::sqrt(sum2 / n);
      const double angle_deg = w.norm() * 180.0 / std::numbers::pi;
      tightest_rot = std::max(tightest_rot, angle_deg / (deg_per_px * rms_px));
      tightest_trans = std::max(tightest_trans, dt.norm() / (m_per_px * rms_px));
    }
    std::cout << "  largest angle / bound " << tightest_rot << ", translation / bound " << tightest_trans << "\n";
    EXPECT_LE(tightest_rot, 1.05);
    EXPECT_LE(tightest_trans, 1.05);
  }
  EXPECT_GT(per_px_deg[0], 3.0 * per_px_deg[1]);
}

// The background rate (StandstillEvidence::background_rate_hz) is the Poisson noise's alone: on uniform noise it is the
// `far` rate, and a line of clutter in the background band (a monitor's border beside a board) raises the `far` rate
// many times but leaves it near the true rate (its cells are significantly above the others).
TEST(StandstillMonitor, BackgroundRateLeavesStructuredActivityOut) {
  const auto cfg = evpipe::testing::source_dir() / "config";
  const camera::CameraModel camera = camera::load_camera((cfg / "davis346.yaml").string());
  const camera::LineModel model = camera::load_line_model((cfg / "target-planar.yaml").string());
  const camera::Pose T = sim::facing_pose(model, 1.5);
  const pose::UndistortMap map(camera);
  constexpr double kRateHz = 2.0;
  constexpr std::int64_t kWindowUs = 30'000;
  std::mt19937_64 rng(11);
  std::uniform_int_distribution<int> ux(0, camera.width - 1), uy(0, camera.height - 1);
  std::uniform_int_distribution<std::int64_t> ut(0, kWindowUs - 1);
  std::vector<Event> noise;
  const auto n_noise = static_cast<std::size_t>(kRateHz * camera.width * camera.height * 1e-6 * kWindowUs);
  for (std::size_t i = 0; i < n_noise; ++i) {
    noise.push_back(Event{ut(rng), static_cast<std::uint16_t>(ux(rng)), static_cast<std::uint16_t>(uy(rng)), true});
  }
  // The clutter: a vertical line 25-30 px right of the model's right edge, 20 events per pixel along it.
  const auto segs = pose::project_model(camera, model, T);
  double right = 0.0;
  for (const auto& s : segs) right = std::max({right, s.segment_px.a_px.x(), s.segment_px.b_px.x()});
  std::vector<Event> cluttered = noise;
  const int x_clutter = static_cast<int>(right) + 27;
  for (int y = camera.height / 4; y < 3 * camera.height / 4; ++y) {
    for (int k = 0; k < 20; ++k) {
      cluttered.push_back(Event{ut(rng), static_cast<std::uint16_t>(x_clutter), static_cast<std::uint16_t>(y), true});
    }
  }
  for (auto* events : {&noise, &cluttered}) {
    std::sort(events->begin(), events->end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  }
  pose::StandstillMonitor m;
  ASSERT_TRUE(m.start(camera, map, model, T, pose::StandstillOptions{}));
  const pose::StandstillEvidence plain = m.observe(noise, kWindowUs, 0, kWindowUs);
  ASSERT_TRUE(m.start(camera, map, model, T, pose::StandstillOptions{}));
  const pose::StandstillEvidence clutter = m.observe(cluttered, kWindowUs, 0, kWindowUs);
  std::cout << "far rate " << plain.noise_rate_hz << " / " << clutter.noise_rate_hz << " Hz, background "
            << plain.background_rate_hz << " / " << clutter.background_rate_hz << " Hz (true " << kRateHz << ")\n";
  EXPECT_NEAR(plain.background_rate_hz, kRateHz, 0.3 * kRateHz);
  EXPECT_NEAR(plain.background_rate_hz, plain.noise_rate_hz, 0.1 * kRateHz);
  EXPECT_GT(clutter.noise_rate_hz, 3.0 * kRateHz);
  EXPECT_NEAR(clutter.background_rate_hz, kRateHz, 0.3 * kRateHz);
}
