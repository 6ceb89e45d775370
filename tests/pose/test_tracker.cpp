// Tracker (ELOPET-style, MM-estimation) on evsim-rendered windows with known poses, plus the projection and
// association helpers and the degenerate cases.

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <random>
#include <string>
#include <vector>

#include "curvature_window.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/pose/projection.hpp"
#include "evpipe/pose/tracker.hpp"
#include "evpipe/sim/noise.hpp"
#include "evpipe/sim/target3d.hpp"
#include "evpipe_test_data.hpp"

using namespace evpipe;

namespace {

camera::CameraModel davis() {
  return camera::load_camera((evpipe::testing::source_dir() / "config" / "davis346.yaml").string());
}
camera::LineModel model_file(const std::string& name) {
  return camera::load_line_model((evpipe::testing::source_dir() / "config" / name).string());
}

camera::Pose pose_at(const std::vector<camera::StampedPose>& traj, std::int64_t t) {
  auto it = std::lower_bound(traj.begin(), traj.end(), t,
                             [](const camera::StampedPose& p, std::int64_t v) { return p.t_us < v; });
  if (it == traj.begin()) return it->pose;
  if (it == traj.end()) return traj.back().pose;
  return camera::interpolate(*(it - 1), *it, t);
}

struct Window {
  std::vector<Event> events;
  camera::Pose truth;  // at the window's mid-time
  std::size_t signal{0};
};

// One window of evsim events: the model in front of the DAVIS346 at distance_m (evsim's default view), smooth
// random motion, BA noise at noise_hz per pixel.
Window make_window(const camera::CameraModel& cam, const camera::LineModel& model, double distance_m, double noise_hz,
                   std::uint64_t seed, std::int64_t window_us = 30'000, const camera::LineModel* rendered = nullptr) {
  sim::TargetScene scene;
  scene.camera = cam;
  scene.model = rendered ? *rendered : model;
  sim::MotionOptions mo;
  mo.base = sim::facing_pose(model, distance_m, sim::default_view(model));
  mo.pivot_model_m = sim::bbox_centre(model);
  std::mt19937_64 rng(seed);
  scene.trajectory = sim::generate_motion(0, 400'000, mo, rng);
  const std::int64_t t0 = 200'000;
  Window w;
  w.events = sim::render_target(scene, t0, t0 + window_us, rng);
  w.signal = w.events.size();
  if (noise_hz > 0) {
    sim::NoiseOptions no;
    no.rate_hz_per_pixel = noise_hz;
    auto noise = sim::background_activity(SensorGeometry{cam.width, cam.height}, t0, t0 + window_us, no, rng);
    w.events.insert(w.events.end(), noise.begin(), noise.end());
    std::stable_sort(w.events.begin(), w.events.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  }
  w.truth = pose_at(scene.trajectory, t0 + window_us / 2);
  return w;
}

void expect_covariance_pd(const pose::TrackUpdate& up) {
  ASSERT_TRUE(up.covariance_known);
  ASSERT_TRUE(up.covariance.allFinite());
  EXPECT_LT((up.covariance - up.covariance.transpose()).norm(), 1e-12 * up.covariance.norm());
  const Eigen::SelfAdjointEigenSolver<pose::Covariance6> es(up.covariance);
  EXPECT_GT(es.eigenvalues()(0), 0.0);
}

}  // namespace

TEST(Projection, UndistortMapMatchesTheCamera) {
  const auto cam = davis();
  const pose::UndistortMap map(cam);
  for (const auto& [x, y] : {std::pair{0, 0}, std::pair{345, 259}, std::pair{173, 128}, std::pair{10, 250}}) {
    EXPECT_TRUE(map.contains(x, y));
    EXPECT_LT((map.at(x, y) - cam.pixel_to_normalised(Eigen::Vector2d(x, y))).norm(), 1e-15);
  }
  EXPECT_FALSE(map.contains(346, 0));
  EXPECT_FALSE(map.contains(0, -1));
}

TEST(Projection, ClipsToTheImageAndDropsShortSegments) {
  const auto cam = davis();
  camera::LineModel m;
  // A long horizontal segment through the optical axis at 1 m (sticks out on both sides), a short one
  // (2 cm = ~5 px), one behind the camera, one crossing the camera plane.
  m.segments_m = {{{-5, 0, 0}, {5, 0, 0}},
                  {{0, 0.1, 0}, {0.02, 0.1, 0}},
                  {{0, 0, -3}, {0.5, 0, -3}},
                  {{0.1, -0.1, -2}, {0.1, -0.1, 0}}};
  camera::Pose T;
  T.t_cam_model_m = {0, 0, 1};
  const auto segs = pose::project_model(cam, m, T);
  ASSERT_EQ(segs.size(), 2U);
  EXPECT_EQ(segs[0].model_index, 0U);
  // The visible part ends on the image border (within the bisection tolerance).
  for (const auto& p : {segs[0].segment_px.a_px, segs[0].segment_px.b_px}) {
    EXPECT_TRUE(cam.in_image(p));
    EXPECT_LT(std::min(std::abs(p.x() + 0.5), std::abs(p.x() - 345.5)), 1e-3) << p.transpose();
  }
  // The segment crossing z = 0 keeps its part in front, from the near plane clipped to the image border.
  EXPECT_EQ(segs[1].model_index, 3U);
  EXPECT_GT(segs[1].a_m.z() + 1.0, 0.0);
}

TEST(Association, GatesByDistanceAndAmbiguity) {
  const auto cam = davis();
  const pose::UndistortMap map(cam);
  camera::LineModel m;
  // Two segments forming an L at 1 m.
  m.segments_m = {{{-0.2, 0, 0}, {0.2, 0, 0}}, {{0.2, 0, 0}, {0.2, 0.2, 0}}};
  camera::Pose T;
  T.t_cam_model_m = {0, 0, 1};
  const auto segs = pose::project_model(cam, m, T);
  ASSERT_EQ(segs.size(), 2U);
  const auto px = [&](double X, double Y) {
    const Eigen::Vector2d p = cam.normalised_to_pixel(Eigen::Vector2d(X, Y));
    return Event{0, static_cast<std::uint16_t>(std::lround(p.x())), static_cast<std::uint16_t>(std::lround(p.y())),
                 true};
  };
  const std::vector<Event> ev{px(0.0, 0.0),      // on the horizontal segment
                              px(0.0, 0.08),     // ~19 px off: beyond the 10 px gate
                              px(0.2, 0.1),      // on the vertical segment
                              px(0.2, 0.0),      // at the corner: near both
                              px(0.19, 0.012)};  // ~3 px from both near the corner: ambiguous
  std::vector<pose::Association> out;
  pose::associate_events(ev, map, segs, {}, out);
  ASSERT_EQ(out.size(), 2U);
  EXPECT_EQ(out[0].event_index, 0U);
  EXPECT_EQ(out[0].segment, 0U);
  EXPECT_EQ(out[1].event_index, 2U);
  EXPECT_EQ(out[1].segment, 1U);
  EXPECT_LT(out[0].distance_px, 0.75);
}

// The grid lookup only skips segments that cannot change a decision: its associations equal the exhaustive loop's
// on random poses of both targets (clipped at the border, near and far), every pixel and every gate setting used
// by the tracker's rounds, with the shipped DAVIS346 calibration and a strongly distorted lens.
TEST(Association, GridEqualsTheExhaustiveLoop) {
  const std::uint64_t seed = 20261121;
  std::cout << "seed " << seed << "\n";
  std::mt19937_64 rng(seed);
  auto strong = davis();
  strong.k1 = -0.35;
  strong.k2 = 0.12;
  strong.k3 = -0.015;
  std::vector<Event> every_pixel;
  for (int y = 0; y < strong.height; ++y) {
    for (int x = 0; x < strong.width; ++x) {
      every_pixel.push_back({0, static_cast<std::uint16_t>(x), static_cast<std::uint16_t>(y), true});
    }
  }
  std::size_t compared = 0, associated = 0;
  for (const auto& cam : {davis(), strong}) {
    const pose::UndistortMap map(cam);
    for (const std::string file : {"target-planar.yaml", "roadheader-wireframe.yaml"}) {
      const auto model = model_file(file);
      for (int trial = 0; trial < 4; ++trial) {
        const double distance = std::uniform_real_distribution<double>(0.3, 1.5)(rng);
        const camera::Pose T =
            sim::perturb_pose(sim::facing_pose(model, distance, sim::default_view(model)), 0.15, 25.0, rng);
        const auto segs = pose::project_model(cam, model, T);
        for (const double gate : {40.0, 20.0, 10.0, 5.0, 2.5}) {
          pose::AssociationOptions o;
          o.gate_px = gate;
          o.ambiguity_ratio = std::uniform_real_distribution<double>(0.5, 2.5)(rng);
          o.junction_px = std::uniform_real_distribution<double>(0.0, 6.0)(rng);
          std::vector<pose::Association> fast, reference;
          pose::associate_events(every_pixel, map, segs, o, fast);
          pose::associate_events_exhaustive(every_pixel, map, segs, o, reference);
          ASSERT_EQ(fast.size(), reference.size()) << file << " trial " << trial << " gate " << gate;
          for (std::size_t j = 0; j < fast.size(); ++j) {
            ASSERT_EQ(fast[j].event_index, reference[j].event_index) << j;
            ASSERT_EQ(fast[j].segment, reference[j].segment) << j;
            ASSERT_EQ(fast[j].distance_px, reference[j].distance_px) << j;
          }
          ++compared;
          associated += fast.size();
        }
      }
    }
  }
  std::cout << compared << " settings, " << associated << " associations, all equal\n";
  EXPECT_GT(associated, 10'000U);  // the comparison saw real work
}

namespace {

// Under the sanitizers (CI's ASan+UBSan and TSan builds: Debug, the numerical libraries at -O1) a sweep runs the
// first seed of each scene only: that covers the code paths of the full sweep at a third of the time (the 5 cm sweep
// took ~100 s there). The thresholds below are the measured quality of all seeds and are checked in the optimised
// builds, which run all seeds; under the sanitizers only what holds for any subset is checked.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kAllSeeds = false;
#else
constexpr bool kAllSeeds = true;
#endif

// Runs the tracker on every scene (2 targets x 0.6/0.8/1.0 m x 3 seeds x {no noise, 5 Hz/px BA noise raw, the
// same noisy window through evpipe's curvature filter}) from the truth perturbed by offset_m / offset_deg; prints
// every result and returns the number converged per input (rotation < 1 deg and translation < 10 mm from the
// mid-window truth, healthy, covariance positive definite).
struct Tally {
  int converged[3]{0, 0, 0};
  int runs[3]{0, 0, 0};
  int planar_noise_free{0};
};

Tally run_scenes(double offset_m, double offset_deg, const pose::TrackerOptions& o, const char* tag) {
  const auto cam = davis();
  const pose::UndistortMap map(cam);
  Tally tally;
  for (const std::string file : {"target-planar.yaml", "roadheader-wireframe.yaml"}) {
    const auto model = model_file(file);
    for (const double distance : {0.6, 0.8, 1.0}) {
      for (const int input : {0, 1, 2}) {
        const int noisy = input > 0 ? 1 : 0;
        for (std::uint64_t k = 0; k < (kAllSeeds ? 3U : 1U); ++k) {
          const std::uint64_t seed = 1000 + 97 * k + static_cast<std::uint64_t>(distance * 10) + 5 * noisy;
          Window w = make_window(cam, model, distance, noisy ? 5.0 : 0.0, seed);
          if (input == 2) {
            w.events = evpipe::testing::curvature_filtered(w.events, SensorGeometry{cam.width, cam.height});
          }
          std::mt19937_64 rng(seed + 1);
          const camera::Pose start = sim::perturb_pose(w.truth, offset_m, offset_deg, rng);
          const auto up = pose::track_window(w.events, map, model, start, o);
          const double rot = camera::rotation_angle_deg(up.T_cam_model, w.truth);
          const double mm = 1000 * camera::translation_distance_m(up.T_cam_model, w.truth);
          bool pd = false;
          if (up.covariance_known && up.covariance.allFinite()) {
            pd = Eigen::SelfAdjointEigenSolver<pose::Covariance6>(up.covariance).eigenvalues()(0) > 0.0;
          }
          const bool ok = rot < 1.0 && mm < 10.0 && up.healthy && pd;
          std::cout << tag << " " << file << " d=" << distance << " noise=" << (noisy ? 5 : 0)
                    << (input == 2 ? " curvature" : "") << " seed=" << seed << ": " << w.events.size() << " ev ("
                    << w.signal << " signal), rot " << rot << " deg, trans " << mm << " mm, sigma " << up.sigma_px
                    << " px, inliers " << up.inliers << " (" << up.inlier_share << "), it " << up.iterations
                    << ", rounds " << up.rounds << ", cond " << up.condition
                    << (up.healthy ? " healthy" : " UNHEALTHY: " + up.reason) << (ok ? "" : "  <- not converged")
                    << "\n";
          EXPECT_TRUE(up.T_cam_model.t_cam_model_m.allFinite());
          ++tally.runs[input];
          if (ok) ++tally.converged[input];
          if (ok && !noisy && file == "target-planar.yaml") ++tally.planar_noise_free;
        }
      }
    }
  }
  std::cout << tag << ": converged " << tally.converged[0] << "/" << tally.runs[0] << " without noise, "
            << tally.converged[1] << "/" << tally.runs[1] << " with 5 Hz/px BA noise, " << tally.converged[2] << "/"
            << tally.runs[2] << " with that noise through the curvature filter\n";
  return tally;
}

}  // namespace

TEST(Tracker, ConvergesFromFiveCmTenDegrees) {
  // Recovery settings (see TrackerOptions): coarse shift search, wide first gate, many short rounds, and starts
  // turned about the line of sight and tilted out of plane (the best result kept).
  pose::TrackerOptions o;
  o.coarse_search_px = 48;
  o.association.gate_px = 20;
  o.association_rounds = 20;
  o.max_iterations = 2;
  o.gate_shrink = 0.85;
  o.recovery_roll_deg = 4.0;
  o.recovery_roll_steps = 2;
  o.recovery_tilt_deg = 7.0;
  o.verify = false;  // convergence of the solver; the pose verification has its own tests (test_verification.cpp)
  const Tally t = run_scenes(0.05, 10.0, o, "5cm/10deg");
  // Measured with these seeds: every noise-free scene converges (without the extra starts: 14/18, the
  // roadheader's dense wireframe trapped the nearest-segment association in 4); 6/18 on raw 5 Hz/px windows; 14/18
  // on the same windows through the curvature filter (13 before the S-scale's warm start) — the 4 misses are
  // sparse planar windows (< 550 events, rotation 1.7-2.1 deg off with the translation within 8 mm: the tilt is
  // weakly observable) that miss from 1 cm / 2 deg as well, and one roadheader window.
  EXPECT_EQ(t.converged[0], t.runs[0]);  // every noise-free scene, whichever seeds ran
  EXPECT_EQ(t.planar_noise_free, t.runs[0] / 2);
  if (kAllSeeds) {
    EXPECT_EQ(t.runs[0], 18);
    EXPECT_GE(t.converged[1], 6);
    EXPECT_GE(t.converged[2], 13);
  }
}

TEST(Tracker, TracksFromOneCmTwoDegrees) {
  // The tracking regime (the previous window's pose as the prediction), default options.
  pose::TrackerOptions o;
  o.verify = false;  // convergence of the solver; the pose verification has its own tests (test_verification.cpp)
  const Tally t = run_scenes(0.01, 2.0, o, "1cm/2deg");
  if (kAllSeeds) {
    EXPECT_GE(t.converged[0], 17);
    EXPECT_GE(t.converged[1], 9);
    // 13 before segment_motion (on by default): the sparse filtered planar windows (< 550 events) have a segment
    // speed each to fit beside the pose; one more misses from this start (2.2 deg off).
    EXPECT_GE(t.converged[2], 12);
  } else {
    EXPECT_GE(t.converged[0], t.runs[0] - 1);  // 17 of the 18 noise-free scenes converge: at most one miss
  }
}

TEST(Tracker, LopetCompatibleSwitchGivesAResult) {
  const auto cam = davis();
  const auto model = model_file("target-planar.yaml");
  const std::uint64_t seed = 4242;
  std::cout << "seed " << seed << "\n";
  const Window w = make_window(cam, model, 0.8, 5.0, seed);
  std::mt19937_64 rng(seed + 1);
  const camera::Pose start = sim::perturb_pose(w.truth, 0.01, 2.0, rng);
  pose::TrackerOptions o;
  o.lopet_compatible = true;
  const auto lo = pose::track_window(w.events, cam, model, start, o);
  const auto tb = pose::track_window(w.events, cam, model, start);
  for (const auto* up : {&tb, &lo}) {
    std::cout << (up == &lo ? "LOPET   " : "textbook") << ": rot "
              << camera::rotation_angle_deg(up->T_cam_model, w.truth) << " deg, trans "
              << 1000 * camera::translation_distance_m(up->T_cam_model, w.truth) << " mm, sigma " << up->sigma_px
              << " px, inliers " << up->inliers << ", it " << up->iterations << "\n";
  }
  EXPECT_TRUE(lo.T_cam_model.t_cam_model_m.allFinite());
  EXPECT_LT(camera::rotation_angle_deg(lo.T_cam_model, w.truth), 2.0);
  EXPECT_LT(camera::translation_distance_m(lo.T_cam_model, w.truth), 0.03);
  // The demo code's scale is larger than the textbook S-scale (pose.md §7.5: ~2x on signed Gaussian residuals;
  // here it is computed on unsigned distances as the demo code does, measured 1.3x).
  EXPECT_GT(lo.sigma_px, 1.15 * tb.sigma_px);
  expect_covariance_pd(lo);
}

// The round stop: from a close prediction (the tracking regime) the pose stops moving after a round or two at the
// smallest gate; the rounds after that re-associate the same events and move it by less than the LM tolerance. The
// update must stop there and give the pose all four rounds give (within 0.1 mm / 0.01 deg, ~0.04 px here).
TEST(Tracker, StopsOnceARoundNoLongerMovesThePose) {
  const auto cam = davis();
  for (const char* file : {"roadheader-wireframe.yaml", "target-planar.yaml"}) {
    const auto model = model_file(file);
    const std::uint64_t seed = 5150;
    SCOPED_TRACE(::testing::Message() << file << ", seed " << seed);
    const Window w = make_window(cam, model, 0.8, 1.0, seed);
    std::mt19937_64 rng(seed + 1);
    const camera::Pose start = sim::perturb_pose(w.truth, 0.002, 0.3, rng);  // one window's prediction error
    pose::TrackerOptions all;
    all.round_tolerance_px = 0.0;
    const auto full = pose::track_window(w.events, cam, model, start, all);
    const auto stopped = pose::track_window(w.events, cam, model, start);
    std::cout << file << ": rounds " << full.rounds << " -> " << stopped.rounds << ", pose difference "
              << 1000 * camera::translation_distance_m(full.T_cam_model, stopped.T_cam_model) << " mm, "
              << camera::rotation_angle_deg(full.T_cam_model, stopped.T_cam_model) << " deg\n";
    ASSERT_TRUE(full.healthy) << full.reason;
    ASSERT_TRUE(stopped.healthy) << stopped.reason;
    EXPECT_EQ(full.rounds, 4);
    EXPECT_LT(stopped.rounds, full.rounds);
    EXPECT_LT(camera::translation_distance_m(full.T_cam_model, stopped.T_cam_model), 0.1e-3);
    EXPECT_LT(camera::rotation_angle_deg(full.T_cam_model, stopped.T_cam_model), 0.01);
    EXPECT_LT(camera::translation_distance_m(stopped.T_cam_model, w.truth), 5e-3);
  }
}

TEST(Tracker, EmptyWindowIsUnhealthyAndKeepsThePrediction) {
  const auto cam = davis();
  const auto model = model_file("target-planar.yaml");
  const camera::Pose predicted = sim::facing_pose(model, 0.8);
  const auto up = pose::track_window({}, cam, model, predicted);
  EXPECT_FALSE(up.healthy);
  EXPECT_NE(up.reason.find("empty"), std::string::npos) << up.reason;
  EXPECT_TRUE(up.T_cam_model.t_cam_model_m.isApprox(predicted.t_cam_model_m));
  EXPECT_FALSE(up.covariance_known);
}

TEST(Tracker, ModelOutOfViewIsUnhealthy) {
  const auto cam = davis();
  const auto model = model_file("target-planar.yaml");
  const std::uint64_t seed = 5;
  std::cout << "seed " << seed << "\n";
  const Window w = make_window(cam, model, 0.8, 5.0, seed);
  for (const Eigen::Vector3d& t : {Eigen::Vector3d(0, 0, -0.8), Eigen::Vector3d(5, 0, 0.8)}) {
    camera::Pose predicted = w.truth;
    predicted.t_cam_model_m = t;
    const auto up = pose::track_window(w.events, cam, model, predicted);
    EXPECT_FALSE(up.healthy);
    EXPECT_NE(up.reason.find("out of view"), std::string::npos) << up.reason;
    EXPECT_TRUE(up.T_cam_model.t_cam_model_m.isApprox(t));
    EXPECT_TRUE(up.T_cam_model.q_cam_model.coeffs().allFinite());
  }
  camera::Pose nan_pose = w.truth;
  nan_pose.t_cam_model_m.x() = std::nan("");
  const auto up = pose::track_window(w.events, cam, model, nan_pose);
  EXPECT_FALSE(up.healthy);
  EXPECT_FALSE(up.reason.empty());
}

TEST(Tracker, OnlyParallelLinesSeenIsUnhealthy) {
  const auto cam = davis();
  const auto model = model_file("target-planar.yaml");
  // Render only the target's horizontal lines (outer top and bottom, the top bar): the events constrain
  // nothing along them.
  camera::LineModel horizontal;
  for (const auto& s : model.segments_m) {
    if (std::abs(s.a_m.y() - s.b_m.y()) < 1e-9) horizontal.segments_m.push_back(s);
  }
  ASSERT_EQ(horizontal.segments_m.size(), 4U);  // top, bottom, the L's foot, top bar
  const std::uint64_t seed = 77;
  std::cout << "seed " << seed << "\n";
  const Window w = make_window(cam, model, 0.8, 0.0, seed, 30'000, &horizontal);
  // Tracked with the full model from the true pose: only horizontal segments get events.
  const auto up = pose::track_window(w.events, cam, model, w.truth);
  EXPECT_FALSE(up.healthy);
  EXPECT_NE(up.reason.find("aperture"), std::string::npos) << up.reason;
  EXPECT_TRUE(up.T_cam_model.t_cam_model_m.allFinite());
  // A model made of parallel lines only, tracked on its own events.
  const auto up2 = pose::track_window(w.events, cam, horizontal, w.truth);
  EXPECT_FALSE(up2.healthy);
  EXPECT_NE(up2.reason.find("aperture"), std::string::npos) << up2.reason;
}

namespace {

// A fast-moving target (0.3 m/s, 40 deg/s: a 30 ms window smears its edges over several pixels) rendered over
// [t0, t1), noise-free; the trajectory for the truth at any time.
struct MovingScene {
  std::vector<Event> events;
  std::vector<camera::StampedPose> trajectory;
};

MovingScene moving_scene(const camera::CameraModel& cam, const camera::LineModel& model, std::uint64_t seed,
                         std::int64_t t0_us, std::int64_t t1_us) {
  sim::TargetScene scene;
  scene.camera = cam;
  scene.model = model;
  sim::MotionOptions mo;
  mo.base = sim::facing_pose(model, 0.8, sim::default_view(model));
  mo.pivot_model_m = sim::bbox_centre(model);
  mo.max_speed_m_s = 0.3;
  mo.max_angular_speed_deg_s = 40.0;
  mo.min_freq_hz = 0.5;
  mo.max_freq_hz = 1.0;
  std::mt19937_64 rng(seed);
  scene.trajectory = sim::generate_motion(0, 1'000'000, mo, rng);
  MovingScene out;
  out.events = sim::render_target(scene, t0_us, t1_us, rng);
  out.trajectory = scene.trajectory;
  return out;
}

}  // namespace

// Segment motion (TrackerOptions::segment_motion): each edge's events lie on a line moving at its own normal speed;
// fitted with the pose, that motion no longer smears the window's events into a band. On fast windows from the
// truth (the tracking regime) the robust scale is smaller and the pose at the window's middle closer to the truth
// (measured: roadheader 0.12 vs 0.19 mm, 0.018 vs 0.027 deg; planar 0.12 vs 0.12 mm, 0.11 vs 0.15 deg).
TEST(Tracker, SegmentMotionTakesAMovingEdgesSmearOut) {
  const auto cam = davis();
  const pose::UndistortMap map(cam);
  for (const char* file : {"roadheader-wireframe.yaml", "target-planar.yaml"}) {
    const auto model = model_file(file);
    double mm_on = 0.0, mm_off = 0.0, deg_on = 0.0, deg_off = 0.0, sigma_on = 0.0, sigma_off = 0.0;
    int runs = 0;
    for (std::uint64_t seed = 610; seed < 616; ++seed) {
      const MovingScene s = moving_scene(cam, model, seed, 300'000, 330'000);
      const camera::Pose truth = pose_at(s.trajectory, 315'000);
      const pose::MotionHint hint{camera::StampedPose{285'000, pose_at(s.trajectory, 285'000)}, 315'000};
      pose::TrackerOptions on, off;
      on.verify = off.verify = false;
      off.segment_motion = false;
      const auto a = pose::track_window(s.events, map, model, truth, on, hint);
      const auto b = pose::track_window(s.events, map, model, truth, off, hint);
      ASSERT_TRUE(a.healthy) << file << " seed " << seed << ": " << a.reason;
      ASSERT_TRUE(b.healthy) << file << " seed " << seed << ": " << b.reason;
      const double ea = 1000 * camera::translation_distance_m(a.T_cam_model, truth);
      const double eb = 1000 * camera::translation_distance_m(b.T_cam_model, truth);
      std::cout << file << " seed " << seed << ": " << s.events.size() << " events; segment motion " << ea << " mm, "
                << camera::rotation_angle_deg(a.T_cam_model, truth) << " deg, sigma " << a.sigma_px << " px; without "
                << eb << " mm, " << camera::rotation_angle_deg(b.T_cam_model, truth) << " deg, sigma " << b.sigma_px
                << " px\n";
      expect_covariance_pd(a);
      mm_on += ea;
      mm_off += eb;
      deg_on += camera::rotation_angle_deg(a.T_cam_model, truth);
      deg_off += camera::rotation_angle_deg(b.T_cam_model, truth);
      sigma_on += a.sigma_px;
      sigma_off += b.sigma_px;
      ++runs;
    }
    std::cout << file << ": mean " << mm_on / runs << " mm (without " << mm_off / runs << "), " << deg_on / runs
              << " deg (without " << deg_off / runs << "), sigma " << sigma_on / runs << " px (without "
              << sigma_off / runs << ")\n";
    EXPECT_LT(sigma_on, 0.9 * sigma_off) << file;
    EXPECT_LT(deg_on, deg_off) << file;
    // The roadheader's many edges in every direction pin the translation; the board's four are few.
    EXPECT_LT(mm_on, std::string(file) == "roadheader-wireframe.yaml" ? 0.8 * mm_off : 1.1 * mm_off) << file;
  }
}

// The edge's scale under background activity (TrackerOptions::background_scale, off by default): on windows that hold
// far more noise than edge events (a 90 ms history under 5 Hz/px, raw: ~40 000 noise events, a few thousand of the
// target's), the S-scale measures the noise's spread over the gate; the EM scale of the edge / background mixture is
// the edge's. From the truth, the fit at the edge's scale stays closer to it (measured: board 2.5 vs 13.1 deg summed
// over six seeds, roadheader 0.29 vs 0.81).
TEST(Tracker, TheEdgesScaleUnderNoiseKeepsTheFitOnTheEdges) {
  const auto cam = davis();
  const pose::UndistortMap map(cam);
  for (const char* file : {"roadheader-wireframe.yaml", "target-planar.yaml"}) {
    const auto model = model_file(file);
    double mm_on = 0.0, mm_off = 0.0, deg_on = 0.0, deg_off = 0.0;
    for (std::uint64_t seed = 620; seed < 626; ++seed) {
      const Window w = make_window(cam, model, 1.0, 5.0, seed, 90'000);
      pose::TrackerOptions on, off;
      on.verify = off.verify = false;
      on.background_scale = true;
      const auto a = pose::track_window(w.events, map, model, w.truth, on);
      const auto b = pose::track_window(w.events, map, model, w.truth, off);
      const double ea = 1000 * camera::translation_distance_m(a.T_cam_model, w.truth);
      const double eb = 1000 * camera::translation_distance_m(b.T_cam_model, w.truth);
      const double da = camera::rotation_angle_deg(a.T_cam_model, w.truth);
      const double db = camera::rotation_angle_deg(b.T_cam_model, w.truth);
      std::cout << file << " seed " << seed << ": " << w.events.size() << " events (" << w.signal
                << " of the target); edge scale " << ea << " mm, " << da << " deg; S-scale " << eb << " mm, " << db
                << " deg (sigma " << b.sigma_px << " px)\n";
      mm_on += ea;
      mm_off += eb;
      deg_on += da;
      deg_off += db;
    }
    std::cout << file << ": sum " << mm_on << " mm, " << deg_on << " deg (S-scale " << mm_off << " mm, " << deg_off
              << " deg)\n";
    EXPECT_LT(mm_on, mm_off) << file;
    EXPECT_LT(deg_on, deg_off) << file;
  }
}

// A sparse window's history: the events end long before the pose's time (a target that stopped). The fitted
// motion is not extrapolated over that gap: the pose is where the events put the target (within half a window of
// their mean time), not 300 ms further along its last motion.
TEST(Tracker, SegmentMotionIsNotExtrapolatedPastItsEvents) {
  const auto cam = davis();
  const pose::UndistortMap map(cam);
  const auto model = model_file("roadheader-wireframe.yaml");
  const std::uint64_t seed = 620;
  const MovingScene s = moving_scene(cam, model, seed, 300'000, 330'000);
  const camera::Pose at_data_end = pose_at(s.trajectory, 330'000);
  const camera::Pose extrapolated = pose_at(s.trajectory, 630'000);
  const pose::MotionHint hint{camera::StampedPose{285'000, pose_at(s.trajectory, 285'000)}, 630'000};
  pose::TrackerOptions o;
  o.verify = false;
  const auto up = pose::track_window(s.events, map, model, pose_at(s.trajectory, 315'000), o, hint);
  ASSERT_TRUE(up.healthy) << up.reason;
  const double mm_end = 1000 * camera::translation_distance_m(up.T_cam_model, at_data_end);
  const double mm_far = 1000 * camera::translation_distance_m(at_data_end, extrapolated);
  std::cout << "seed " << seed << ": " << mm_end
            << " mm from the pose at the events' end; the motion would have moved it " << mm_far
            << " mm by the pose's time\n";
  EXPECT_LT(mm_end, 1.0);
  EXPECT_GT(mm_far, 10.0);  // the test means something: extrapolating would be far off
}
