#pragma once
// Geometric line cost of a pose and its Levenberg-Marquardt refinement (Ceres) on line reprojection distances.
//
// For a correspondence the measured image line is l̂ = ([a_n;1] × [b_n;1]) / ‖(.)[0:2]‖, so that l̂ᵀ[x;y;1] is
// the signed distance (normalised image units) of an image point (x, y) to the measured line. Each of the two
// model endpoints P gives the residual r = sqrt(w) · l̂ᵀ π(R P + t), π([X;Y;Z]) = [X/Z; Y/Z; 1]. The model
// segment is treated as an infinite line; the image endpoints need not correspond to the model endpoints.
// Used by OPnL (selection, refinement, fallback) and by the initialiser (verification, refinement).

#include "evpipe/camera/pose.hpp"
#include "evpipe/pose/types.hpp"

#include <Eigen/Core>

#include <span>
#include <string>

namespace evpipe::pose {

/// The measured image line of an observation, scaled so that its first two entries have unit norm (l̂ above).
/// A zero-length observation gives a zero vector.
[[nodiscard]] Eigen::Vector3d image_line_n(const LineObservation& obs);

/// Σ_i w_i Σ_{P ∈ {a_m, b_m}} (l̂_iᵀ π(R P + t))², normalised image units squared. +infinity when an endpoint
/// is on the camera plane (|Z| < 1e-12 m) or a value is not finite. Endpoints behind the camera are NOT rejected
/// here (π is defined there): check with all_in_front().
[[nodiscard]] double line_cost(std::span<const LineCorrespondence> lines, const camera::Pose& T_cam_model);

/// RMS endpoint-to-line distance, normalised units: sqrt(line_cost / (2 Σ w)) (the plain RMS for unit weights).
[[nodiscard]] double line_rms(std::span<const LineCorrespondence> lines, const camera::Pose& T_cam_model);

/// True when every model endpoint is at depth Z > min_depth_m in the camera frame (cheirality).
[[nodiscard]] bool all_in_front(std::span<const LineCorrespondence> lines, const camera::Pose& T_cam_model,
                                double min_depth_m = 0.0);

struct RefineOptions {
  enum class Loss { none, huber, cauchy };
  Loss loss{Loss::none};
  double loss_scale_n{2e-3};  ///< robust loss scale, normalised image units (e.g. 2 px / f)
  int max_iterations{30};
  double function_tolerance{1e-14};  ///< Ceres relative cost change for convergence
  double gradient_tolerance{1e-16};
  double parameter_tolerance{1e-14};
};

struct RefineResult {
  bool ok{false};            ///< false: bad input, non-finite start, or the solver failed (message says why)
  std::string message;       ///< empty when ok
  camera::Pose T_cam_model;  ///< refined pose (the start pose when !ok)
  double initial_cost{0.0};  ///< line_cost at the start (non-robust)
  double final_cost{0.0};    ///< line_cost at the result (non-robust, whatever the loss)
  double rms_n{0.0};         ///< line_rms at the result
  int iterations{0};         ///< LM iterations performed
  bool cheiral{false};       ///< all model endpoints in front of the camera at the result
};

/// 6-DoF Levenberg-Marquardt (Ceres, dense QR) on the residuals above, rotation as a unit quaternion on
/// ceres::EigenQuaternionManifold and translation on ceres::EuclideanManifold<3>. Steps that put an endpoint
/// at Z <= 1e-9 m are rejected. Never throws; needs at least 1 line (6 DoF need >= 3 lines to be determined:
/// fewer are refined but the result is ambiguous).
[[nodiscard]] RefineResult refine_pose_lines(std::span<const LineCorrespondence> lines, const camera::Pose& T_init,
                                             const RefineOptions& options = {});

}  // namespace evpipe::pose
