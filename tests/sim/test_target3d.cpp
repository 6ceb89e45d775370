#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <map>

#include "evpipe/camera/line_model.hpp"
#include "evpipe/sim/target3d.hpp"
#include "evpipe_test_data.hpp"

using namespace evpipe;

namespace {

struct Fixture {
  sim::TargetScene scene;
  Fixture(const std::string& model_file, double distance_m, const Eigen::Quaterniond& R, std::uint64_t seed) {
    const auto cfg = evpipe::testing::source_dir() / "config";
    scene.camera = camera::load_camera((cfg / "davis346.yaml").string());
    scene.model = camera::load_line_model((cfg / model_file).string());
    sim::MotionOptions mo;
    mo.base = sim::facing_pose(scene.model, distance_m, R);
    mo.pivot_model_m = sim::bbox_centre(scene.model);
    std::mt19937_64 rng(seed);
    scene.trajectory = sim::generate_motion(0, 1'000'000, mo, rng);
  }
};

// Distance (pixels) from a pixel centre to the image of a model segment at pose T.
// p: the pixel centre in normalised undistorted coordinates.
double distance_px(const camera::CameraModel& cam, const camera::Pose& T, const camera::Segment3& s,
                   const Eigen::Vector2d& p) {
  const Eigen::Vector3d a = T.apply(s.a_m), b = T.apply(s.b_m);
  const Eigen::Vector2d an = a.head<2>() / a.z(), bn = b.head<2>() / b.z();
  const Eigen::Vector2d ab = bn - an;
  const double u = std::clamp((p - an).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
  return (p - (an + u * ab)).norm() * 0.5 * (cam.fx + cam.fy);
}

camera::Pose pose_at(const std::vector<camera::StampedPose>& traj, std::int64_t t) {
  auto it = std::lower_bound(traj.begin(), traj.end(), t,
                             [](const camera::StampedPose& p, std::int64_t v) { return p.t_us < v; });
  if (it == traj.begin()) return it->pose;
  if (it == traj.end()) return traj.back().pose;
  return camera::interpolate(*(it - 1), *it, t);
}

}  // namespace

TEST(Target3D, EverySignalEventLiesWithinOnePointFivePixelsOfAProjectedSegment) {
  const Eigen::Quaterniond side_view(Eigen::AngleAxisd(-M_PI / 2, Eigen::Vector3d::UnitX()) *
                                     Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitZ()));
  for (const auto& [file, R] : {std::pair{std::string("target-planar.yaml"), Eigen::Quaterniond::Identity()},
                                std::pair{std::string("roadheader-wireframe.yaml"), side_view}}) {
    const std::uint64_t seed = 42;
    SCOPED_TRACE(::testing::Message() << file << " seed=" << seed);
    Fixture fx(file, file == "target-planar.yaml" ? 0.8 : 1.6, R, seed);
    std::mt19937_64 rng(seed);
    const auto ev = sim::render_target(fx.scene, 0, 1'000'000, rng);
    ASSERT_GT(ev.size(), 10'000U);
    std::size_t on = 0;
    double worst = 0;
    for (std::size_t i = 0; i < ev.size(); ++i) {
      const auto& e = ev[i];
      if (i) {
        ASSERT_LE(ev[i - 1].t_us, e.t_us);
      }
      const auto T = pose_at(fx.scene.trajectory, e.t_us);
      const Eigen::Vector2d p = fx.scene.camera.pixel_to_normalised(Eigen::Vector2d(e.x, e.y));
      double d = 1e9;
      for (const auto& s : fx.scene.model.segments_m) d = std::min(d, distance_px(fx.scene.camera, T, s, p));
      worst = std::max(worst, d);
      on += e.polarity;
    }
    std::cout << file << ": " << ev.size() << " events, worst distance to the model " << worst << " px\n";
    EXPECT_LE(worst, 1.5);
    // Both polarities occur (bright sides are random per segment, motion goes both ways).
    EXPECT_GT(on, ev.size() / 10);
    EXPECT_LT(on, ev.size() * 9 / 10);
  }
}

TEST(Target3D, StrongEdgesFireMoreThanOnceAndRefractoryHolds) {
  Fixture fx("target-planar.yaml", 0.8, Eigen::Quaterniond::Identity(), 3);
  fx.scene.edge.jitter_us = 0;
  std::mt19937_64 r1(3);
  fx.scene.edge.contrast_log = 0.26;  // one event per crossing
  const auto one = sim::render_target(fx.scene, 0, 500'000, r1);
  std::mt19937_64 r2(3);
  fx.scene.edge.contrast_log = 0.9;  // three per crossing
  const auto three = sim::render_target(fx.scene, 0, 500'000, r2);
  EXPECT_GT(three.size(), 2 * one.size());
  std::map<std::pair<int, int>, std::int64_t> last;
  for (const auto& e : three) {
    auto key = std::pair<int, int>(e.x, e.y);
    if (last.count(key)) {
      ASSERT_GE(e.t_us - last[key], fx.scene.edge.refractory_us);
    }
    last[key] = e.t_us;
  }
}

TEST(Target3D, SameSeedSameEvents) {
  Fixture a("target-planar.yaml", 0.8, Eigen::Quaterniond::Identity(), 5);
  Fixture b("target-planar.yaml", 0.8, Eigen::Quaterniond::Identity(), 5);
  std::mt19937_64 ra(9), rb(9);
  EXPECT_EQ(sim::render_target(a.scene, 0, 200'000, ra), sim::render_target(b.scene, 0, 200'000, rb));
}

TEST(Motion, StaysWithinRangeAndSpeed) {
  sim::MotionOptions mo;
  mo.base.t_cam_model_m = Eigen::Vector3d(0, 0, 0.8);
  std::mt19937_64 rng(77);
  const auto traj = sim::generate_motion(0, 10'000'000, mo, rng);
  ASSERT_EQ(traj.size(), 10'001U);
  for (std::size_t i = 0; i < traj.size(); ++i) {
    const Eigen::Vector3d d = traj[i].pose.t_cam_model_m - mo.base.t_cam_model_m;
    ASSERT_LE(d.cwiseAbs().maxCoeff(), mo.range_m + 1e-12);
    ASSERT_LE(camera::rotation_angle_deg(traj[i].pose, mo.base), std::sqrt(3.0) * mo.range_deg + 1e-9);
    if (i) {
      const double dt = 1e-6 * static_cast<double>(traj[i].t_us - traj[i - 1].t_us);
      ASSERT_LE((traj[i].pose.t_cam_model_m - traj[i - 1].pose.t_cam_model_m).norm() / dt, mo.max_speed_m_s * 1.001);
      ASSERT_LE(camera::rotation_angle_deg(traj[i].pose, traj[i - 1].pose) / dt, mo.max_angular_speed_deg_s * 1.001);
    }
  }
}

TEST(Target3D, DefaultRoadheaderViewCloseUpStaysOnTheModel) {
  // The scene set's closest roadheader scene: default view at 0.6 m, parts of the machine outside the image.
  const auto cfg = evpipe::testing::source_dir() / "config";
  sim::TargetScene scene;
  scene.camera = camera::load_camera((cfg / "davis346.yaml").string());
  scene.model = camera::load_line_model((cfg / "roadheader-wireframe.yaml").string());
  sim::MotionOptions mo;
  mo.base = sim::facing_pose(scene.model, 0.6, sim::default_view(scene.model));
  mo.pivot_model_m = sim::bbox_centre(scene.model);
  std::mt19937_64 rng(11);
  scene.trajectory = sim::generate_motion(0, 300'000, mo, rng);
  const auto ev = sim::render_target(scene, 0, 300'000, rng);
  ASSERT_GT(ev.size(), 5'000U);
  double worst = 0;
  for (const auto& e : ev) {
    const auto T = pose_at(scene.trajectory, e.t_us);
    const Eigen::Vector2d p = scene.camera.pixel_to_normalised(Eigen::Vector2d(e.x, e.y));
    double d = 1e9;
    for (const auto& s : scene.model.segments_m) d = std::min(d, distance_px(scene.camera, T, s, p));
    worst = std::max(worst, d);
  }
  EXPECT_LE(worst, 1.5);
}

TEST(View, LookAtZUpPutsTheModelUprightAndFacesTheRightSide) {
  // From the front (azimuth 0): the model's x axis points at the camera, its left (+y) appears on the right.
  const Eigen::Quaterniond front = sim::look_at_z_up(0.0, 0.0);
  EXPECT_TRUE((front * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d(0, 0, -1), 1e-12));
  EXPECT_TRUE((front * Eigen::Vector3d::UnitY()).isApprox(Eigen::Vector3d(1, 0, 0), 1e-12));
  EXPECT_TRUE((front * Eigen::Vector3d::UnitZ()).isApprox(Eigen::Vector3d(0, -1, 0), 1e-12));  // up in the image
  // From the left side, 30 degrees above: the camera looks along -y and down.
  const Eigen::Quaterniond left = sim::look_at_z_up(90.0, 30.0);
  const Eigen::Vector3d view_dir_model = left.conjugate() * Eigen::Vector3d::UnitZ();
  EXPECT_TRUE(view_dir_model.isApprox(Eigen::Vector3d(0, -std::cos(M_PI / 6), -0.5), 1e-12));
  // Upright: the camera's x axis stays horizontal in the model frame.
  EXPECT_NEAR((left.conjugate() * Eigen::Vector3d::UnitX()).z(), 0.0, 1e-12);

  const auto cfg = evpipe::testing::source_dir() / "config";
  const auto planar = camera::load_line_model((cfg / "target-planar.yaml").string());
  EXPECT_TRUE(sim::default_view(planar).coeffs() == Eigen::Quaterniond::Identity().coeffs());
  const auto rh = camera::load_line_model((cfg / "roadheader-wireframe.yaml").string());
  EXPECT_TRUE(
      sim::default_view(rh).isApprox(sim::look_at_z_up(sim::kDefaultViewAzimuth_deg, sim::kDefaultViewElevation_deg)));
  // The default view of the roadheader at 1 m: the whole machine inside the image.
  const auto cam = camera::load_camera((cfg / "davis346.yaml").string());
  const auto T = sim::facing_pose(rh, 1.0, sim::default_view(rh));
  for (const auto& s : rh.segments_m) {
    for (const auto& p : {s.a_m, s.b_m}) {
      const auto px = cam.project(T.apply(p));
      ASSERT_TRUE(px.has_value());
      EXPECT_TRUE(cam.in_image(*px)) << px->transpose();
    }
  }
}

TEST(Densify, InsertsRowsOnTheInterpolationAndKeepsTheOriginals) {
  std::vector<camera::StampedPose> sparse(3);
  sparse[0].t_us = 0;
  sparse[1].t_us = 100'000;
  sparse[1].pose.t_cam_model_m = Eigen::Vector3d(0.1, 0, 1);
  sparse[1].pose.q_cam_model = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()));
  sparse[2].t_us = 100'500;  // already dense here
  sparse[2].pose = sparse[1].pose;
  const auto dense = sim::densify(sparse, 1000);
  ASSERT_EQ(dense.size(), 102U);
  EXPECT_EQ(dense[0].t_us, 0);
  EXPECT_EQ(dense[100].t_us, 100'000);
  EXPECT_TRUE(dense[100].pose.q_cam_model.coeffs() == sparse[1].pose.q_cam_model.coeffs());
  EXPECT_EQ(dense[101].t_us, 100'500);
  for (std::size_t i = 1; i < dense.size(); ++i) ASSERT_LE(dense[i].t_us - dense[i - 1].t_us, 1000);
  // Same motion: interpolating the dense trajectory equals interpolating the sparse one.
  for (std::int64_t t = 0; t <= 100'000; t += 777) {
    const auto a = pose_at(sparse, t);
    const auto b = pose_at(dense, t);
    ASSERT_LT(camera::translation_distance_m(a, b), 1e-12) << t;
    ASSERT_LT(camera::rotation_angle_deg(a, b), 1e-6) << t;
  }
  EXPECT_EQ(sim::densify(dense, 1000).size(), dense.size());
}

TEST(PerturbPose, ExactOffsetsInRandomDirections) {
  camera::Pose truth;
  truth.t_cam_model_m = Eigen::Vector3d(0.1, -0.2, 0.8);
  truth.q_cam_model = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  std::mt19937_64 rng(5);
  Eigen::Vector3d mean_shift = Eigen::Vector3d::Zero();
  for (int i = 0; i < 2000; ++i) {
    const auto p = sim::perturb_pose(truth, 0.05, 10.0, rng);
    ASSERT_NEAR(camera::translation_distance_m(p, truth), 0.05, 1e-12);
    ASSERT_NEAR(camera::rotation_angle_deg(p, truth), 10.0, 1e-6);
    mean_shift += (p.t_cam_model_m - truth.t_cam_model_m) / 0.05;
  }
  // Uniform directions: the mean unit shift is ~0 (each component's std. error is 1/sqrt(3 * 2000) = 0.013).
  EXPECT_LT((mean_shift / 2000).cwiseAbs().maxCoeff(), 0.06);
}

TEST(Motion, CoversTheWholeSpanWhenItIsNotAWholeNumberOfSteps) {
  sim::MotionOptions mo;
  std::mt19937_64 rng(1);
  const auto traj = sim::generate_motion(0, 1'000'500, mo, rng);
  ASSERT_EQ(traj.size(), 1002U);
  EXPECT_EQ(traj[1000].t_us, 1'000'000);
  EXPECT_EQ(traj.back().t_us, 1'000'500);
}
