#include "evpipe/camera/pose.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

namespace evpipe::camera {

Eigen::Quaterniond from_wire(double qw, double qx, double qy, double qz) {
  // The one place where the wire order (w first) meets Eigen's constructor (also w first; storage is x y z w).
  Eigen::Quaterniond q(qw, qx, qy, qz);
  const double n = q.norm();
  if (!std::isfinite(n) || n < 1e-12) throw std::invalid_argument("quaternion is zero or not finite");
  q.coeffs() /= n;
  return q;
}

Eigen::Quaterniond from_wire(const WireQuaternion& w) {
  return from_wire(w.qw, w.qx, w.qy, w.qz);
}

WireQuaternion to_wire(const Eigen::Quaterniond& q_in) {
  Eigen::Quaterniond q = q_in.normalized();
  bool flip = q.w() < 0.0;
  if (q.w() == 0.0) {  // q and -q both have qw = 0: pick the one whose first non-zero vector entry is > 0
    for (int i = 0; i < 3; ++i) {
      if (q.vec()[i] != 0.0) {
        flip = q.vec()[i] < 0.0;
        break;
      }
    }
  }
  if (flip) q.coeffs() = -q.coeffs();
  // + 0.0 turns -0.0 into 0.0 so that files do not show "-0.000000000".
  return WireQuaternion{q.w() + 0.0, q.x() + 0.0, q.y() + 0.0, q.z() + 0.0};
}

Pose Pose::from_wire(const Eigen::Vector3d& t_m, double qw, double qx, double qy, double qz) {
  Pose p;
  p.q_cam_model = camera::from_wire(qw, qx, qy, qz);
  p.t_cam_model_m = t_m;
  return p;
}

Eigen::Isometry3d Pose::isometry() const {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotation();
  T.translation() = t_cam_model_m;
  return T;
}

Pose Pose::from_isometry(const Eigen::Isometry3d& T) {
  Pose p;
  p.q_cam_model = Eigen::Quaterniond(T.linear()).normalized();
  p.t_cam_model_m = T.translation();
  return p;
}

Pose Pose::inverse() const {
  // p_model = R^T (p_cam - t)  =>  R' = R^T, t' = -R^T t.
  Pose inv;
  inv.q_cam_model = q_cam_model.conjugate();
  inv.t_cam_model_m = -(inv.q_cam_model * t_cam_model_m);
  return inv;
}

Pose operator*(const Pose& T_a_b, const Pose& T_b_c) {
  // p_a = R_ab (R_bc p_c + t_bc) + t_ab.
  Pose T_a_c;
  T_a_c.q_cam_model = (T_a_b.q_cam_model * T_b_c.q_cam_model).normalized();  // no drift over long chains
  T_a_c.t_cam_model_m = T_a_b.q_cam_model * T_b_c.t_cam_model_m + T_a_b.t_cam_model_m;
  return T_a_c;
}

double rotation_angle_deg(const Pose& a, const Pose& b) {
  const Eigen::Quaterniond d = a.q_cam_model.conjugate() * b.q_cam_model;
  // atan2 form: accurate for small and large angles alike (acos loses precision near 0).
  const double angle_rad = 2.0 * std::atan2(d.vec().norm(), std::abs(d.w()));
  return angle_rad * 180.0 / std::numbers::pi;
}

double translation_distance_m(const Pose& a, const Pose& b) {
  return (a.t_cam_model_m - b.t_cam_model_m).norm();
}

Pose interpolate(const Pose& a, const Pose& b, double s) {
  Pose out;
  out.q_cam_model = a.q_cam_model.slerp(s, b.q_cam_model).normalized();  // Eigen's slerp takes the short arc
  out.t_cam_model_m = (1.0 - s) * a.t_cam_model_m + s * b.t_cam_model_m;
  return out;
}

Pose interpolate(const StampedPose& a, const StampedPose& b, std::int64_t t_us) {
  if (b.t_us <= a.t_us) return a.pose;
  const std::int64_t t_clamped_us = std::clamp(t_us, a.t_us, b.t_us);
  const double s = static_cast<double>(t_clamped_us - a.t_us) / static_cast<double>(b.t_us - a.t_us);
  return interpolate(a.pose, b.pose, s);
}

}  // namespace evpipe::camera
