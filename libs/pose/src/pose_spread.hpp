#pragma once
// Private to libs/pose: the largest rotation and translation among the pose changes an information matrix allows
// (the verification's "do the supported edges fix the pose", the standstill monitor's pose change per pixel).

#include "evpipe/pose/types.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace evpipe::pose::detail {

struct PoseSpread {
  double rotation_deg{std::numeric_limits<double>::infinity()};
  double translation_m{std::numeric_limits<double>::infinity()};
};

/// H: information of a left increment [dθ, dt] (types.hpp's ordering). Over the pose changes δ with δᵀ H δ ≤ 1,
/// the largest rotation angle and translation: √λ_max of each block of H⁻¹. H is inverted with the translations
/// scaled by depth_m (both blocks then angles) for the conditioning; infinite when it is singular.
[[nodiscard]] inline PoseSpread pose_spread(const Covariance6& H, double depth_m) {
  Eigen::Matrix<double, 6, 1> scale;
  scale << 1.0, 1.0, 1.0, depth_m, depth_m, depth_m;
  const Eigen::SelfAdjointEigenSolver<Covariance6> es(scale.asDiagonal() * H * scale.asDiagonal());
  PoseSpread out;
  if (es.info() != Eigen::Success || !(es.eigenvalues()(0) > 1e-12 * std::max(es.eigenvalues()(5), 1e-300))) return out;
  const Covariance6 C =
      scale.asDiagonal() *
      (es.eigenvectors() * es.eigenvalues().cwiseInverse().asDiagonal() * es.eigenvectors().transpose()) *
      scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> er(C.topLeftCorner<3, 3>());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> et(C.bottomRightCorner<3, 3>());
  out.rotation_deg = std::sqrt(std::max(er.eigenvalues()(2), 0.0)) * 180.0 / std::numbers::pi;
  out.translation_m = std::sqrt(std::max(et.eigenvalues()(2), 0.0));
  return out;
}

}  // namespace evpipe::pose::detail
