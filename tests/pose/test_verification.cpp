// Pose verification (issue 21): supported along its length, beating the scene's other structure, 6 DoF fixed.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <numbers>
#include <optional>
#include <random>
#include <string>

#include "evbench_board.hpp"
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

// The real sequence's model (evbench_board.hpp), with or without its grid lines.
camera::LineModel board(bool with_grid) {
  return pose_test::evbench_board(with_grid);
}

// A board seen from 0.5 m moving on a seeded smooth trajectory; events rendered from `rendered`.
struct BoardScene {
  sim::TargetScene scene;
  std::vector<Event> events;
  BoardScene(const camera::LineModel& rendered, std::uint64_t seed, double noise_hz) {
    const auto cfg = evpipe::testing::source_dir() / "config";
    scene.camera = camera::load_camera((cfg / "davis346.yaml").string());
    scene.model = rendered;
    sim::MotionOptions mo;
    mo.base = sim::facing_pose(board(true), 0.5, sim::default_view(board(true)));
    mo.pivot_model_m = sim::bbox_centre(board(true));
    std::mt19937_64 rng(seed);
    scene.trajectory = sim::generate_motion(0, 600'000, mo, rng);
    events = sim::render_target(scene, 0, 600'000, rng);
    if (noise_hz > 0.0) {
      std::mt19937_64 noise_rng(seed + 1);
      sim::NoiseOptions no;
      no.rate_hz_per_pixel = noise_hz;
      const auto noise =
          sim::background_activity(SensorGeometry{scene.camera.width, scene.camera.height}, 0, 600'000, no, noise_rng);
      events.insert(events.end(), noise.begin(), noise.end());
      std::stable_sort(events.begin(), events.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
    }
  }
};

// Poisson tail threshold: the smallest k with P(X >= k) <= p.
TEST(PoseVerify, PoissonThreshold) {
  EXPECT_EQ(pose::poisson_threshold(0.0, 0.05), 1);
  // P(Poisson(1) >= 3) = 0.080, >= 4 = 0.019.
  EXPECT_EQ(pose::poisson_threshold(1.0, 0.05), 4);
  EXPECT_EQ(pose::poisson_threshold(1.0, 0.1), 3);
}

// The board rendered whole verifies at its true pose; a decoy with the board's outline but no inner grid lines
// (a monitor border, a door frame) does not verify as the board, at the same pose, with and without noise.
TEST(PoseVerify, DecoyOutlineWithoutInnerLinesIsRefused) {
  for (const double noise_hz : {0.0, 0.5}) {
    for (const std::uint64_t seed : {11u, 12u, 13u}) {
      SCOPED_TRACE(::testing::Message() << "seed " << seed << ", " << noise_hz << " Hz/px");
      const BoardScene whole(board(true), seed, noise_hz);
      const BoardScene decoy(board(false), seed, noise_hz);
      int whole_ok = 0, decoy_ok = 0, windows = 0;
      for (std::int64_t t = 45'000; t + 15'000 <= 600'000; t += 30'000, ++windows) {
        const auto T = *camera::interpolate(whole.scene.trajectory, t);
        const pose::MotionHint hint{
            camera::StampedPose{t - 30'000, *camera::interpolate(whole.scene.trajectory, t - 30'000)}, t};
        const auto v = pose::verify_pose(slice(whole.events, t - 15'000, t + 15'000), whole.scene.camera, board(true),
                                         T, {}, hint);
        const auto d = pose::verify_pose(slice(decoy.events, t - 15'000, t + 15'000), decoy.scene.camera, board(true),
                                         T, {}, hint);
        whole_ok += v.ok ? 1 : 0;
        decoy_ok += d.ok ? 1 : 0;
      }
      EXPECT_EQ(decoy_ok, 0);
      EXPECT_GE(whole_ok, windows * 8 / 10) << whole_ok << " of " << windows;
    }
  }
}

// Only the horizontal lines fire (a tilt): the vertical ones are not demanded (no motion across them), but the
// horizontal ones alone do not fix the pose: refused.
TEST(PoseVerify, OneDirectionOfEdgesIsRefused) {
  camera::LineModel horizontal = board(true);
  std::erase_if(horizontal.segments_m,
                [](const camera::Segment3& s) { return std::abs(s.a_m.y() - s.b_m.y()) > 1e-9; });
  const BoardScene scene(horizontal, 21, 0.0);
  for (std::int64_t t = 45'000; t + 15'000 <= 600'000; t += 30'000) {
    const auto T = *camera::interpolate(scene.scene.trajectory, t);
    const auto v = pose::verify_pose(slice(scene.events, t - 15'000, t + 15'000), scene.scene.camera, board(true), T);
    EXPECT_FALSE(v.ok) << "window at " << t;
  }
}

// Redundancy (VerifyOptions::leave_one_out): three edges of a rectangle (top, left, bottom) give six constraints
// for six degrees of freedom, so each carries part of the pose alone and a bias on it would move the pose without
// a residual; they verify without the option and never with it. The whole board (19 edges) stays fixed without any
// one of them.
TEST(PoseVerify, APoseThatOneEdgeFixesAloneIsNotRedundant) {
  const camera::LineModel full = board(true);
  camera::LineModel three;
  for (const std::size_t k : {0u, 2u, 3u}) three.segments_m.push_back(full.segments_m[k]);
  pose::VerifyOptions redundant;
  redundant.leave_one_out = true;
  for (const std::uint64_t seed : {32u, 33u, 34u}) {
    SCOPED_TRACE(::testing::Message() << "seed " << seed);
    const BoardScene part(three, seed, 0.0);
    const BoardScene whole(full, seed, 0.0);
    int part_ok = 0, part_redundant = 0, whole_ok = 0, whole_redundant = 0, windows = 0;
    for (std::int64_t t = 45'000; t + 15'000 <= 600'000; t += 30'000, ++windows) {
      const auto T = *camera::interpolate(part.scene.trajectory, t);
      const pose::MotionHint hint{
          camera::StampedPose{t - 30'000, *camera::interpolate(part.scene.trajectory, t - 30'000)}, t};
      const EventSpan p = slice(part.events, t - 15'000, t + 15'000);
      const EventSpan w = slice(whole.events, t - 15'000, t + 15'000);
      part_ok += pose::verify_pose(p, part.scene.camera, three, T, {}, hint).ok ? 1 : 0;
      const pose::VerifyResult r = pose::verify_pose(p, part.scene.camera, three, T, redundant, hint);
      part_redundant += r.ok ? 1 : 0;
      if (r.rotation_std_without_deg > 0.0) {
        EXPECT_GE(r.rotation_std_without_deg, r.rotation_std_deg);
      }
      whole_ok += pose::verify_pose(w, whole.scene.camera, full, T, {}, hint).ok ? 1 : 0;
      whole_redundant += pose::verify_pose(w, whole.scene.camera, full, T, redundant, hint).ok ? 1 : 0;
    }
    std::printf("seed %llu: three edges %d / %d redundant, whole board %d / %d redundant, of %d windows\n",
                static_cast<unsigned long long>(seed), part_ok, part_redundant, whole_ok, whole_redundant, windows);
    EXPECT_GT(part_ok, 0);
    EXPECT_EQ(part_redundant, 0);
    EXPECT_GE(whole_redundant, whole_ok * 8 / 10);
  }
}

// Honest covariance: the normalised estimation error squared of the tracked poses of a seeded scene averages
// within [0.5, 2] x 6 (the events of one edge are one measurement per cell, not one per event).
TEST(PoseVerify, CovarianceIsHonestOnASeededScene) {
  double sum = 0.0;
  int n = 0;
  for (const std::uint64_t seed : {20261121u, 31u}) {
    const Scene s("roadheader-wireframe.yaml", 1.0, seed, 900'000);
    camera::PosePrior prior;
    std::mt19937_64 rng(seed + 7);
    prior.pose = sim::perturb_pose(s.scene.trajectory.front().pose, 0.05, 10.0, rng);
    prior.position_tolerance_m = 0.3;
    prior.angle_tolerance_deg = 45.0;
    pose::PoseEstimator est(s.scene.camera, s.scene.model, prior);
    for (std::int64_t t0 = 0; t0 + 30'000 <= 900'000; t0 += 30'000) {
      const auto out = est.process(slice(s.events, t0, t0 + 30'000), t0 + 15'000);
      if (out.status != pose::TrackStatus::tracking || !out.covariance_known) continue;
      const auto truth = *camera::interpolate(s.scene.trajectory, t0 + 15'000);
      Eigen::Matrix<double, 6, 1> e;
      const Eigen::AngleAxisd dq(truth.q_cam_model * out.T_cam_model.q_cam_model.inverse());
      e.head<3>() = dq.angle() * dq.axis();
      e.tail<3>() = truth.t_cam_model_m - out.T_cam_model.t_cam_model_m;
      const double nees = e.dot(out.covariance.ldlt().solve(e));
      sum += nees;
      ++n;
    }
  }
  ASSERT_GT(n, 20);
  const double mean = sum / n;
  std::cout << "mean NEES " << mean << " over " << n << " tracked windows (target 3..12)\n";
  EXPECT_GE(mean, 3.0);
  EXPECT_LE(mean, 12.0);
}

// The real DAVIS240 checkerboard recordings (../shared/data/real/davis240-evbench-checkerboard): the board sits
// inside a monitor whose screen border is a rectangle ~1.45x the board; before the verification the estimator
// locked onto it and reported tracking 270-500 mm / 24-78 deg off (pan + tilt), and without a prior it accepted
// wrong poses on both sequences. Now no tracking pose may be more than 20 mm / 2 deg off (scored against each of
// the board's equivalent poses), with and without the prior.
using pose_test::board_error;

class RealBoard : public ::testing::TestWithParam<const char*> {};

// Under the sanitizers (Debug, ~20x slower: minutes per sequence) the first windows with the prior cover the code
// paths, and the board's direct alignment (DirectAlignment::automatic: 1-2 s per attempt optimised) searches a grid
// 100x coarser; the optimised builds check both sequences whole with the default options, with and without the prior.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kWholeSequences = false;
constexpr double kAlignmentReads = 2e6;
#else
constexpr bool kWholeSequences = true;
constexpr double kAlignmentReads = pose::PriorAlignmentOptions{}.max_level0_reads;
#endif

TEST_P(RealBoard, NoTrackingPoseIsWrongWithOrWithoutPrior) {
  if (!kWholeSequences && std::string(GetParam()) == "seq_0001") {
    GTEST_SKIP() << "optimised builds only: under the sanitizers seq_0003's first windows (two refused after the "
                    "board's alignment, then tracked) take its paths";
  }
  const std::string rel = std::string("davis240-evbench-checkerboard/") + GetParam();
  EVPIPE_REQUIRE_REAL(dir, rel);
  const auto cam = camera::load_camera(dir + "/camera.yaml");
  const auto model = camera::load_line_model(dir + "/model.yaml");
  const auto gt = camera::read_trajectory_csv(dir + "/gt.csv");
  const auto batch = io::read_all(dir + "/events.aedat4");
  for (const bool with_prior : {true, false}) {
    if (!with_prior && !kWholeSequences) continue;
    SCOPED_TRACE(with_prior ? "with the prior" : "without a prior");
    std::optional<camera::PosePrior> prior;
    if (with_prior) prior = camera::load_prior(dir + "/prior.yaml");
    pose::EstimatorOptions eo;
    eo.init.alignment.max_level0_reads = kAlignmentReads;
    pose::PoseEstimator est(cam, model, prior, eo);
    int tracking = 0, wrong = 0, good = 0, windows = 0;
    for (std::int64_t t0 = batch.events.front().t_us; t0 + 30'000 <= batch.events.back().t_us; t0 += 30'000) {
      if (!kWholeSequences && t0 - batch.events.front().t_us >= 4 * 30'000) break;
      const auto out = est.process(slice(batch.events, t0, t0 + 30'000), t0 + 15'000);
      const auto truth = camera::interpolate(gt, t0 + 15'000);
      if (!truth) continue;
      ++windows;
      if (out.status != pose::TrackStatus::tracking) continue;
      ++tracking;
      double deg = 0.0;
      const double mm = board_error(out.T_cam_model, *truth, deg);
      wrong += (mm > 20.0 || deg > 2.0) ? 1 : 0;
      good += (mm <= 10.0 && deg <= 1.0) ? 1 : 0;
    }
    std::cout << GetParam() << (with_prior ? " with prior: " : " without prior: ") << tracking << " of " << windows
              << " windows tracking, " << good << " within 10 mm / 1 deg, " << wrong << " wrong\n";
    EXPECT_EQ(wrong, 0);
    // The pan + tilt sequence is tracked from the prior (issue 21; measured 20 of 26 windows within 10 mm / 1 deg
    // on its raw events): the board's direct alignment starts it, and its 7 000-event windows are tracked alone
    // (before the background rate left the monitor's border out, as 100 ms histories: 2-4 windows per start).
    if (kWholeSequences && with_prior && std::string(GetParam()) == "seq_0003") {
      EXPECT_GE(good, windows / 2);
    }
  }
}
INSTANTIATE_TEST_SUITE_P(Sequences, RealBoard, ::testing::Values("seq_0001", "seq_0003"));

// The reference pose of the pan + tilt sequence verifies: the board is small (squares of ~5.9 px), so every cell of
// a grid line is crossed by the other direction's lines; when their events counted in a cell's side strips, the
// vertical lines (moving ~0.7 px per window against ~2 px for the horizontal ones) were never supported and the
// truth verified 7 of 19 segments. Pixels in another segment's band now count for no cell.
TEST(PoseVerify, TheRealBoardsReferencePoseVerifies) {
  EVPIPE_REQUIRE_REAL(dir, std::string("davis240-evbench-checkerboard/seq_0003"));
  const auto cam = camera::load_camera(dir + "/camera.yaml");
  const auto model = camera::load_line_model(dir + "/model.yaml");
  const auto gt = camera::read_trajectory_csv(dir + "/gt.csv");
  const auto batch = io::read_all(dir + "/events.aedat4");
  pose::VerifyOptions vo;
  vo.symmetries = pose::model_symmetries(model);
  int windows = 0, verified = 0;
  for (std::int64_t t0 = gt.front().t_us; t0 + 30'000 <= gt.back().t_us; t0 += 30'000) {
    const auto truth = camera::interpolate(gt, t0 + 15'000);
    if (!truth) continue;
    ++windows;
    pose::MotionHint hint;
    hint.before.t_us = t0;
    hint.before.pose = *camera::interpolate(gt, t0);
    hint.t_us = t0 + 15'000;
    const auto v = pose::verify_pose(slice(batch.events, t0, t0 + 30'000), cam, model, *truth, vo, hint);
    verified += v.ok ? 1 : 0;
  }
  // Measured 19 of 25 (before: the two windows checked showed 7 of 19 segments). The others fail only the
  // observability test: the 57 x 40 px board's tilt from its supported cells is 2.0-2.5 deg at 1 sigma, just over
  // the 2 deg bound (the planar target's weak tilt, docs/algorithms.md).
  std::cout << "seq_0003: the reference verifies in " << verified << " of " << windows << " windows\n";
  EXPECT_GE(verified, windows * 7 / 10);
}

// The partial symmetries of the two bundled models: the board's outline is mapped onto itself by the 180 deg turns
// about its three axes (the inner marks are not); the roadheader's body box by the turns about its own centre.
TEST(PoseVerify, ModelSymmetriesOfTheBundledModels) {
  const auto cfg = evpipe::testing::source_dir() / "config";
  const auto planar = camera::load_line_model((cfg / "target-planar.yaml").string());
  const auto S = pose::model_symmetries(planar);
  ASSERT_EQ(S.size(), 3u);
  for (const camera::Pose& s : S) {
    EXPECT_NEAR(camera::rotation_angle_deg(s, camera::Pose{}), 180.0, 1e-6);
    EXPECT_LT(s.t_cam_model_m.norm(), 1e-9);  // about the outline's centre, the model's origin
  }
  const auto rh = camera::load_line_model((cfg / "roadheader-wireframe.yaml").string());
  const auto R = pose::model_symmetries(rh);
  ASSERT_FALSE(R.empty());
  bool box_turn = false;  // 180 deg about y through the body box's centre (0.3, 0, 0.1) m
  for (const camera::Pose& s : R) {
    const Eigen::Vector3d c(0.3, 0.0, 0.1);
    box_turn = box_turn || ((s.apply(c) - c).norm() < 1e-6 && std::abs(std::abs(s.q_cam_model.y()) - 1.0) < 1e-6);
  }
  EXPECT_TRUE(box_turn);
  for (const camera::Pose& s : R) EXPECT_GT(camera::rotation_angle_deg(s, camera::Pose{}), 1.0);
}

// Without a prior the board's search can stop on the board seen from behind (turned 180 deg about an in-plane axis:
// its outline and top bar on the true ones, only the inner marks elsewhere). Seeded windows (0.8 m, 1 Hz/px) where
// the initialiser without the symmetry comparison returns that flip (seed 2: 4 windows; seed 3: 1): with it, the
// pose is the true one (seed 2) or none (seed 3: the inner marks hardly fire, the two are alike), never the flip.
TEST(PoseVerify, PlanarFlipWithoutPriorIsRefusedOrCorrected) {
  int flips = 0, corrected = 0, refused = 0;
  for (const std::uint64_t seed : {2u, 3u}) {
    const Scene s("target-planar.yaml", 0.8, seed, 400'000, 1.0);
    for (std::int64_t t = 45'000; t + 15'000 <= 400'000; t += 90'000) {
      SCOPED_TRACE(::testing::Message() << "seed " << seed << ", window at " << t);
      const camera::Pose truth = *camera::interpolate(s.scene.trajectory, t);
      const EventSpan w = slice(s.events, t - 15'000, t + 15'000);
      const pose::InitialiserOptions plain;
      const auto before = pose::initialise_pose(w, s.scene.camera, s.scene.model, std::nullopt, plain);
      pose::InitialiserOptions with = plain;
      with.verification.symmetries = pose::model_symmetries(s.scene.model);
      const auto after = pose::initialise_pose(w, s.scene.camera, s.scene.model, std::nullopt, with);
      const bool flip = before.ok && camera::rotation_angle_deg(before.T_cam_model, truth) > 170.0 &&
                        camera::translation_distance_m(before.T_cam_model, truth) < 0.2;
      if (!flip) continue;
      ++flips;
      if (!after.ok) {
        ++refused;
        EXPECT_NE(after.message.find("ambiguous"), std::string::npos) << after.message;
        continue;
      }
      ++corrected;
      EXPECT_LT(camera::rotation_angle_deg(after.T_cam_model, truth), 2.0);
      EXPECT_LT(camera::translation_distance_m(after.T_cam_model, truth), 0.02);
    }
  }
  EXPECT_EQ(flips, 5);  // the case exists on these seeds
  EXPECT_EQ(corrected, 4);
  EXPECT_EQ(refused, 1);
}

// An edge seen beside a required segment that shows no support (VerifyOptions::displaced_max_px) refutes the pose only
// when the pose moved onto it explains the window better. The planar target rendered with its diagonal moved 25 mm
// across itself (~7.6 px at 0.8 m) and judged with the true model at the true pose: the diagonal is empty and its
// edge runs beside it, but moving the whole model there would empty every other segment, so the pose is not
// refused for it (as unrelated parallel structure beside a segment must not refute a true pose: a monitor's border
// beside the real board's outline). The moved model is still found: the same windows judged with the diagonal's
// own model at the true pose verify.
TEST(PoseVerify, AnEdgeBesideOneSegmentDoesNotRefuteAPoseTheRestConfirms) {
  const auto cfg = evpipe::testing::source_dir() / "config";
  const camera::LineModel model = camera::load_line_model((cfg / "target-planar.yaml").string());
  constexpr std::size_t kDiagonal = 7;
  camera::LineModel moved = model;
  {
    camera::Segment3& s = moved.segments_m[kDiagonal];
    const Eigen::Vector3d along = (s.b_m - s.a_m).normalized();
    const Eigen::Vector3d across = Eigen::Vector3d::UnitZ().cross(along).normalized() * 0.025;
    s.a_m += across;
    s.b_m += across;
  }
  int windows = 0, verified = 0, displaced = 0, moved_verified = 0;
  for (const std::uint64_t seed : {31u, 32u, 33u}) {
    Scene shifted("target-planar.yaml", 0.8, seed, 600'000);
    shifted.scene.model = moved;
    std::mt19937_64 rng(seed);
    shifted.events = sim::render_target(shifted.scene, 0, 600'000, rng);
    for (std::int64_t t = 45'000; t + 15'000 <= 600'000; t += 30'000, ++windows) {
      const auto T = *camera::interpolate(shifted.scene.trajectory, t);
      const pose::MotionHint hint{
          camera::StampedPose{t - 30'000, *camera::interpolate(shifted.scene.trajectory, t - 30'000)}, t};
      const EventSpan w = slice(shifted.events, t - 15'000, t + 15'000);
      const auto v = pose::verify_pose(w, shifted.scene.camera, model, T, {}, hint);
      verified += v.ok ? 1 : 0;
      displaced += v.displaced_segment >= 0 ? 1 : 0;
      moved_verified += pose::verify_pose(w, shifted.scene.camera, moved, T, {}, hint).ok ? 1 : 0;
    }
  }
  std::cout << "diagonal moved 25 mm: the true pose verifies in " << verified << " of " << windows
            << " windows (refuted for a displaced edge: " << displaced << "); with the moved model " << moved_verified
            << "\n";
  EXPECT_EQ(displaced, 0);
  EXPECT_GE(verified * 10, windows * 7);  // measured 45 of 57 in both
  EXPECT_GE(moved_verified * 10, windows * 7);
}

// The case the displaced-edge refutation is for (tools/pose_seeds.sh, planar decoy seeds: a board slid onto a
// decoy's parallel edges): unmodelled horizontal lines on the board's body run 14 px below each horizontal segment.
// The pose moved 14 px down the image (a turn about the camera's x axis) keeps every vertical edge on its events
// (it slid along them) and puts every horizontal segment on the unmodelled lines, so its edges fix it, but its
// diagonal falls ~9.5 px beside the diagonal's own events: that pose is refused for the displaced diagonal. The
// true pose of the same windows verifies and is never refuted for a displaced edge.
TEST(PoseVerify, AnEdgeSeenBesideItsEmptySegmentRefutesThePose) {
  const auto cfg = evpipe::testing::source_dir() / "config";
  constexpr std::size_t kDiagonal = 7;
  constexpr double kShiftPx = 14.0, kDistanceM = 0.6;
  sim::TargetScene scene;
  scene.camera = camera::load_camera((cfg / "davis346.yaml").string());
  scene.model = camera::load_line_model((cfg / "target-planar.yaml").string());
  const camera::LineModel model = scene.model;
  for (const auto& s : model.segments_m) {
    if (std::abs(s.a_m.y() - s.b_m.y()) > 1e-9) continue;
    const Eigen::Vector3d down(0.0, kShiftPx * kDistanceM / scene.camera.fy, 0.0);
    scene.model.segments_m.push_back(camera::Segment3{s.a_m + down, s.b_m + down});
  }
  // The image moved down by kShiftPx: the camera frame turned about its x axis.
  const Eigen::Quaterniond turn(Eigen::AngleAxisd(-std::atan(kShiftPx / scene.camera.fy), Eigen::Vector3d::UnitX()));
  const auto moved = [&](const camera::Pose& T) {
    camera::Pose out;
    out.q_cam_model = (turn * T.q_cam_model).normalized();
    out.t_cam_model_m = turn * T.t_cam_model_m;
    return out;
  };
  int windows = 0, true_ok = 0, true_displaced = 0, moved_ok = 0, moved_diagonal = 0;
  for (const std::uint64_t seed : {41u, 42u}) {
    const camera::Pose base = sim::facing_pose(model, kDistanceM, sim::default_view(model));
    camera::Pose end = base;
    end.t_cam_model_m += Eigen::Vector3d(0.08, -0.07, 0.0);  // 0.18 m/s, across the diagonal
    scene.trajectory = {camera::StampedPose{0, base}, camera::StampedPose{600'000, end}};
    std::mt19937_64 rng(seed);
    std::vector<Event> events = sim::render_target(scene, 0, 600'000, rng);
    std::mt19937_64 noise_rng(seed + 1);
    sim::NoiseOptions no;
    no.rate_hz_per_pixel = 1.0;
    const auto noise =
        sim::background_activity(SensorGeometry{scene.camera.width, scene.camera.height}, 0, 600'000, no, noise_rng);
    events.insert(events.end(), noise.begin(), noise.end());
    std::stable_sort(events.begin(), events.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
    for (std::int64_t t = 45'000; t + 15'000 <= 600'000; t += 30'000, ++windows) {
      const auto T = *camera::interpolate(scene.trajectory, t);
      const auto T_before = *camera::interpolate(scene.trajectory, t - 30'000);
      const EventSpan w = slice(events, t - 15'000, t + 15'000);
      const auto v = pose::verify_pose(w, scene.camera, model, T, {}, pose::MotionHint{{t - 30'000, T_before}, t});
      true_ok += v.ok ? 1 : 0;
      true_displaced += v.displaced_segment >= 0 ? 1 : 0;
      const auto m =
          pose::verify_pose(w, scene.camera, model, moved(T), {}, pose::MotionHint{{t - 30'000, moved(T_before)}, t});
      moved_ok += m.ok ? 1 : 0;
      moved_diagonal += m.displaced_segment == static_cast<int>(kDiagonal) ? 1 : 0;
    }
  }
  std::cout << "board with unmodelled lines 14 px below its horizontal ones: the true pose verifies in " << true_ok
            << " of " << windows << " windows (refuted for a displaced edge: " << true_displaced
            << "); moved onto them: verifies in " << moved_ok << ", refuted for the displaced diagonal in "
            << moved_diagonal << "\n";
  EXPECT_EQ(true_displaced, 0);
  EXPECT_GE(true_ok * 10, windows * 8);
  EXPECT_EQ(moved_ok, 0);
  EXPECT_GE(moved_diagonal * 10, windows * 8);
}
