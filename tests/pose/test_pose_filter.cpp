// Fusion of window poses (pose_filter.hpp): on seeded synthetic tracks measured with known Gaussian noise the
// fused poses are closer to the truth than the measurements and their covariance is honest (NEES ~ 6); a manoeuvre
// beyond the limits restarts the filter at the measurement; measurements sharing events count less; a hold stops
// the motion.

#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>

#include "evpipe/pose/pose_filter.hpp"

using namespace evpipe;
using namespace evpipe::pose;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Eigen::Matrix3d exp_so3(const Eigen::Vector3d& w) {
  const double a = w.norm();
  return a < 1e-12 ? Eigen::Matrix3d::Identity() : Eigen::AngleAxisd(a, w / a).toRotationMatrix();
}

Eigen::Matrix<double, 6, 1> error_of(const camera::Pose& est, const camera::Pose& truth) {
  Eigen::Matrix<double, 6, 1> e;
  const Eigen::AngleAxisd aa(est.rotation() * truth.rotation().transpose());
  e.head<3>() = aa.axis() * aa.angle();
  e.tail<3>() = est.t_cam_model_m - truth.t_cam_model_m;
  return e;
}

// The truth at t (s): a model 0.8 m in front of the camera turning at 6 deg/s and moving at 5 cm/s, both
// modulated slowly (accelerations ~10 deg/s^2 and 0.1 m/s^2, inside the default limits).
camera::Pose truth_at(double t) {
  camera::Pose p;
  const Eigen::Vector3d angle(0.1 * std::sin(1.2 * t), 0.08 * std::sin(0.9 * t + 1.0), 0.05 * t);
  p.q_cam_model = Eigen::Quaterniond(exp_so3(angle));
  p.t_cam_model_m = Eigen::Vector3d(0.05 * std::sin(t), -0.03 * t, 0.8 + 0.02 * std::sin(2.0 * t));
  return p;
}

// A measurement of `truth` with the covariance `cov` (errors in the filter's convention).
camera::Pose measure(const camera::Pose& truth, const Covariance6& cov, std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Matrix<double, 6, 1> z;
  for (int i = 0; i < 6; ++i) z(i) = n(rng);
  const Eigen::Matrix<double, 6, 1> e = Eigen::LLT<Covariance6>(cov).matrixL() * z;
  camera::Pose m;
  m.q_cam_model = Eigen::Quaterniond(exp_so3(e.head<3>()) * truth.rotation());
  m.t_cam_model_m = truth.t_cam_model_m + e.tail<3>();
  return m;
}

// A planar target's measurement: the tilt about x weak (1 deg), the rest well measured, correlated with depth.
Covariance6 window_covariance() {
  Covariance6 c = Covariance6::Zero();
  c.diagonal() << std::pow(1.0 * kDeg, 2), std::pow(0.3 * kDeg, 2), std::pow(0.1 * kDeg, 2), std::pow(0.5e-3, 2),
      std::pow(0.5e-3, 2), std::pow(2e-3, 2);
  c(0, 5) = c(5, 0) = 0.5 * std::sqrt(c(0, 0) * c(5, 5));
  return c;
}

}  // namespace

TEST(PoseFilter, FusedPosesBeatTheMeasurementsWithAnHonestCovariance) {
  const Covariance6 cov = window_covariance();
  double meas_rot2 = 0.0, fused_rot2 = 0.0, nees = 0.0;
  int n = 0;
  for (std::uint64_t seed = 1; seed <= 20; ++seed) {
    std::mt19937_64 rng(seed);
    PoseFilter filter;
    for (int k = 0; k < 100; ++k) {
      const std::int64_t t_us = 30'000 * k;
      const camera::Pose truth = truth_at(1e-6 * static_cast<double>(t_us));
      const camera::Pose m = measure(truth, cov, rng);
      const FusedPose f = filter.update(t_us, m, cov, 30'000);
      EXPECT_EQ(f.restarted, k == 0) << "seed " << seed << " window " << k;
      if (k < 10) continue;  // the velocity settles first
      const Eigen::Matrix<double, 6, 1> em = error_of(m, truth), ef = error_of(f.T_cam_model, truth);
      meas_rot2 += em.head<3>().squaredNorm();
      fused_rot2 += ef.head<3>().squaredNorm();
      nees += ef.dot(f.covariance.ldlt().solve(ef));
      ++n;
    }
  }
  const double meas_rms = std::sqrt(meas_rot2 / n) / kDeg, fused_rms = std::sqrt(fused_rot2 / n) / kDeg;
  EXPECT_LT(fused_rms, 0.6 * meas_rms) << "rotation RMS: measured " << meas_rms << " deg, fused " << fused_rms;
  // Honest: the mean NEES of a consistent 6-dof estimate is 6 (its motion model covers the truth's accelerations).
  EXPECT_GT(nees / n, 3.0);
  EXPECT_LT(nees / n, 9.0);
}

TEST(PoseFilter, AManoeuvreBeyondTheLimitsRestartsAtTheMeasurement) {
  const Covariance6 cov = window_covariance();
  std::mt19937_64 rng(7);
  PoseFilter filter;
  camera::Pose truth = truth_at(0.0);
  for (int k = 0; k < 20; ++k) (void)filter.update(30'000 * k, measure(truth, cov, rng), cov, 30'000);
  // 10 deg in one window: 11000 deg/s^2.
  truth.q_cam_model = Eigen::Quaterniond(exp_so3(Eigen::Vector3d(0.0, 10.0 * kDeg, 0.0)) * truth.rotation());
  const camera::Pose m = measure(truth, cov, rng);
  const FusedPose f = filter.update(30'000 * 20, m, cov, 30'000);
  EXPECT_TRUE(f.restarted);
  EXPECT_LT(error_of(f.T_cam_model, m).norm(), 1e-12);
  EXPECT_TRUE(f.covariance.isApprox(cov));
}

TEST(PoseFilter, MeasurementsSharingEventsCountLess) {
  const Covariance6 cov = window_covariance();
  PoseFilter independent, shared;
  std::mt19937_64 rng(3);
  FusedPose a, b;
  for (int k = 0; k < 30; ++k) {
    const camera::Pose m = measure(truth_at(0.03 * k), cov, rng);
    a = independent.update(30'000 * k, m, cov, 30'000);
    b = shared.update(30'000 * k, m, cov, 300'000);  // each window's events span the last 10 windows
  }
  EXPECT_GT(b.covariance(0, 0), 1.5 * a.covariance(0, 0));
}

TEST(PoseFilter, AHoldStopsTheMotion) {
  const Covariance6 cov = window_covariance() * 1e-4;  // precise: the velocity is well known before the hold
  PoseFilter filter;
  std::mt19937_64 rng(5);
  for (int k = 0; k < 30; ++k) (void)filter.update(30'000 * k, measure(truth_at(0.03 * k), cov, rng), cov, 30'000);
  const camera::Pose held = filter.pose();
  filter.hold(29 * 30'000, held, filter.pose_covariance());
  // Measured again 1 s later where it was held: without the hold the velocity (~6 deg/s, 6 cm/s) would predict
  // it 6 deg / 6 cm away and the gate would restart the filter.
  const FusedPose f = filter.update(29 * 30'000 + 1'000'000, held, cov, 30'000);
  EXPECT_FALSE(f.restarted);
  EXPECT_LT(error_of(f.T_cam_model, held).norm(), 1e-4);
}

TEST(PoseFilter, OptionsOutOfRangeAreRefusedByName) {
  PoseFilterOptions o;
  o.max_acceleration_m_s2 = 0.0;
  EXPECT_THROW(
      {
        try {
          o.validate();
        } catch (const std::invalid_argument& e) {
          EXPECT_NE(std::string(e.what()).find("max_acceleration_m_s2"), std::string::npos);
          throw;
        }
      },
      std::invalid_argument);
  o = {};
  o.gate_probability = 1.0;
  EXPECT_THROW(o.validate(), std::invalid_argument);
}
