#include "pose_spread.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace evpipe::pose::detail {

SymmetricEigen6 symmetric_eigen(const Covariance6& A) {
  const Eigen::SelfAdjointEigenSolver<Covariance6> es(A);
  SymmetricEigen6 out;
  out.ok = es.info() == Eigen::Success;
  out.values = es.eigenvalues();
  out.vectors = es.eigenvectors();
  return out;
}

PoseSpread pose_spread(const Covariance6& H, double depth_m) {
  Eigen::Matrix<double, 6, 1> scale;
  scale << 1.0, 1.0, 1.0, depth_m, depth_m, depth_m;
  const SymmetricEigen6 es = symmetric_eigen(scale.asDiagonal() * H * scale.asDiagonal());
  PoseSpread out;
  if (!es.ok || !(es.values(0) > 1e-12 * std::max(es.values(5), 1e-300))) return out;
  const Covariance6 C = scale.asDiagonal() *
                        (es.vectors * es.values.cwiseInverse().asDiagonal() * es.vectors.transpose()) *
                        scale.asDiagonal();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> er(C.topLeftCorner<3, 3>());
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> et(C.bottomRightCorner<3, 3>());
  out.rotation_deg = std::sqrt(std::max(er.eigenvalues()(2), 0.0)) * 180.0 / std::numbers::pi;
  out.translation_m = std::sqrt(std::max(et.eigenvalues()(2), 0.0));
  return out;
}

}  // namespace evpipe::pose::detail
