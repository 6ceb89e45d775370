#pragma once
// ELOPET-style tracking: project the model with the predicted pose, associate events to projected segments,
// robust MM-estimation (Tukey bisquare: S-scale with c = 1.547, then MM with c = 4.685) of the pose.
// CONTRACT (issue 5 helpers): the names below are used by the estimator; extend, do not rename.

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/core/event.hpp"
#include "evpipe/pose/types.hpp"

#include <cstddef>
#include <string>

namespace evpipe::pose {

struct TrackerOptions {
  // (the implementation adds its parameters here, documented: gates, c constants, iterations, thresholds)
};

struct TrackUpdate {
  camera::Pose T_cam_model;
  Covariance6 covariance{Covariance6::Zero()};
  bool covariance_known{false};
  double sigma_px{0.0};       ///< robust (S) scale of the event-to-line distances, pixels
  std::size_t associated{0};  ///< events associated with a projected segment
  std::size_t inliers{0};     ///< associated events with non-zero final weight
  double inlier_share{0.0};   ///< inliers / events in the window
  int iterations{0};
  bool converged{false};
  bool healthy{false};  ///< enough inliers, lines in >= 2 directions, well conditioned
  std::string reason;   ///< why not healthy
};

/// One tracking update on a window of events from the predicted pose. Never throws on degenerate input
/// (empty window, model out of view): healthy = false with a reason, the predicted pose returned.
[[nodiscard]] TrackUpdate track_window(EventSpan events, const camera::CameraModel& camera,
                                       const camera::LineModel& model, const camera::Pose& T_predicted,
                                       const TrackerOptions& options = {});

}  // namespace evpipe::pose
