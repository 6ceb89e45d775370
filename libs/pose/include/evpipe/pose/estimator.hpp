#pragma once
// The per-window pose state machine: initialise (OPnL with automatic correspondences) -> track (MM) -> on loss
// re-initialise. One call per window of denoised events; no threads here.

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/prior.hpp"
#include "evpipe/core/event.hpp"
#include "evpipe/pose/initialiser.hpp"
#include "evpipe/pose/tracker.hpp"
#include "evpipe/pose/types.hpp"

#include <cstdint>
#include <optional>

namespace evpipe::pose {

struct EstimatorOptions {
  InitialiserOptions init;
  TrackerOptions track;
};

/// The result of one window.
struct PoseEstimate {
  std::int64_t t_us{0};  ///< sensor time the pose refers to (the window's end)
  camera::Pose T_cam_model;
  bool pose_valid{false};  ///< false while initialising / lost: T_cam_model is the last good pose or the prior
  Covariance6 covariance{Covariance6::Zero()};
  bool covariance_known{false};
  TrackStatus status{TrackStatus::initialising};
  std::size_t window_events{0};
  std::size_t inliers{0};
  double sigma_px{0.0};
};

class PoseEstimator {
 public:
  PoseEstimator(camera::CameraModel camera, camera::LineModel model, std::optional<camera::PosePrior> prior,
                EstimatorOptions options = {});
  /// One window of denoised events ending at t_end_us.
  PoseEstimate process(EventSpan window, std::int64_t t_end_us);
  [[nodiscard]] TrackStatus status() const noexcept { return status_; }

 private:
  camera::CameraModel camera_;
  camera::LineModel model_;
  std::optional<camera::PosePrior> prior_;
  EstimatorOptions options_;
  TrackStatus status_{TrackStatus::initialising};
  std::optional<camera::Pose> last_pose_;
};

}  // namespace evpipe::pose
