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
//
// Trustworthiness (issue 21): a pose whose status is "tracking" or "holding" is a CONFIDENT pose (the controller
// may act on it); a confident pose more than wrong_max_mm or wrong_max_deg off is a "wrong confident pose". The
// normalised estimation error squared of a pose with a covariance P (6x6, order rx ry rz [rad, small rotation
// about the camera axes, left-multiplied: R = exp([d]x) R_hat] tx ty tz [m]) is NEES = e^T P^-1 e with
// e = (log(R_G R_E^T), t_G - t_E): 6 on average for an honest P. A symmetric model (a board) is only defined up
// to a set of model-frame transforms S (T_cam_model S sees the same lines): each pose is scored against every
// G S and the best (smallest max(error / wrong_max_mm, rotation / wrong_max_deg)) is kept.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

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
  std::string status;              ///< the row's status ("" without a status column)
  bool confident = false;          ///< status tracking or holding (or no status column at all: every row published)
  bool wrong = false;              ///< confident and over wrong_max_mm or wrong_max_deg
  std::optional<double> nees;      ///< when the row has a covariance and it is positive definite
  std::size_t symmetry_index = 0;  ///< which equivalent truth was the best (0: the truth itself)
};

/// Is this status a valid (published, confident) pose? "tracking" and "holding".
[[nodiscard]] bool is_confident_status(const std::string& status);

/// The 6-vector e = (log(R_G R_E^T), t_G - t_E) (rad, m) in the covariance's parametrisation.
[[nodiscard]] Eigen::Matrix<double, 6, 1> pose_error_vector(const camera::Pose& estimate, const camera::Pose& truth);

/// NEES e^T P^-1 e; nullopt when P is not symmetric positive definite (or not finite).
[[nodiscard]] std::optional<double> nees(const Eigen::Matrix<double, 6, 1>& e, const Eigen::Matrix<double, 6, 6>& P);

/// Model-frame symmetries of a planar rectangular model (a board as a line model): identity, the 180 deg turn
/// about the normal through the bounding-box centre and the 180 deg turns about the two in-plane axes through it
/// (a wireframe seen from behind looks the same). std::invalid_argument when the model's points do not share one z
/// (only boards drawn in z = const, as evpipe's planar models are).
[[nodiscard]] std::vector<camera::Pose> planar_rect_symmetries(const std::vector<Eigen::Vector3d>& model_points);

struct TrajectoryEvalOptions {
  /// Evaluate only estimated poses whose status is "tracking" (needs a status per pose).
  bool only_tracking = false;
  /// Time coverage: two consecutive evaluated poses at most this far apart cover the time between them.
  std::int64_t max_gap_us = 100'000;
  /// A confident pose further off than either of these is wrong (issue 21: 20 mm, 2 deg).
  double wrong_max_mm = 20.0;
  double wrong_max_deg = 2.0;
  /// Equivalent model-frame transforms S (the identity is always tried first; empty = only it).
  std::vector<camera::Pose> symmetries;
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
  /// Rows whose status is "holding" (nullopt without statuses).
  std::optional<std::size_t> poses_holding;

  /// Confident evaluated poses (status tracking/holding; every evaluated pose when there is no status column),
  /// and how many of them are wrong (over wrong_max_mm or wrong_max_deg); share = wrong / confident.
  std::size_t confident_evaluated = 0;
  std::size_t wrong_confident = 0;
  std::optional<double> wrong_confident_share;
  /// NEES over the evaluated TRACKING poses (holding repeats an old measurement) that have a covariance:
  /// count, mean, median; nees_invalid = rows whose covariance is not positive definite (skipped).
  std::size_t nees_count = 0;
  std::size_t nees_invalid = 0;
  std::optional<double> nees_mean;
  std::optional<double> nees_median;

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
/// otherwise); only_tracking (which keeps the confident rows: tracking and holding) without statuses is
/// std::invalid_argument too. `covariance` is empty or has one entry per pose (nullopt: none for that row). An
/// empty truth evaluates nothing.
[[nodiscard]] TrajectoryEval evaluate_trajectory(
    std::span<const camera::StampedPose> estimate, std::span<const camera::StampedPose> truth,
    const TrajectoryEvalOptions& options = {}, std::span<const std::string> status = {},
    std::span<const std::optional<Eigen::Matrix<double, 6, 6>>> covariance = {});

/// The truth at t_us, interpolated between the two rows around it (binary search, then camera::interpolate);
/// nullopt outside [front, back] or for an empty truth. `truth` must be sorted by t_us.
[[nodiscard]] std::optional<camera::Pose> truth_at(std::span<const camera::StampedPose> truth, std::int64_t t_us);

}  // namespace evpipe::metrics
