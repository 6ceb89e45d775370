// Pose verification (issue 21): supported along its length, beating the scene's other structure, 6 DoF fixed.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <optional>
#include <random>

#include "evpipe/camera/trajectory.hpp"
#include "evpipe/io/reader.hpp"
#include "evpipe/pose/estimator.hpp"
#include "evpipe/pose/tracker.hpp"
#include "evpipe/pose/verification.hpp"
#include "evpipe/sim/noise.hpp"
#include "evpipe/sim/target3d.hpp"
#include "evpipe_test_data.hpp"

using namespace evpipe;

namespace {

EventSpan slice(const std::vector<Event>& ev, std::int64_t t0, std::int64_t t1) {
  const auto lo = std::lower_bound(ev.begin(), ev.end(), t0, [](const Event& e, std::int64_t t) { return e.t_us < t; });
  const auto hi = std::lower_bound(lo, ev.end(), t1, [](const Event& e, std::int64_t t) { return e.t_us < t; });
  return {lo, hi};
}

struct Scene {
  sim::TargetScene scene;
  std::vector<Event> events;
  Scene(const std::string& model_file, double distance_m, std::uint64_t seed, std::int64_t duration_us,
        double noise_hz = 0.0) {
    const auto cfg = evpipe::testing::source_dir() / "config";
    scene.camera = camera::load_camera((cfg / "davis346.yaml").string());
    scene.model = camera::load_line_model((cfg / model_file).string());
    sim::MotionOptions mo;
    mo.base = sim::facing_pose(scene.model, distance_m, sim::default_view(scene.model));
    mo.pivot_model_m = sim::bbox_centre(scene.model);
    std::mt19937_64 rng(seed);
    scene.trajectory = sim::generate_motion(0, duration_us, mo, rng);
    events = sim::render_target(scene, 0, duration_us, rng);
    if (noise_hz > 0.0) {
      std::mt19937_64 noise_rng(seed + 1);
      sim::NoiseOptions no;
      no.rate_hz_per_pixel = noise_hz;
      const auto noise = sim::background_activity(SensorGeometry{scene.camera.width, scene.camera.height}, 0,
                                                  duration_us, no, noise_rng);
      events.insert(events.end(), noise.begin(), noise.end());
      std::stable_sort(events.begin(), events.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
    }
  }
};

}  // namespace

TEST(PoseVerifyExperiment, Synthetic) {
  for (const char* m : {"target-planar.yaml", "roadheader-wireframe.yaml"}) {
    const Scene s(m, 0.8, 20261121, 600000);
    for (std::int64_t t = 15000; t + 15000 < 600000; t += 60000) {
      const EventSpan w = slice(s.events, t - 15000, t + 15000);
      const auto T = *camera::interpolate(s.scene.trajectory, t);
      const auto Tb = *camera::interpolate(s.scene.trajectory, std::max<std::int64_t>(t - 30000, 0));
      const auto v =
          pose::verify_pose(w, s.scene.camera, s.scene.model, T, {},
                            pose::MotionHint{camera::StampedPose{std::max<std::int64_t>(t - 30000, 0), Tb}, t});
      const auto v0 = pose::verify_pose(w, s.scene.camera, s.scene.model, T, {});
      std::cout << m << " " << t << " n=" << w.size() << " ok=" << v.ok << " cov=" << v.coverage << " seg "
                << v.segments_supported << "/" << v.segments_required << "/" << v.segments_judged
                << " thr=" << v.support_threshold << " std " << v.rotation_std_deg << "deg "
                << v.translation_std_m * 1000 << "mm " << v.reason << " | nohint ok=" << v0.ok << " " << v0.reason
                << "\n";
      for (const auto& sg : v.segments)
        std::cout << "  s" << sg.model_index << " " << sg.supported << "/" << sg.cells << " nm=" << sg.normal_motion_px;
      std::cout << "\n";
    }
  }
}

TEST(PoseVerifyExperiment, RealPanTilt) {
  EVPIPE_REQUIRE_REAL(dir, "davis240-evbench-checkerboard/seq_0003");
  const auto cam = camera::load_camera(dir + "/camera.yaml");
  const auto model = camera::load_line_model(dir + "/model.yaml");
  const auto gt = camera::read_trajectory_csv(dir + "/gt.csv");
  const auto batch = io::read_all(dir + "/events.aedat4");
  const auto& ev = batch.events;
  for (std::int64_t t = gt.front().t_us + 15000; t + 15000 < gt.back().t_us; t += 90000) {
    const EventSpan w = slice(ev, t - 15000, t + 15000);
    const auto T = camera::interpolate(gt, t);
    const auto Tb = camera::interpolate(gt, t - 30000);
    pose::MotionHint hint{camera::StampedPose{t - 30000, *Tb}, t};
    const auto v = pose::verify_pose(w, cam, model, *T, {}, hint);
    const auto v0 = pose::verify_pose(w, cam, model, *T, {});
    const auto u = pose::track_window(w, cam, model, *T);
    std::cout << t << " n=" << w.size() << " gt: ok=" << v.ok << " cov=" << v.coverage << " seg "
              << v.segments_supported << "/" << v.segments_required << " thr=" << v.support_threshold
              << " noise=" << v.noise_per_cell << " std " << v.rotation_std_deg << "deg " << v.translation_std_m * 1000
              << "mm | nohint ok=" << v0.ok << " cov=" << v0.coverage << " " << v0.reason
              << "\n   track from gt: healthy=" << u.healthy
              << " d=" << 1000 * camera::translation_distance_m(u.T_cam_model, *T)
              << "mm a=" << camera::rotation_angle_deg(u.T_cam_model, *T) << " sigma=" << u.sigma_px
              << " inl=" << u.inliers << " " << u.reason << "\n";
    const auto vu = pose::verify_pose(w, cam, model, u.T_cam_model, {}, hint);
    for (const auto& sg : v.segments)
      std::cout << "  seg" << sg.model_index << " " << sg.supported << "/" << sg.cells << " nm=" << sg.normal_motion_px;
    std::cout << "\n";
    std::cout << "   verify(tracked) ok=" << vu.ok << " cov=" << vu.coverage << " " << vu.reason << "\n";
  }
}
