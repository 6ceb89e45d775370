#pragma once
// Private to libs/pose: the 6x6 symmetric eigen-decomposition of an information matrix, and the largest rotation and
// translation among the pose changes it allows (the verification's "do the supported edges fix the pose", the
// standstill monitor's pose change per pixel). Both live in pose_spread.cpp: Eigen's SelfAdjointEigenSolver for 6x6
// cost ~9 s of compile in each source that instantiated it.

#include "evpipe/pose/types.hpp"

#include <limits>

namespace evpipe::pose::detail {

struct SymmetricEigen6 {
  bool ok{false};                      // the solver converged
  Eigen::Matrix<double, 6, 1> values;  // ascending
  Covariance6 vectors;                 // column k belongs to values(k)
};

/// Eigen::SelfAdjointEigenSolver of A (symmetric; its lower triangle is read).
[[nodiscard]] SymmetricEigen6 symmetric_eigen(const Covariance6& A);

struct PoseSpread {
  double rotation_deg{std::numeric_limits<double>::infinity()};
  double translation_m{std::numeric_limits<double>::infinity()};
};

/// H: information of a left increment [dθ, dt] (types.hpp's ordering). Over the pose changes δ with δᵀ H δ ≤ 1,
/// the largest rotation angle and translation: √λ_max of each block of H⁻¹. H is inverted with the translations
/// scaled by depth_m (both blocks then angles) for the conditioning; infinite when it is singular.
[[nodiscard]] PoseSpread pose_spread(const Covariance6& H, double depth_m);

}  // namespace evpipe::pose::detail
