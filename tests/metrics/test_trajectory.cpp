// Trajectory accuracy: error statistics, ATE / per-axis / rotation errors against an interpolated truth,
// skipped poses, the status filter and time coverage, on hand-made trajectories with known errors.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include <Eigen/Cholesky>

#include "evpipe/metrics/trajectory.hpp"

namespace evpipe::metrics {
namespace {

using camera::Pose;
using camera::StampedPose;

constexpr double kTol = 1e-9;

Eigen::Quaterniond rot_z_deg(double deg) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(deg * std::numbers::pi / 180.0, Eigen::Vector3d::UnitZ()));
}

StampedPose pose_at(std::int64_t t_us, const Eigen::Vector3d& t_m, double yaw_deg = 0.0) {
  StampedPose sp;
  sp.t_us = t_us;
  sp.pose.t_cam_model_m = t_m;
  sp.pose.q_cam_model = rot_z_deg(yaw_deg);
  return sp;
}

/// Truth at 1 kHz over [0, 10 ms]: x moves 1 mm per ms, z = 1 m, the yaw turns 1 degree per ms.
std::vector<StampedPose> linear_truth() {
  std::vector<StampedPose> truth;
  for (std::int64_t t_us = 0; t_us <= 10'000; t_us += 1000) {
    truth.push_back(pose_at(t_us, {static_cast<double>(t_us) * 1e-6, 0.0, 1.0}, static_cast<double>(t_us) / 1000.0));
  }
  return truth;
}

/// The truth at t_us (exactly, for linear_truth) plus an offset in mm and a yaw offset in degrees.
StampedPose perturbed(std::int64_t t_us, const Eigen::Vector3d& offset_mm, double yaw_offset_deg = 0.0) {
  return pose_at(t_us, Eigen::Vector3d(static_cast<double>(t_us) * 1e-6, 0.0, 1.0) + offset_mm / 1000.0,
                 static_cast<double>(t_us) / 1000.0 + yaw_offset_deg);
}

TEST(ErrorStats, ByHand) {
  EXPECT_FALSE(error_stats({}).has_value());
  const std::vector<double> even = {4.0, 1.0, 3.0, 2.0};
  const ErrorStats s = *error_stats(even);
  EXPECT_EQ(s.count, 4u);
  EXPECT_DOUBLE_EQ(s.mean, 2.5);
  EXPECT_DOUBLE_EQ(s.rmse, std::sqrt(30.0 / 4.0));
  EXPECT_DOUBLE_EQ(s.median, 2.5);           // mean of the two middle values
  EXPECT_DOUBLE_EQ(s.std, std::sqrt(1.25));  // population std (divide by n)
  EXPECT_DOUBLE_EQ(s.max, 4.0);
  EXPECT_NEAR(s.rmse * s.rmse, s.mean * s.mean + s.std * s.std, 1e-12);
  const std::vector<double> odd = {5.0, 1.0, 3.0};
  EXPECT_DOUBLE_EQ(error_stats(odd)->median, 3.0);
  const std::vector<double> one = {7.0};
  const ErrorStats o = *error_stats(one);
  EXPECT_DOUBLE_EQ(o.rmse, 7.0);
  EXPECT_DOUBLE_EQ(o.std, 0.0);
  EXPECT_DOUBLE_EQ(o.median, 7.0);
}

TEST(TruthAt, InterpolatesBetweenRowsExactAtStampsNulloptOutside) {
  const auto truth = linear_truth();
  const Pose mid = *truth_at(truth, 2500);
  EXPECT_NEAR(mid.t_cam_model_m.x(), 0.0025, 1e-15);
  EXPECT_NEAR(camera::rotation_angle_deg(mid, Pose{rot_z_deg(2.5), {}}), 0.0, kTol);
  EXPECT_EQ(truth_at(truth, 3000)->t_cam_model_m, truth[3].pose.t_cam_model_m);
  EXPECT_EQ(truth_at(truth, 10'000)->t_cam_model_m, truth.back().pose.t_cam_model_m);
  EXPECT_FALSE(truth_at(truth, -1));
  EXPECT_FALSE(truth_at(truth, 10'001));
  EXPECT_FALSE(truth_at({}, 0));
}

TEST(EvaluateTrajectory, KnownErrorsSkippedPosesAndCoverage) {
  const auto truth = linear_truth();
  // Errors: (3, -4, 0) mm = 5 mm, (0, 0, 12) mm = 12 mm, (-6, 8, 0) = 10 mm, (0, 0, 0); yaw offsets 2, 0, -1, 0.
  // The first one sits between truth rows: the truth is interpolated there.
  const std::vector<StampedPose> estimate = {
      perturbed(-10, {1.0, 1.0, 1.0}),        // before the truth: skipped
      perturbed(500, {3.0, -4.0, 0.0}, 2.0),  // interpolated truth
      perturbed(2000, {0.0, 0.0, 12.0}),     perturbed(3000, {-6.0, 8.0, 0.0}, -1.0),
      perturbed(9000, {0.0, 0.0, 0.0}),      perturbed(20'000, {1.0, 1.0, 1.0}),  // after the truth: skipped
  };
  TrajectoryEvalOptions opt;
  opt.max_gap_us = 1500;
  const TrajectoryEval r = evaluate_trajectory(estimate, truth, opt);
  EXPECT_EQ(r.poses_in, 6u);
  EXPECT_EQ(r.poses_before_truth, 1u);
  EXPECT_EQ(r.poses_after_truth, 1u);
  EXPECT_EQ(r.poses_not_tracking, 0u);
  EXPECT_EQ(r.poses_evaluated, 4u);
  EXPECT_FALSE(r.poses_tracking.has_value());
  EXPECT_DOUBLE_EQ(*r.matched_fraction, 4.0 / 6.0);
  // Gaps 1500 (covered: <= max_gap), 1000 (covered), 6000 (not) over the 10 ms span.
  EXPECT_DOUBLE_EQ(*r.time_coverage, 2500.0 / 10'000.0);
  EXPECT_DOUBLE_EQ(*r.first_pose_delay_ms, 0.5);

  ASSERT_TRUE(r.ate_mm);
  const ErrorStats& ate = *r.ate_mm;
  EXPECT_EQ(ate.count, 4u);
  EXPECT_NEAR(ate.mean, (5.0 + 12.0 + 10.0 + 0.0) / 4.0, kTol);
  EXPECT_NEAR(ate.rmse, std::sqrt((25.0 + 144.0 + 100.0) / 4.0), kTol);
  EXPECT_NEAR(ate.median, 7.5, kTol);
  EXPECT_NEAR(ate.max, 12.0, kTol);
  const double mean = 6.75;
  EXPECT_NEAR(
      ate.std,
      std::sqrt(((5 - mean) * (5 - mean) + (12 - mean) * (12 - mean) + (10 - mean) * (10 - mean) + mean * mean) / 4.0),
      kTol);

  // Per axis: x errors 3, 0, -6, 0; y -4, 0, 8, 0; z 0, 12, 0, 0.
  ASSERT_TRUE(r.axis_mm[0] && r.axis_mm[1] && r.axis_mm[2]);
  EXPECT_NEAR(r.axis_mm[0]->bias, -0.75, kTol);
  EXPECT_NEAR(r.axis_mm[0]->abs.mean, 2.25, kTol);
  EXPECT_NEAR(r.axis_mm[0]->abs.median, 1.5, kTol);
  EXPECT_NEAR(r.axis_mm[0]->abs.max, 6.0, kTol);
  EXPECT_NEAR(r.axis_mm[0]->abs.rmse, std::sqrt(45.0 / 4.0), kTol);
  EXPECT_NEAR(r.axis_mm[1]->bias, 1.0, kTol);
  EXPECT_NEAR(r.axis_mm[1]->abs.max, 8.0, kTol);
  EXPECT_NEAR(r.axis_mm[2]->bias, 3.0, kTol);
  EXPECT_NEAR(r.axis_mm[2]->abs.rmse, 6.0, kTol);  // sqrt(144 / 4)
  EXPECT_NEAR(r.axis_mm[2]->abs.median, 0.0, kTol);

  // Rotation errors 2, 0, 1, 0 degrees (the first against the slerped truth at 0.5 degrees).
  ASSERT_TRUE(r.rotation_deg);
  EXPECT_NEAR(r.rotation_deg->mean, 0.75, kTol);
  EXPECT_NEAR(r.rotation_deg->rmse, std::sqrt(5.0 / 4.0), kTol);
  EXPECT_NEAR(r.rotation_deg->median, 0.5, kTol);
  EXPECT_NEAR(r.rotation_deg->max, 2.0, kTol);

  ASSERT_EQ(r.samples.size(), 4u);
  EXPECT_EQ(r.samples[0].t_us, 500);
  EXPECT_NEAR(r.samples[0].t_truth_m.x(), 0.0005, 1e-15);
  EXPECT_NEAR(r.samples[0].error_mm.y(), -4.0, kTol);
  EXPECT_NEAR(r.samples[3].rotation_error_deg, 0.0, kTol);
}

TEST(EvaluateTrajectory, PerfectEstimateCoversTheWholeSpan) {
  const auto truth = linear_truth();
  const TrajectoryEval r = evaluate_trajectory(truth, truth);  // default max gap 100 ms > 1 ms rows
  EXPECT_EQ(r.poses_evaluated, truth.size());
  EXPECT_DOUBLE_EQ(*r.matched_fraction, 1.0);
  EXPECT_DOUBLE_EQ(*r.time_coverage, 1.0);
  EXPECT_DOUBLE_EQ(*r.first_pose_delay_ms, 0.0);
  EXPECT_DOUBLE_EQ(r.ate_mm->max, 0.0);
  EXPECT_DOUBLE_EQ(r.rotation_deg->max, 0.0);
}

TEST(EvaluateTrajectory, OnlyTrackingSkipsOtherStatusesAndTheirGaps) {
  const auto truth = linear_truth();
  std::vector<StampedPose> estimate;
  for (std::int64_t t_us = 0; t_us <= 10'000; t_us += 1000) estimate.push_back(perturbed(t_us, {0.0, 0.0, 2.0}));
  estimate[0] = perturbed(0, {0.0, 0.0, 500.0});  // a wild pose while initialising
  const std::vector<std::string> status = {"initialising", "tracking", "tracking", "tracking", "lost",    "lost",
                                           "tracking",     "tracking", "tracking", "tracking", "tracking"};
  TrajectoryEvalOptions opt;
  opt.max_gap_us = 1000;
  const TrajectoryEval all = evaluate_trajectory(estimate, truth, opt, status);
  EXPECT_EQ(all.poses_evaluated, 11u);
  EXPECT_EQ(*all.poses_tracking, 8u);
  EXPECT_NEAR(all.ate_mm->max, 500.0, kTol);
  EXPECT_DOUBLE_EQ(*all.time_coverage, 1.0);

  opt.only_tracking = true;
  const TrajectoryEval tr = evaluate_trajectory(estimate, truth, opt, status);
  EXPECT_EQ(tr.poses_not_tracking, 3u);
  EXPECT_EQ(tr.poses_evaluated, 8u);
  EXPECT_DOUBLE_EQ(*tr.matched_fraction, 1.0);
  EXPECT_NEAR(tr.ate_mm->max, 2.0, kTol);
  EXPECT_NEAR(tr.ate_mm->std, 0.0, kTol);
  // Tracking at 1..3 ms and 6..10 ms: gaps of 1 ms covered, the 3 ms gap (3 -> 6) not: 2 + 4 ms of 10.
  EXPECT_DOUBLE_EQ(*tr.time_coverage, 0.6);
  EXPECT_DOUBLE_EQ(*tr.first_pose_delay_ms, 1.0);
}

TEST(EvaluateTrajectory, NoOverlapAndEmptyInputsGiveNoStatistics) {
  const auto truth = linear_truth();
  const std::vector<StampedPose> late = {perturbed(20'000, Eigen::Vector3d::Zero()),
                                         perturbed(30'000, Eigen::Vector3d::Zero())};
  const TrajectoryEval r = evaluate_trajectory(late, truth);
  EXPECT_EQ(r.poses_evaluated, 0u);
  EXPECT_EQ(r.poses_after_truth, 2u);
  EXPECT_DOUBLE_EQ(*r.matched_fraction, 0.0);
  EXPECT_DOUBLE_EQ(*r.time_coverage, 0.0);
  EXPECT_FALSE(r.ate_mm || r.rotation_deg || r.axis_mm[0] || r.first_pose_delay_ms);

  const TrajectoryEval empty = evaluate_trajectory({}, truth);
  EXPECT_EQ(empty.poses_in, 0u);
  EXPECT_FALSE(empty.matched_fraction);

  const TrajectoryEval no_truth = evaluate_trajectory(late, {});
  EXPECT_EQ(no_truth.poses_before_truth, 2u);
  EXPECT_FALSE(no_truth.time_coverage);

  const std::vector<StampedPose> single = {truth[2]};
  const TrajectoryEval one_row_truth = evaluate_trajectory(single, single);
  EXPECT_EQ(one_row_truth.poses_evaluated, 1u);
  EXPECT_FALSE(one_row_truth.time_coverage);  // zero span
}

TEST(EvaluateTrajectory, RejectsBadArguments) {
  const auto truth = linear_truth();
  std::vector<StampedPose> unsorted = {truth[3], truth[1]};
  EXPECT_THROW((void)evaluate_trajectory(unsorted, truth), std::invalid_argument);
  EXPECT_THROW((void)evaluate_trajectory(truth, unsorted), std::invalid_argument);
  const std::vector<std::string> one_status = {"tracking"};
  EXPECT_THROW((void)evaluate_trajectory(truth, truth, {}, one_status), std::invalid_argument);
  TrajectoryEvalOptions opt;
  opt.only_tracking = true;
  EXPECT_THROW((void)evaluate_trajectory(truth, truth, opt), std::invalid_argument);
  opt.only_tracking = false;
  opt.max_gap_us = -1;
  EXPECT_THROW((void)evaluate_trajectory(truth, truth, opt), std::invalid_argument);
}

}  // namespace
}  // namespace evpipe::metrics

// ---- issue 21: wrong confident poses, holding, NEES, symmetry ------------------------------------------------

namespace evpipe::metrics {
namespace {

camera::StampedPose at(std::int64_t t_us, const Eigen::Vector3d& t_m, const Eigen::Quaterniond& q) {
  camera::StampedPose sp;
  sp.t_us = t_us;
  sp.pose.t_cam_model_m = t_m;
  sp.pose.q_cam_model = q.normalized();
  return sp;
}

TEST(TrajectoryTrust, WrongConfidentCountsTrackingAndHoldingOverEitherThreshold) {
  const Eigen::Vector3d base(0.1, 0.0, 1.0);
  const std::vector<camera::StampedPose> truth = {at(0, base, Eigen::Quaterniond::Identity()),
                                                  at(1000, base, Eigen::Quaterniond::Identity())};
  const auto turn = [](double deg) {
    return Eigen::Quaterniond(Eigen::AngleAxisd(deg * std::numbers::pi / 180.0, Eigen::Vector3d::UnitX()));
  };
  const std::vector<camera::StampedPose> est = {
      at(100, base + Eigen::Vector3d(0.019, 0, 0), turn(1.9)),  // tracking, within both: right
      at(200, base + Eigen::Vector3d(0.021, 0, 0), turn(0.0)),  // tracking, 21 mm: wrong
      at(300, base, turn(2.1)),                                 // holding, 2.1 deg: wrong
      at(400, base + Eigen::Vector3d(0.5, 0, 0), turn(0.0)),    // lost (not confident): not counted
      at(500, base, turn(0.0)),                                 // holding, right
  };
  const std::vector<std::string> status = {"tracking", "tracking", "holding", "lost", "holding"};
  TrajectoryEval r = evaluate_trajectory(est, truth, {}, status);
  EXPECT_EQ(r.confident_evaluated, 4u);
  EXPECT_EQ(r.wrong_confident, 2u);
  ASSERT_TRUE(r.wrong_confident_share);
  EXPECT_DOUBLE_EQ(*r.wrong_confident_share, 0.5);
  EXPECT_EQ(r.poses_holding, std::optional<std::size_t>(2));
  // only_tracking keeps the valid poses: tracking AND holding.
  TrajectoryEvalOptions valid;
  valid.only_tracking = true;
  r = evaluate_trajectory(est, truth, valid, status);
  EXPECT_EQ(r.poses_evaluated, 4u);
  EXPECT_EQ(r.poses_not_tracking, 1u);
  // Thresholds are options.
  TrajectoryEvalOptions loose;
  loose.wrong_max_mm = 30.0;
  loose.wrong_max_deg = 3.0;
  EXPECT_EQ(evaluate_trajectory(est, truth, loose, status).wrong_confident, 0u);
  // Without a status column every published pose is confident.
  EXPECT_EQ(evaluate_trajectory(est, truth).wrong_confident, 3u);
}

TEST(TrajectoryTrust, ErrorVectorIsTheCovarianceParametrisation) {
  // R = exp([d]x) R_hat, t = t_hat + dt: an estimate made from the truth by the inverse perturbation gives (d, dt).
  const Eigen::Vector3d d(0.01, -0.02, 0.005), dt(0.003, -0.001, 0.002);
  camera::Pose truth;
  truth.q_cam_model = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  truth.t_cam_model_m = Eigen::Vector3d(0.1, -0.2, 0.9);
  camera::Pose est;
  est.q_cam_model = Eigen::Quaterniond(Eigen::AngleAxisd(-d.norm(), d.normalized())) * truth.q_cam_model;
  est.t_cam_model_m = truth.t_cam_model_m - dt;
  const auto e = pose_error_vector(est, truth);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(e[i], d[i], 1e-12);
    EXPECT_NEAR(e[3 + i], dt[i], 1e-12);
  }
}

TEST(TrajectoryTrust, NeesOfKnownErrorsAndCovariances) {
  Eigen::Matrix<double, 6, 1> e;
  e << 0.01, 0.0, 0.0, 0.002, 0.0, 0.0;
  Eigen::Matrix<double, 6, 6> P = Eigen::Matrix<double, 6, 6>::Identity();
  P.diagonal() << 1e-4, 1e-4, 1e-4, 4e-6, 4e-6, 4e-6;
  ASSERT_TRUE(nees(e, P));
  EXPECT_NEAR(*nees(e, P), 1.0 + 1.0, 1e-9);
  Eigen::Matrix<double, 6, 6> bad = P;
  bad(0, 0) = -1.0;
  EXPECT_FALSE(nees(e, bad));
  bad = P;
  bad(0, 1) = 1e-3;  // not symmetric
  EXPECT_FALSE(nees(e, bad));

  // Seeded Gaussian errors drawn from the covariance: the mean NEES is close to 6; only tracking rows count.
  std::mt19937_64 rng(21);
  std::normal_distribution<double> g(0.0, 1.0);
  Eigen::Matrix<double, 6, 6> cov = Eigen::Matrix<double, 6, 6>::Zero();
  cov.diagonal() << 4e-6, 9e-6, 1e-6, 1e-6, 4e-6, 2.5e-5;
  cov(3, 5) = cov(5, 3) = 2e-6;
  const Eigen::Matrix<double, 6, 6> L = cov.llt().matrixL();
  std::vector<camera::StampedPose> truth, est;
  std::vector<std::string> status;
  std::vector<std::optional<Eigen::Matrix<double, 6, 6>>> covs;
  for (int i = 0; i < 2000; ++i) {
    camera::StampedPose t;
    t.t_us = i * 1000;
    t.pose.t_cam_model_m = Eigen::Vector3d(0, 0, 1);
    truth.push_back(t);
    Eigen::Matrix<double, 6, 1> z;
    for (int k = 0; k < 6; ++k) z[k] = g(rng);
    const Eigen::Matrix<double, 6, 1> err = L * z;
    camera::StampedPose e_pose = t;
    const Eigen::Vector3d rv = err.head<3>();
    e_pose.pose.q_cam_model = Eigen::Quaterniond(Eigen::AngleAxisd(-rv.norm(), rv.normalized())) * t.pose.q_cam_model;
    e_pose.pose.t_cam_model_m = t.pose.t_cam_model_m - err.tail<3>();
    est.push_back(e_pose);
    status.push_back(i % 10 == 0 ? "holding" : "tracking");
    covs.emplace_back(i % 7 == 0 ? std::nullopt : std::optional<Eigen::Matrix<double, 6, 6>>(cov));
  }
  const TrajectoryEval r = evaluate_trajectory(est, truth, {}, status, covs);
  ASSERT_TRUE(r.nees_mean);
  EXPECT_NEAR(*r.nees_mean, 6.0, 0.4);
  std::size_t expected = 0;
  for (int i = 0; i < 2000; ++i) expected += (i % 10 != 0 && i % 7 != 0) ? 1 : 0;
  EXPECT_EQ(r.nees_count, expected);
  EXPECT_EQ(r.nees_invalid, 0u);
  // No covariance anywhere: NEES n/a.
  EXPECT_FALSE(evaluate_trajectory(est, truth, {}, status).nees_mean);
}

TEST(TrajectoryTrust, PlanarRectSymmetryScoresAgainstTheBestEquivalentTruth) {
  // A 0.27 x 0.189 board in z = 0 with its corner at the origin (as the evbench model).
  const std::vector<Eigen::Vector3d> pts = {{0, 0, 0}, {0.27, 0, 0}, {0.27, 0.189, 0}, {0, 0.189, 0}};
  const auto syms = planar_rect_symmetries(pts);
  ASSERT_EQ(syms.size(), 3u);
  for (const auto& S : syms) {
    // Each maps the board's corners onto corners (the board onto itself).
    for (const auto& p : pts) {
      const Eigen::Vector3d q = S.apply(p);
      double best = 1e9;
      for (const auto& c : pts) best = std::min(best, (q - c).norm());
      EXPECT_LT(best, 1e-12);
    }
  }
  EXPECT_THROW((void)planar_rect_symmetries({{0, 0, 0}, {0, 0, 1}}), std::invalid_argument);

  camera::StampedPose g;
  g.pose.t_cam_model_m = Eigen::Vector3d(-0.1, 0.0, 0.9);
  g.pose.q_cam_model = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()));
  std::vector<camera::StampedPose> truth = {g, g};
  truth[1].t_us = 1000;
  camera::StampedPose e = g;
  e.t_us = 500;
  e.pose = g.pose * syms[0];  // the board turned 180 deg about its normal: the same lines
  const std::vector<camera::StampedPose> est = {e};
  EXPECT_EQ(evaluate_trajectory(est, truth).wrong_confident, 1u);
  TrajectoryEvalOptions o;
  o.symmetries = syms;
  const TrajectoryEval r = evaluate_trajectory(est, truth, o);
  EXPECT_EQ(r.wrong_confident, 0u);
  EXPECT_LT(r.ate_mm->max, 1e-6);
  EXPECT_EQ(r.samples[0].symmetry_index, 1u);
}

}  // namespace
}  // namespace evpipe::metrics
