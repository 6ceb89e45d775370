#pragma once
// Fusion of a track's window poses over time (docs/algorithms.md, "Fusion over windows"): a constant-velocity
// Kalman filter on SE(3) whose measurements are the tracker's window poses with their covariances. One window
// measures a small planar target's tilt to about a degree (its edges move ~0.3 px per 3 deg); consecutive windows
// measure it independently, and the target cannot turn by that much between them, so the filter averages the
// measurement noise over the windows that the motion model says saw the same pose. The motion model's only
// parameters are the target's physical limits: the largest linear and angular acceleration of the machine (white
// acceleration noise of that standard deviation, the conservative reading of a bound). A measurement the
// prediction cannot explain (Mahalanobis distance of the innovation beyond chi-square(6) at `gate_probability`)
// restarts the filter at it: the fused pose never lags a manoeuvre the limits did not foresee.
//
// State: the pose (R, t) = T_cam_model and its velocity (w, v) in the camera frame, R(t + dt) = Exp(w dt) R,
// t(t + dt) = t + v dt; errors as the tracker's covariance, [rotation (rad, left increment: R = Exp(dtheta) R^),
// translation (m)], then [w (rad/s), v (m/s)].

#include "evpipe/camera/pose.hpp"
#include "evpipe/pose/types.hpp"

#include <Eigen/Core>
#include <cstdint>

namespace evpipe::pose {

struct PoseFilterOptions {
  /// Fuse the window poses (false: every published pose is its window's own measurement).
  bool enabled = true;
  /// The target's largest linear acceleration (m/s^2) and angular acceleration (deg/s^2): the standard deviation
  /// of the motion model's white acceleration noise. A roadheader's boom and body move far below both.
  double max_acceleration_m_s2 = 1.0;
  double max_angular_acceleration_deg_s2 = 90.0;
  /// A measurement further from the prediction than chi-square(6) allows at this probability restarts the filter.
  double gate_probability = 1e-3;
  /// The velocity's standard deviation at a (re)start, before two measurements have shown it.
  double initial_speed_m_s = 1.0;
  double initial_angular_speed_deg_s = 90.0;

  /// Throws std::invalid_argument naming the field when a value is out of range.
  void validate() const;
};

struct FusedPose {
  camera::Pose T_cam_model;
  Covariance6 covariance{Covariance6::Zero()};
  bool restarted{false};  ///< this measurement (re)started the filter: the fused pose is the measurement
};

class PoseFilter {
 public:
  explicit PoseFilter(PoseFilterOptions options = {});

  /// Forget the track (a new one starts with the next measurement).
  void reset() { started_ = false; }
  [[nodiscard]] bool started() const { return started_; }

  /// One window's pose measured at t_us with its covariance (positive definite). `span_us`: the time the
  /// measurement's events span; when it exceeds the time since the previous measurement, consecutive
  /// measurements share events and each counts as span / step independent ones (its covariance is scaled up).
  FusedPose update(std::int64_t t_us, const camera::Pose& measured, const Covariance6& covariance,
                   std::int64_t span_us);

  /// The target stands still at this (held) pose: the velocity is zero from here on.
  void hold(std::int64_t t_us, const camera::Pose& held, const Covariance6& covariance);

  [[nodiscard]] std::int64_t last_t_us() const { return t_us_; }
  [[nodiscard]] const camera::Pose& pose() const { return pose_; }
  [[nodiscard]] Covariance6 pose_covariance() const { return P_.topLeftCorner<6, 6>(); }

 private:
  using Matrix12 = Eigen::Matrix<double, 12, 12>;
  void start(std::int64_t t_us, const camera::Pose& measured, const Covariance6& covariance);

  PoseFilterOptions options_;
  double gate_chi2_{0.0};
  bool started_{false};
  std::int64_t t_us_{0};
  camera::Pose pose_;
  Eigen::Vector3d w_rad_s_{Eigen::Vector3d::Zero()};
  Eigen::Vector3d v_m_s_{Eigen::Vector3d::Zero()};
  Matrix12 P_{Matrix12::Zero()};
};

}  // namespace evpipe::pose
