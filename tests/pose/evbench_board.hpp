#pragma once
// The real evbench checkerboard (../shared/data/real/davis240-evbench-checkerboard: 10 x 7 squares of 27 mm): its
// line model, and the error of a pose against its truth up to the board's symmetries (180 deg about an axis through
// its centre). Shared by test_verification.cpp and test_prior_alignment.cpp.

#include <Eigen/Geometry>

#include <numbers>

#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/pose.hpp"

namespace evpipe::pose_test {

/// The board's model: border + 9 + 6 grid lines (with_grid), or the border alone.
inline camera::LineModel evbench_board(bool with_grid = true) {
  camera::LineModel m;
  m.name = with_grid ? "board" : "outline";
  const double W = 0.270, H = 0.189, s = 0.027;
  const auto add = [&](double x0, double y0, double x1, double y1) {
    m.segments_m.push_back({Eigen::Vector3d(x0, y0, 0), Eigen::Vector3d(x1, y1, 0)});
  };
  add(0, 0, W, 0);
  add(W, 0, W, H);
  add(W, H, 0, H);
  add(0, H, 0, 0);
  if (with_grid) {
    for (int i = 1; i < 10; ++i) add(i * s, 0, i * s, H);
    for (int j = 1; j < 7; ++j) add(0, j * s, W, j * s);
  }
  return m;
}

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
