// Stop-and-go motion (time warp) and the clutter of the 3D scenes (docs/simulation.md "Stops", "Distractors").
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "evpipe/camera/line_model.hpp"
#include "evpipe/sim/distractors.hpp"
#include "evpipe/sim/target3d.hpp"
#include "evpipe_test_data.hpp"

using namespace evpipe;

namespace {

TEST(MotionStops, TimeWarpPausesAndContinues) {
  const std::vector<sim::MotionStop> stops = {{1.0, 2.0}, {4.0, 0.5}};
  const double r = 0.1;
  EXPECT_DOUBLE_EQ(sim::motion_time_s(0.5, stops, r), 0.5);
  // Standing still: constant motion time over the stop.
  const double still = sim::motion_time_s(1.0, stops, r);
  EXPECT_NEAR(still, 1.0 - 0.05, 1e-12);  // the slow-down ramp loses r / 2
  EXPECT_DOUBLE_EQ(sim::motion_time_s(2.0, stops, r), still);
  EXPECT_DOUBLE_EQ(sim::motion_time_s(2.999, stops, r), still);
  // After both stops: 2 + 0.5 s still and 4 ramps of r / 2 lost.
  EXPECT_NEAR(sim::motion_time_s(6.0, stops, r), 6.0 - 2.5 - 0.2, 1e-12);
  // Monotonic, continuous, never faster than real time.
  double prev = sim::motion_time_s(0.0, stops, r);
  for (int i = 1; i <= 7000; ++i) {
    const double t = i * 1e-3;
    const double m = sim::motion_time_s(t, stops, r);
    EXPECT_GE(m, prev - 1e-12);
    EXPECT_LE(m - prev, 1e-3 + 1e-12);
    prev = m;
  }
  EXPECT_THROW((void)sim::motion_time_s(0.0, {{1.0, 1.0}, {2.05, 1.0}}, r), std::invalid_argument);  // overlap
  EXPECT_THROW((void)sim::motion_time_s(0.0, {{1.0, -1.0}}, r), std::invalid_argument);
}

struct Scene {
  camera::CameraModel cam;
  camera::LineModel model;
  sim::MotionOptions mo;
  Scene(const std::string& model_file, double distance_m) {
    const auto cfg = evpipe::testing::source_dir() / "config";
    cam = camera::load_camera((cfg / "davis346.yaml").string());
    model = camera::load_line_model((cfg / model_file).string());
    mo.base = sim::facing_pose(model, distance_m, sim::default_view(model));
    mo.pivot_model_m = sim::bbox_centre(model);
  }
};

TEST(MotionStops, GroundTruthStandsStillAndTheBoundsHold) {
  Scene s("target-planar.yaml", 0.8);
  s.mo.stops = {{0.5, 1.0}};
  std::mt19937_64 rng(3), rng_plain(3);
  const auto traj = sim::generate_motion(0, 2'500'000, s.mo, rng);
  sim::MotionOptions plain = s.mo;
  plain.stops.clear();
  const auto ref = sim::generate_motion(0, 2'500'000, plain, rng_plain);
  ASSERT_EQ(traj.size(), ref.size());
  // Before the slow-down the motion is the unstopped one; during the stop every row is the same pose.
  for (std::size_t i = 0; i < 400; ++i) EXPECT_TRUE(traj[i].pose.t_cam_model_m.isApprox(ref[i].pose.t_cam_model_m));
  for (std::size_t i = 500; i <= 1500; ++i) {
    EXPECT_LT((traj[i].pose.t_cam_model_m - traj[500].pose.t_cam_model_m).norm(), 1e-12);
    EXPECT_LT(traj[i].pose.q_cam_model.angularDistance(traj[500].pose.q_cam_model), 1e-12);
  }
  // The speed never exceeds the bound (the stop only slows the motion down).
  for (std::size_t i = 1; i < traj.size(); ++i) {
    const Eigen::Vector3d& c = s.mo.pivot_model_m;  // the pivot moves by the translation part only
    const double v = (traj[i].pose.apply(c) - traj[i - 1].pose.apply(c)).norm() / 1e-3;
    EXPECT_LE(v, s.mo.max_speed_m_s * 1.001);
  }
  // A stopped target gives no event while still.
  sim::TargetScene ts{s.cam, s.model, traj, {}};
  std::mt19937_64 sig(1);
  const auto ev = sim::render_target(ts, 0, 2'500'000, sig);
  const auto still =
      std::count_if(ev.begin(), ev.end(), [](const Event& e) { return e.t_us >= 600'000 && e.t_us < 1'400'000; });
  EXPECT_EQ(still, 0);
  EXPECT_GT(ev.size(), 1000u);
}

TEST(MotionStops, SlowMotionReachesItsBounds) {
  // --max-speed-m-s 0.01 .. 0.08 and <= 12 deg/s: the generated speeds stay below and reach a good share of them.
  for (const double vmax : {0.01, 0.08}) {
    Scene s("roadheader-wireframe.yaml", 1.0);
    s.mo.max_speed_m_s = vmax;
    s.mo.max_angular_speed_deg_s = 12.0;
    s.mo.pivot_model_m = sim::bbox_centre(s.model);
    std::mt19937_64 rng(5);
    const auto traj = sim::generate_motion(0, 10'000'000, s.mo, rng);
    double vpeak = 0, wpeak = 0;
    for (std::size_t i = 1; i < traj.size(); ++i) {
      const auto& a = traj[i - 1].pose;
      const auto& b = traj[i].pose;
      // Speed of the pivot (the model's centre), and the angular speed.
      const double v = (b.apply(s.mo.pivot_model_m) - a.apply(s.mo.pivot_model_m)).norm() / 1e-3;
      const double w = camera::rotation_angle_deg(a, b) / 1e-3;
      vpeak = std::max(vpeak, v);
      wpeak = std::max(wpeak, w);
    }
    EXPECT_LE(vpeak, vmax * 1.001);
    EXPECT_GT(vpeak, 0.3 * vmax);
    EXPECT_LE(wpeak, 12.0 * 1.001);
  }
}

std::vector<Event> render_body(const Scene& s, const sim::DistractorBody& b) {
  sim::TargetScene ts{s.cam, b.model, b.trajectory, {}};
  std::mt19937_64 rng(9);
  return sim::render_target(ts, b.trajectory.front().t_us, b.trajectory.back().t_us, rng);
}

TEST(Distractors, EveryKindIsPlacedBesideTheTargetAndRendersAsEdges) {
  for (const auto& [file, dist] : {std::pair<std::string, double>{"target-planar.yaml", 0.8},
                                   std::pair<std::string, double>{"roadheader-wireframe.yaml", 1.0}}) {
    Scene s(file, dist);
    std::mt19937_64 rng(2);
    const auto traj = sim::generate_motion(0, 1'000'000, s.mo, rng);
    const auto box = sim::target_image_box(s.cam, s.model, traj.front().pose);
    EXPECT_GT(box.width(), 20.0);
    for (const auto kind : {sim::DistractorKind::lines, sim::DistractorKind::moving_lines, sim::DistractorKind::decoy,
                            sim::DistractorKind::decoy_static}) {
      std::mt19937_64 mrng(4);
      const auto body = sim::make_distractor_body(kind, s.cam, s.model, traj, s.mo, mrng);
      EXPECT_EQ(body.model.segments_m.size(), 4u);  // 3 bars + a diagonal, or a rectangle
      const auto ev = render_body(s, body);
      if (kind == sim::DistractorKind::decoy_static) {
        EXPECT_TRUE(ev.empty()) << "a body fixed to a fixed camera is invisible";
      } else {
        EXPECT_GT(ev.size(), 500u) << sim::to_string(kind) << " " << file;
      }
      // Deterministic.
      std::mt19937_64 mrng2(4);
      const auto again = sim::make_distractor_body(kind, s.cam, s.model, traj, s.mo, mrng2);
      EXPECT_EQ(render_body(s, again).size(), ev.size());
    }
    // The decoy is a rectangle at 1.5 x the target's depth.
    std::mt19937_64 mrng(4);
    const auto decoy = sim::make_distractor_body(sim::DistractorKind::decoy_static, s.cam, s.model, traj, s.mo, mrng);
    const double z_target = traj.front().pose.apply(sim::bbox_centre(s.model)).z();
    for (const auto& seg : decoy.model.segments_m) EXPECT_NEAR(seg.a_m.z(), 1.5 * z_target, 1e-9);
  }
  EXPECT_EQ(sim::distractor_kind("moving-lines"), sim::DistractorKind::moving_lines);
  EXPECT_THROW((void)sim::distractor_kind("tree"), std::invalid_argument);
}

TEST(Distractors, FlickerFiresOnAndOffInItsPatchAtItsRate) {
  const sim::ImageBox patch{300, 200, 310, 210};
  sim::FlickerOptions o;
  o.rate_hz = 100;
  std::mt19937_64 rng(7);
  const auto ev = sim::flicker_events(patch, 0, 1'000'000, o, 3, 20.0, rng);
  // 100 pixels x 200 transitions x 3 events, give or take the transitions cut at the ends.
  EXPECT_NEAR(static_cast<double>(ev.size()), 100.0 * 200 * 3, 100.0 * 3 * 2 + 1);
  std::set<std::pair<int, int>> pixels;
  std::size_t on = 0;
  for (const auto& e : ev) {
    EXPECT_GE(e.x, 300);
    EXPECT_LT(e.x, 310);
    EXPECT_GE(e.y, 200);
    EXPECT_LT(e.y, 210);
    pixels.insert({e.x, e.y});
    on += e.polarity ? 1 : 0;
  }
  EXPECT_EQ(pixels.size(), 100u);
  EXPECT_NEAR(static_cast<double>(on) / static_cast<double>(ev.size()), 0.5, 0.01);
  EXPECT_TRUE(std::is_sorted(ev.begin(), ev.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; }));
}

}  // namespace
