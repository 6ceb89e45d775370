#pragma once
// Plain types shared by the pose solvers, the tracker and the estimator that runs them per window.

#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/pose.hpp"
#include "evpipe/core/track_status.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <string_view>

namespace evpipe::pose {

/// Tracking status published with every pose: the one definition in libs/core (evpipe/core/track_status.hpp),
/// whose values are the wire values of the LCM pose message.
using TrackStatus = evpipe::TrackStatus;
using evpipe::to_string;

/// 6x6 covariance of a pose, ordered [rotation (rad, small angle about the camera axes, left-multiplied:
/// R = exp([dθ]x) R̂), translation (m, camera frame)].
using Covariance6 = Eigen::Matrix<double, 6, 6>;

/// A 2D line observation for OPnL: a segment's endpoints in normalised undistorted image coordinates
/// (camera::CameraModel::pixel_to_normalised of the measured pixels).
struct LineObservation {
  Eigen::Vector2d a_n{Eigen::Vector2d::Zero()};
  Eigen::Vector2d b_n{Eigen::Vector2d::Zero()};
};

/// One 2D-3D line correspondence: the image segment lies on the projection of the (infinite) model line.
/// Endpoints need not correspond.
struct LineCorrespondence {
  LineObservation image;
  camera::Segment3 model;
  double weight{1.0};  ///< relative weight in the least-squares costs (> 0)
};

}  // namespace evpipe::pose
