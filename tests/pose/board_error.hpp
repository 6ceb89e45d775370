#pragma once
// The error of a pose of the real evbench checkerboard (../shared/data/real/davis240-evbench-checkerboard: 10 x 7
// squares of 27 mm) against its truth, up to the board's symmetries (180 deg about an axis through its centre):
// the equivalent truth closest to the estimate. Shared by test_verification.cpp and test_prior_alignment.cpp.

#include <Eigen/Geometry>

#include <numbers>

#include "evpipe/camera/pose.hpp"

namespace evpipe::pose_test {

/// Millimetres to the closest equivalent truth; its rotation error in `deg`.
inline double board_error(const camera::Pose& est, const camera::Pose& truth, double& deg) {
  const Eigen::Vector3d c(0.135, 0.0945, 0.0);
  double best_mm = 1e300;
  deg = 1e300;
  for (int axis = -1; axis < 3; ++axis) {
    camera::Pose S;  // model -> model symmetry: identity, or 180 deg about an axis through the centre
    if (axis >= 0) {
      S.q_cam_model = Eigen::Quaterniond(Eigen::AngleAxisd(std::numbers::pi, Eigen::Vector3d::Unit(axis)));
      S.t_cam_model_m = c - S.q_cam_model * c;
    }
    const camera::Pose equivalent = truth * S;
    const double mm = 1000.0 * camera::translation_distance_m(est, equivalent);
    const double d = camera::rotation_angle_deg(est, equivalent);
    if (mm + 10.0 * d < best_mm + 10.0 * deg) {
      best_mm = mm;
      deg = d;
    }
  }
  return best_mm;
}

}  // namespace evpipe::pose_test
