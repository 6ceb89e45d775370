// align_at_prior (prior_alignment.hpp): direct model-to-events alignment around a prior.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <numbers>
#include <optional>
#include <random>

#include "evbench_board.hpp"
#include "evpipe/camera/trajectory.hpp"
#include "evpipe/io/reader.hpp"
#include "evpipe/pose/initialiser.hpp"
#include "evpipe/pose/prior_alignment.hpp"
#include "evpipe/pose/tracker.hpp"
#include "evpipe/pose/verification.hpp"
#include "evpipe/sim/target3d.hpp"
#include "evpipe_test_data.hpp"
#include "pose_scenes.hpp"

using namespace evpipe;

namespace {

EventSpan slice(const std::vector<Event>& ev, std::int64_t t0, std::int64_t t1) {
  const auto a = std::lower_bound(ev.begin(), ev.end(), t0, [](const Event& e, std::int64_t t) { return e.t_us < t; });
  const auto b = std::lower_bound(a, ev.end(), t1, [](const Event& e, std::int64_t t) { return e.t_us < t; });
  return {a, b};
}

using pose_test::board_error;

camera::LineModel grid_board() {
  return pose_test::evbench_board(true);
}

// The board seen small (DAVIS346 at 1.2 m: grid lines a few pixels apart, as the real DAVIS240 board), moving by
// evsim's seeded default motion.
struct BoardScene {
  sim::TargetScene scene;
  std::vector<Event> events;
  explicit BoardScene(std::uint64_t seed) {
    const auto cfg = evpipe::testing::source_dir() / "config";
    scene.camera = camera::load_camera((cfg / "davis346.yaml").string());
    scene.model = grid_board();
    sim::MotionOptions mo;
    mo.base = sim::facing_pose(scene.model, 1.2, sim::default_view(scene.model));
    mo.pivot_model_m = sim::bbox_centre(scene.model);
    std::mt19937_64 rng(seed);
    scene.trajectory = sim::generate_motion(0, 300'000, mo, rng);
    events = sim::render_target(scene, 0, 300'000, rng);
  }
};

// The pose moved by position_m and turned by angle_deg about the model's centre (seeded random directions).
camera::Pose perturbed(const camera::Pose& T, const Eigen::Vector3d& centre_model, double position_m, double angle_deg,
                       std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  const Eigen::Vector3d dt = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized() * position_m;
  const Eigen::Vector3d axis = Eigen::Vector3d(n(rng), n(rng), n(rng)).normalized();
  const Eigen::Quaterniond R(Eigen::AngleAxisd(angle_deg * std::numbers::pi / 180.0, axis));
  const Eigen::Vector3d c = T.apply(centre_model);
  camera::Pose P;
  P.q_cam_model = (R * T.q_cam_model).normalized();
  P.t_cam_model_m = R * (T.t_cam_model_m - c) + c + dt;
  return P;
}

}  // namespace

TEST(PriorAlignment, EmptyWindowIsNotOk) {
  camera::CameraModel cam;
  cam.width = 240;
  cam.height = 180;
  cam.fx = cam.fy = 200.0;
  cam.cx = 120.0;
  cam.cy = 90.0;
  camera::PosePrior prior;
  prior.pose.t_cam_model_m = Eigen::Vector3d(-0.135, -0.0945, 1.0);
  const auto r = pose::align_at_prior({}, cam, grid_board(), prior);
  EXPECT_FALSE(r.ok);
  EXPECT_FALSE(r.message.empty());
}

// The score: the true pose beats the board shifted by one grid line (the aliasing the search must resolve) and the
// board turned by 10 degrees.
TEST(PriorAlignment, TheTruthScoresAboveTheGridShiftedByOneLine) {
  const BoardScene s(3);
  const std::int64_t t = 150'000;
  const auto w = slice(s.events, t - 15'000, t + 15'000);
  const camera::Pose truth = *camera::interpolate(s.scene.trajectory, t);
  camera::Pose shifted = truth;
  shifted.t_cam_model_m += truth.q_cam_model * Eigen::Vector3d(0.027, 0.0, 0.0);
  const double at_truth = pose::prior_alignment_score(w, s.scene.camera, s.scene.model, truth);
  EXPECT_GT(at_truth, 0.0);
  EXPECT_GT(at_truth, pose::prior_alignment_score(w, s.scene.camera, s.scene.model, shifted));
  std::mt19937_64 rng(5);
  const camera::Pose turned = perturbed(truth, Eigen::Vector3d(0.135, 0.0945, 0.0), 0.0, 10.0, rng);
  EXPECT_GT(at_truth, pose::prior_alignment_score(w, s.scene.camera, s.scene.model, turned));
}

// Under the sanitizers (Debug, ~20x slower) two windows per seed and the initialiser's alignment on a grid 100x coarser
// cover the code paths (82 s with every window); the optimised builds check the search's reach.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr std::int64_t kLastWindowUs = 120'000;
constexpr double kInitAlignmentReads = 2e6;
constexpr std::uint64_t kLastBoardSeed = 3;  // one seed (62 s under ASan with two)
#else
constexpr std::int64_t kLastWindowUs = 240'000;
constexpr double kInitAlignmentReads = pose::PriorAlignmentOptions{}.max_level0_reads;
constexpr std::uint64_t kLastBoardSeed = 4;
#endif

// From a prior 50 mm / 10 deg off (seeded directions) the alignment lands within the tracker's reach of the truth
// (measured: 1.5-12 mm / 1.6-5.7 deg before refinement), and a direct initialisation is never wrong. (The line
// correspondences' pose of this small board can be: seen 130 mm / 21 deg verified from 4 lines, seed 3 at 240 ms;
// the default initialiser therefore aligns this board directly.)
TEST(PriorAlignment, SmallGridBoardFromAPriorOff50mm10deg) {
  for (std::uint64_t seed = 3; seed <= kLastBoardSeed; ++seed) {
    const BoardScene s(seed);
    std::mt19937_64 rng(seed + 100);
    for (std::int64_t t = 60'000; t <= kLastWindowUs; t += 60'000) {
      SCOPED_TRACE(::testing::Message() << "seed " << seed << ", window at " << t);
      const auto w = slice(s.events, t - 30'000, t + 30'000);
      const camera::Pose truth = *camera::interpolate(s.scene.trajectory, t);
      camera::PosePrior prior;
      prior.pose = perturbed(truth, Eigen::Vector3d(0.135, 0.0945, 0.0), 0.05, 10.0, rng);
      const auto a = pose::align_at_prior(w, s.scene.camera, s.scene.model, prior);
      ASSERT_TRUE(a.ok) << a.message;
      double deg = 0.0;
      const double mm = board_error(a.T_cam_model, truth, deg);
      std::cout << w.size() << " events, aligned: " << mm << " mm / " << deg << " deg (" << a.message << ")\n";
      EXPECT_LT(mm, 20.0);
      EXPECT_LT(deg, 8.0);
      pose::InitialiserOptions io;
      io.verification.symmetries = pose::model_symmetries(s.scene.model);
      io.alignment.max_level0_reads = kInitAlignmentReads;
      const auto init = pose::initialise_pose(w, s.scene.camera, s.scene.model, prior, io);
      // The board is finer than the line search resolves: DirectAlignment::automatic searches it directly, never by
      // the lines (their poses alias onto other grid lines: 180 mm / 29 deg off in the pipeline).
      EXPECT_TRUE(init.direct || !init.ok) << init.message;
      if (!init.ok) continue;
      EXPECT_TRUE(init.verified);
      EXPECT_LT(board_error(init.T_cam_model, truth, deg), 20.0);
      EXPECT_LT(deg, 2.0);
    }
  }
}

// parallel_spacing_px and crowded_length_share (what DirectAlignment::automatic decides on): the board facing the
// camera has its grid lines f x 27 mm / Z apart, 5.5 px at 1.2 m on the DAVIS346 (finer than the line search's
// consistency band, 8 px: all of the board is crowded) and 16 px at 0.4 m (none is); a single segment has no
// parallel neighbour; the roadheader wireframe at 1 m has a few thin parts, far from half of its length.
TEST(PriorAlignment, ParallelSpacingIsTheGridPitchInPixels) {
  const auto cam = camera::load_camera((evpipe::testing::source_dir() / "config" / "davis346.yaml").string());
  const camera::LineModel board = grid_board();
  const pose::InitialiserOptions io;
  for (const double z : {1.2, 0.4}) {
    const camera::Pose T = sim::facing_pose(board, z);
    const double pitch = cam.fx * 0.027 / z;
    EXPECT_NEAR(pose::parallel_spacing_px(cam, board, T), pitch, 0.05 * pitch) << z << " m";
    EXPECT_EQ(pose::parallel_spacing_px(cam, board, T) < io.consistency_px, z > 1.0);
    EXPECT_DOUBLE_EQ(pose::crowded_length_share(cam, board, T, io.consistency_px), z > 1.0 ? 1.0 : 0.0);
  }
  const auto roadheader =
      camera::load_line_model((evpipe::testing::source_dir() / "config" / "roadheader-wireframe.yaml").string());
  const double share = pose::crowded_length_share(
      cam, roadheader, sim::facing_pose(roadheader, 1.0, sim::default_view(roadheader)), io.consistency_px);
  std::cout << "roadheader at 1 m: " << share << " of its length crowded\n";
  EXPECT_LT(share, 0.5);
  camera::LineModel one;
  one.segments_m.push_back(board.segments_m.front());
  EXPECT_TRUE(std::isinf(pose::parallel_spacing_px(cam, one, sim::facing_pose(board, 1.0))));
}

// The real DAVIS240 board (../shared/data/real/davis240-evbench-checkerboard, seq_0003, pan + tilt) from its prior
// (50 mm / 10 deg off), carried to windows every 120 ms: the line correspondences give no verified pose there (few,
// one-sided lines of a 57 x 40 px board); the direct alignment does in most windows. Measured: 6 of 7 within
// 10 mm / 1.4 deg, one wrong (255 ms: 76 mm / 19 deg, verified): why the option is off by default.
TEST(PriorAlignment, RealBoardInitialisesFromThePrior) {
  const std::string rel = "davis240-evbench-checkerboard/seq_0003";
  EVPIPE_REQUIRE_REAL(dir, rel);
  const auto cam = camera::load_camera(dir + "/camera.yaml");
  const auto model = camera::load_line_model(dir + "/model.yaml");
  const auto gt = camera::read_trajectory_csv(dir + "/gt.csv");
  const auto batch = io::read_all(dir + "/events.aedat4");
  const auto prior = camera::load_prior(dir + "/prior.yaml");
  const camera::Pose offset = gt.front().pose.inverse() * prior.pose;  // the prior's error, carried to each window
  pose::InitialiserOptions io;
  io.direct_alignment = pose::DirectAlignment::on;
  io.verification.symmetries = pose::model_symmetries(model);
  int good = 0, wrong = 0, windows = 0;
  for (std::int64_t t = gt.front().t_us + 15'000; t + 15'000 < gt.back().t_us; t += 120'000) {
    const auto truth = *camera::interpolate(gt, t);
    camera::PosePrior p = prior;
    p.pose = truth * offset;
    const auto init = pose::initialise_pose(slice(batch.events, t - 15'000, t + 15'000), cam, model, p, io);
    ++windows;
    if (!init.ok || !init.verified) continue;  // an unverified pose is left to the tracker's verification
    double deg = 0.0;
    const double mm = board_error(init.T_cam_model, truth, deg);
    good += mm <= 10.0 && deg <= 1.5 ? 1 : 0;
    wrong += mm > 20.0 || deg > 2.0 ? 1 : 0;
    std::cout << (t - gt.front().t_us) / 1000 << " ms: " << mm << " mm / " << deg << " deg (" << init.message << ")\n";
  }
  std::cout << good << " of " << windows << " windows initialised within 10 mm / 1.5 deg, " << wrong << " wrong\n";
  EXPECT_GE(good, windows / 2);
  EXPECT_LE(wrong, 1);  // a known defect (above), not the target: 0
}

// The work bound (PriorAlignmentOptions::max_level0_reads): the roadheader wireframe (close parallel segments set a
// fine blur) inside a wide tolerance (0.3 m / 45 deg) meant a level-0 grid of ~10^8 poses (this call ran over 2
// minutes without the bound; 5 GB on a clutter scene, docs/history.md session 16). The grid now coarsens until it
// fits (1.4 s), and the truth is still found from a prior 20 mm / 4 deg off. Counted in poses scored, not timed.
TEST(PriorAlignment, ALongModelInAWideToleranceStaysWithinTheWorkBound) {
  sim::TargetScene scene;
  scene.camera = pose_test::davis346();
  scene.model = pose_test::load_model("roadheader-wireframe.yaml");
  sim::MotionOptions mo;
  mo.base = sim::facing_pose(scene.model, 1.0, sim::default_view(scene.model));
  mo.pivot_model_m = sim::bbox_centre(scene.model);
  std::mt19937_64 rng(2302);
  scene.trajectory = sim::generate_motion(0, 100'000, mo, rng);
  const std::vector<Event> events = sim::render_target(scene, 0, 100'000, rng);
  const auto w = slice(events, 20'000, 80'000);
  const camera::Pose truth = *camera::interpolate(scene.trajectory, 50'000);
  camera::PosePrior prior;
  prior.pose = perturbed(truth, sim::bbox_centre(scene.model), 0.02, 4.0, rng);
  prior.position_tolerance_m = 0.3;
  prior.angle_tolerance_deg = 45.0;
  const pose::PriorAlignmentOptions o;
  const auto a = pose::align_at_prior(w, scene.camera, scene.model, prior, o);
  ASSERT_TRUE(a.ok) << a.message;
  std::cout << w.size() << " events: " << a.message << ", "
            << camera::translation_distance_m(a.T_cam_model, truth) * 1e3 << " mm / "
            << camera::rotation_angle_deg(a.T_cam_model, truth) << " deg\n";
  // Level 0 reads at most max_level0_reads samples, each pose at least one per segment; the finer levels (at most 8
  // here) search from each candidate, then from 24 starts around the best, each search 1 + 12 x max_moves poses.
  EXPECT_LT(static_cast<double>(a.evaluations),
            o.max_level0_reads / static_cast<double>(scene.model.segments_m.size()) +
                (static_cast<double>(o.candidates) * 8.0 + 24.0) * (1.0 + 12.0 * o.max_moves));
  EXPECT_LT(camera::translation_distance_m(a.T_cam_model, truth), 0.02);
  EXPECT_LT(camera::rotation_angle_deg(a.T_cam_model, truth), 2.0);
}
