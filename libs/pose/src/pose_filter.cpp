#include "evpipe/pose/pose_filter.hpp"

#include <fmt/format.h>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace evpipe::pose {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;

Eigen::Matrix3d exp_so3(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  if (angle < 1e-12) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

Eigen::Vector3d log_so3(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.axis() * aa.angle();
}

// Upper tail of chi-square with 6 degrees of freedom: exp(-x/2) (1 + x/2 + x^2/8).
double chi2_6_tail(double x) {
  const double h = 0.5 * x;
  return std::exp(-h) * (1.0 + h + 0.5 * h * h);
}

// The x at which that tail equals p (bisection; the tail decreases).
double chi2_6_quantile(double p) {
  double lo = 0.0, hi = 1000.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (chi2_6_tail(mid) > p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

void PoseFilterOptions::validate() const {
  const auto positive = [](const char* name, double v) {
    if (!(v > 0.0) || !std::isfinite(v)) {
      throw std::invalid_argument(fmt::format("pose.filter.{}: must be a finite number > 0, got {}", name, v));
    }
  };
  positive("max_acceleration_m_s2", max_acceleration_m_s2);
  positive("max_angular_acceleration_deg_s2", max_angular_acceleration_deg_s2);
  positive("initial_speed_m_s", initial_speed_m_s);
  positive("initial_angular_speed_deg_s", initial_angular_speed_deg_s);
  if (!(gate_probability > 0.0 && gate_probability < 1.0)) {
    throw std::invalid_argument(
        fmt::format("pose.filter.gate_probability: must be in (0, 1), got {}", gate_probability));
  }
}

PoseFilter::PoseFilter(PoseFilterOptions options)
    : options_(options), gate_chi2_(chi2_6_quantile(options.gate_probability)) {
  options_.validate();
}

void PoseFilter::start(std::int64_t t_us, const camera::Pose& measured, const Covariance6& covariance) {
  started_ = true;
  t_us_ = t_us;
  pose_ = measured;
  w_rad_s_.setZero();
  v_m_s_.setZero();
  P_.setZero();
  P_.topLeftCorner<6, 6>() = covariance;
  const double sw = options_.initial_angular_speed_deg_s * kDegToRad;
  const double sv = options_.initial_speed_m_s;
  P_.block<3, 3>(6, 6) = Eigen::Matrix3d::Identity() * sw * sw;
  P_.block<3, 3>(9, 9) = Eigen::Matrix3d::Identity() * sv * sv;
}

void PoseFilter::hold(std::int64_t t_us, const camera::Pose& held, const Covariance6& covariance) {
  // Still: the held pose, no velocity and none uncertain (the standstill test bounded the motion).
  start(t_us, held, covariance);
  P_.block<6, 6>(6, 6).setZero();
}

FusedPose PoseFilter::update(std::int64_t t_us, const camera::Pose& measured, const Covariance6& covariance,
                             std::int64_t span_us) {
  FusedPose out;
  if (!started_ || t_us <= t_us_ || !covariance.allFinite()) {
    start(t_us, measured, covariance);
    out.T_cam_model = measured;
    out.covariance = covariance;
    out.restarted = true;
    return out;
  }
  const double dt = 1e-6 * static_cast<double>(t_us - t_us_);
  // Prediction: constant velocity; white acceleration noise of the limits' size.
  const Eigen::Matrix3d step = exp_so3(w_rad_s_ * dt);
  camera::Pose predicted;
  predicted.q_cam_model = Eigen::Quaterniond(step * pose_.rotation()).normalized();
  predicted.t_cam_model_m = pose_.t_cam_model_m + v_m_s_ * dt;
  Matrix12 F = Matrix12::Identity();
  F.block<3, 3>(0, 0) = step;  // a left rotation error is turned by the step
  F.block<3, 3>(0, 6) = Eigen::Matrix3d::Identity() * dt;
  F.block<3, 3>(3, 9) = Eigen::Matrix3d::Identity() * dt;
  Matrix12 Q = Matrix12::Zero();
  const double qa = options_.max_angular_acceleration_deg_s2 * kDegToRad;
  const double ql = options_.max_acceleration_m_s2;
  const double t4 = dt * dt * dt * dt / 4.0, t3 = dt * dt * dt / 2.0, t2 = dt * dt;
  for (int k = 0; k < 2; ++k) {
    const double q = k == 0 ? qa * qa : ql * ql;
    const int p = 3 * k, v = 6 + 3 * k;
    for (int i = 0; i < 3; ++i) {
      Q(p + i, p + i) = q * t4;
      Q(p + i, v + i) = Q(v + i, p + i) = q * t3;
      Q(v + i, v + i) = q * t2;
    }
  }
  const Matrix12 P_pred = F * P_ * F.transpose() + Q;

  // Measurement of the pose part; consecutive measurements sharing events count span / step times less.
  const double shared = std::max(1.0, 1e-6 * static_cast<double>(span_us) / dt);
  const Covariance6 R = covariance * shared;
  Eigen::Matrix<double, 6, 1> innovation;
  innovation.head<3>() = log_so3(measured.rotation() * predicted.rotation().transpose());
  innovation.tail<3>() = measured.t_cam_model_m - predicted.t_cam_model_m;
  const Covariance6 S = P_pred.topLeftCorner<6, 6>() + R;
  const Eigen::FullPivLU<Covariance6> lu(S);
  if (!lu.isInvertible() || !(innovation.dot(lu.solve(innovation)) <= gate_chi2_)) {
    // A manoeuvre beyond the limits (or a measurement the prediction cannot explain): start again at it.
    start(t_us, measured, covariance);
    out.T_cam_model = measured;
    out.covariance = covariance;
    out.restarted = true;
    return out;
  }
  const Eigen::Matrix<double, 12, 6> K = P_pred.leftCols<6>() * lu.inverse();
  const Eigen::Matrix<double, 12, 1> dx = K * innovation;
  pose_.q_cam_model = Eigen::Quaterniond(exp_so3(dx.head<3>()) * predicted.rotation()).normalized();
  pose_.t_cam_model_m = predicted.t_cam_model_m + dx.segment<3>(3);
  w_rad_s_ += dx.segment<3>(6);
  v_m_s_ += dx.tail<3>();
  // Joseph form: stays symmetric positive definite.
  Matrix12 IKH = Matrix12::Identity();
  IKH.leftCols<6>() -= K;
  P_ = IKH * P_pred * IKH.transpose() + K * R * K.transpose();
  P_ = 0.5 * (P_ + P_.transpose()).eval();
  t_us_ = t_us;
  out.T_cam_model = pose_;
  out.covariance = P_.topLeftCorner<6, 6>();
  return out;
}

}  // namespace evpipe::pose
