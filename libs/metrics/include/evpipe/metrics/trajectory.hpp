#pragma once
// Accuracy of an estimated trajectory against ground truth (docs/evpose-eval.md).
//
// Both trajectories are T_cam_model in the camera frame, so there is NO alignment (no Umeyama / SE(3) fit): each
// estimated pose is compared with the truth interpolated at its time stamp (camera::interpolate: slerp + linear).
// With E = estimate, G = truth at the same t_us:
//   translation error  e_i   = |t_E - t_G|                 (mm)  -> ATE RMSE, mean, median, std, max
//   per-axis error     e_i,a = t_E,a - t_G,a, a in {x,y,z}  (mm)  -> bias (signed mean) + stats of |e_i,a|
//   rotation error     r_i   = angle(R_G^T R_E)            (deg) -> same statistics
// std is the population standard deviation (divide by n), as evo and the TUM benchmark tools report it, so that
// RMSE^2 = mean^2 + std^2. The median of an even count is the mean of the two middle values.
// Estimated poses outside [truth.front().t_us, truth.back().t_us] have no truth: counted and skipped.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "evpipe/camera/pose.hpp"

namespace evpipe::metrics {

/// Summary of a set of non-negative errors.
struct ErrorStats {
  std::size_t count = 0;
  double rmse = 0.0;
  double mean = 0.0;
  double median = 0.0;
  double std = 0.0;  ///< population standard deviation
  double max = 0.0;
};

/// Statistics of `values` (any sign; the caller passes magnitudes); nullopt when empty.
[[nodiscard]] std::optional<ErrorStats> error_stats(std::span<const double> values);

/// One axis of the translation error.
struct AxisStats {
  double bias = 0.0;  ///< mean signed error t_E - t_G (mm)
  ErrorStats abs;     ///< statistics of |t_E - t_G| on this axis (mm)
};

/// One evaluated pose: the estimate, the truth interpolated at its time and the errors.
struct PoseError {
  std::int64_t t_us = 0;
  Eigen::Vector3d t_est_m = Eigen::Vector3d::Zero();    ///< estimated t_cam_model
  Eigen::Vector3d t_truth_m = Eigen::Vector3d::Zero();  ///< true t_cam_model at t_us
  Eigen::Vector3d error_mm = Eigen::Vector3d::Zero();   ///< t_est - t_truth, per axis, mm
  double rotation_error_deg = 0.0;
};

struct TrajectoryEvalOptions {
  /// Evaluate only estimated poses whose status is "tracking" (needs a status per pose).
  bool only_tracking = false;
  /// Time coverage: two consecutive evaluated poses at most this far apart cover the time between them.
  std::int64_t max_gap_us = 100'000;
};

struct TrajectoryEval {
  // Counts. poses_in = poses_not_tracking + poses_before_truth + poses_after_truth + poses_evaluated.
  std::size_t poses_in = 0;            ///< rows of the estimate
  std::size_t poses_not_tracking = 0;  ///< skipped by only_tracking (0 otherwise)
  std::size_t poses_before_truth = 0;  ///< t_us < truth.front().t_us: skipped
  std::size_t poses_after_truth = 0;   ///< t_us > truth.back().t_us: skipped
  std::size_t poses_evaluated = 0;
  /// Rows whose status is "tracking" when statuses were given (whatever only_tracking says), else nullopt.
  std::optional<std::size_t> poses_tracking;

  /// Share of the considered poses (all, or the tracking ones with only_tracking) that have ground truth:
  /// poses_evaluated / (poses_evaluated + poses_before_truth + poses_after_truth); nullopt when none considered.
  std::optional<double> matched_fraction;
  /// Share of the truth's time span [front, back] covered by evaluated poses: the sum of the gaps between
  /// consecutive evaluated poses that are <= max_gap_us, divided by the span; nullopt for a zero span.
  std::optional<double> time_coverage;
  /// Time from the truth's first stamp to the first evaluated pose (ms); nullopt when none evaluated.
  std::optional<double> first_pose_delay_ms;

  std::optional<ErrorStats> ate_mm;  ///< translation error |t_E - t_G| (nullopt when none evaluated)
  std::optional<AxisStats> axis_mm[3];
  std::optional<ErrorStats> rotation_deg;

  std::vector<PoseError> samples;  ///< one per evaluated pose, in estimate order
};

/// Evaluates `estimate` against `truth`. Both must be sorted by t_us (read_trajectory_csv() guarantees it;
/// std::invalid_argument otherwise). `status` is empty or has one entry per estimated pose (std::invalid_argument
/// otherwise); only_tracking without statuses is std::invalid_argument too. An empty truth evaluates nothing.
[[nodiscard]] TrajectoryEval evaluate_trajectory(std::span<const camera::StampedPose> estimate,
                                                 std::span<const camera::StampedPose> truth,
                                                 const TrajectoryEvalOptions& options = {},
                                                 std::span<const std::string> status = {});

/// The truth at t_us, interpolated between the two rows around it (binary search, then camera::interpolate);
/// nullopt outside [front, back] or for an empty truth. `truth` must be sorted by t_us.
[[nodiscard]] std::optional<camera::Pose> truth_at(std::span<const camera::StampedPose> truth, std::int64_t t_us);

}  // namespace evpipe::metrics
