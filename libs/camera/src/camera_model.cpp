#include "evpipe/camera/camera_model.hpp"

#include <Eigen/LU>

#include <cmath>

namespace evpipe::camera {
namespace {

constexpr double kMinDepth_m = 1e-9;

/// Distorted point and its 2x2 Jacobian with respect to the undistorted normalised point.
struct DistortionEval {
  Eigen::Vector2d xy_d;
  Eigen::Matrix2d J;
};

DistortionEval distort_with_jacobian(const CameraModel& c, const Eigen::Vector2d& xy) {
  const double x = xy.x();
  const double y = xy.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (c.k1 + r2 * (c.k2 + r2 * c.k3));
  const double dradial_dr2 = c.k1 + r2 * (2.0 * c.k2 + 3.0 * r2 * c.k3);
  DistortionEval e;
  e.xy_d.x() = x * radial + 2.0 * c.p1 * x * y + c.p2 * (r2 + 2.0 * x * x);
  e.xy_d.y() = y * radial + c.p1 * (r2 + 2.0 * y * y) + 2.0 * c.p2 * x * y;
  // d(r2)/dx = 2x, d(r2)/dy = 2y.
  e.J(0, 0) = radial + 2.0 * x * x * dradial_dr2 + 2.0 * c.p1 * y + 6.0 * c.p2 * x;
  e.J(0, 1) = 2.0 * x * y * dradial_dr2 + 2.0 * c.p1 * x + 2.0 * c.p2 * y;
  e.J(1, 0) = 2.0 * x * y * dradial_dr2 + 2.0 * c.p1 * x + 2.0 * c.p2 * y;
  e.J(1, 1) = radial + 2.0 * y * y * dradial_dr2 + 6.0 * c.p1 * y + 2.0 * c.p2 * x;
  return e;
}

/// d(r·radial(r))/dr = 1 + 3 k1 r² + 5 k2 r⁴ + 7 k3 r⁶: where it is <= 0 the radial mapping folds back.
double radial_slope(const CameraModel& c, double r2) {
  return 1.0 + r2 * (3.0 * c.k1 + r2 * (5.0 * c.k2 + r2 * 7.0 * c.k3));
}

}  // namespace

Eigen::Vector2d CameraModel::distort(const Eigen::Vector2d& xy) const {
  const double x = xy.x();
  const double y = xy.y();
  const double r2 = x * x + y * y;
  const double radial = 1.0 + r2 * (k1 + r2 * (k2 + r2 * k3));
  return {x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
          y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y};
}

Eigen::Vector2d CameraModel::undistort_normalised(const Eigen::Vector2d& xy_d) const {
  if (!has_distortion()) return xy_d;
  constexpr int kMaxIterations = 20;
  constexpr double kStepTolerance = 1e-12;  // normalised units; ~2.4e-10 px at f = 243 px
  Eigen::Vector2d xy = xy_d;                // the distortion is small: the distorted point is a good start
  DistortionEval e = distort_with_jacobian(*this, xy);
  double residual = (e.xy_d - xy_d).squaredNorm();
  for (int it = 0; it < kMaxIterations; ++it) {
    const double det = e.J.determinant();
    if (!std::isfinite(det) || std::abs(det) < 1e-15) break;  // at the fold: no inverse
    Eigen::Vector2d step = e.J.inverse() * (xy_d - e.xy_d);
    if (!step.allFinite()) break;
    if (step.norm() < kStepTolerance) {  // converged: the residual is at rounding level
      xy += step;
      break;
    }
    // Step halving keeps Newton from overshooting where the distortion is strongly non-linear.
    bool improved = false;
    for (int halvings = 0; halvings < 30 && !improved; ++halvings) {
      const Eigen::Vector2d candidate = xy + step;
      const DistortionEval ec = distort_with_jacobian(*this, candidate);
      const double r = (ec.xy_d - xy_d).squaredNorm();
      if (std::isfinite(r) && r < residual) {
        xy = candidate;
        e = ec;
        residual = r;
        improved = true;
      } else {
        step *= 0.5;
      }
    }
    if (!improved) break;
  }
  return xy;
}

std::optional<Eigen::Vector2d> CameraModel::project(const Eigen::Vector3d& p_cam) const {
  if (!(p_cam.z() > kMinDepth_m)) return std::nullopt;  // also rejects NaN
  const Eigen::Vector2d xy(p_cam.x() / p_cam.z(), p_cam.y() / p_cam.z());
  if (radial_slope(*this, xy.squaredNorm()) <= 0.0) return std::nullopt;
  return normalised_to_pixel(xy);
}

Eigen::Vector2d CameraModel::normalised_to_pixel(const Eigen::Vector2d& xy) const {
  const Eigen::Vector2d xy_d = distort(xy);
  return {fx * xy_d.x() + cx, fy * xy_d.y() + cy};
}

Eigen::Vector2d CameraModel::pixel_to_normalised(const Eigen::Vector2d& px) const {
  return undistort_normalised(Eigen::Vector2d((px.x() - cx) / fx, (px.y() - cy) / fy));
}

Eigen::Vector2d CameraModel::undistort(const Eigen::Vector2d& px) const {
  const Eigen::Vector2d xy = pixel_to_normalised(px);
  return {fx * xy.x() + cx, fy * xy.y() + cy};
}

bool CameraModel::in_image(const Eigen::Vector2d& px) const {
  return px.x() >= -0.5 && px.x() < static_cast<double>(width) - 0.5 && px.y() >= -0.5 &&
         px.y() < static_cast<double>(height) - 0.5;
}

}  // namespace evpipe::camera
