#pragma once
// Initial pose without given correspondences: detected lines + model + (optional) prior -> hypotheses ->
// RANSAC over minimal sets with OPnL -> the pose that explains the most events.
// CONTRACT (issue 5 helpers): the names below are used by the estimator; extend, do not rename.

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/prior.hpp"
#include "evpipe/core/event.hpp"

#include <cstddef>
#include <optional>
#include <string>

namespace evpipe::pose {

struct InitialiserOptions {
  // (the implementation adds its parameters here, documented; a seed for RANSAC)
};

struct InitResult {
  bool ok{false};
  std::string message;  ///< why not ok ("3 lines detected, need 4", "no hypothesis within the prior", ...)
  camera::Pose T_cam_model;
  std::size_t lines_detected{0};
  std::size_t correspondences{0};  ///< inlier 2D-3D matches of the chosen pose
  double support_share{0.0};       ///< share of the window's events explained by the chosen pose
};

[[nodiscard]] InitResult initialise_pose(EventSpan events, const camera::CameraModel& camera,
                                         const camera::LineModel& model, const std::optional<camera::PosePrior>& prior,
                                         const InitialiserOptions& options = {});

}  // namespace evpipe::pose
