#pragma once
// Rigid transforms between the camera and the model (target) frame.
//
// Convention (interfaces.md): T_cam_model maps a point of the model frame into the camera frame,
//   p_cam = R_cam_model * p_model + t_cam_model_m,
// camera frame x right, y down, z forward (OpenCV). Lengths in metres. Quaternions are Hamilton. On every wire
// (YAML, CSV, LCM) they are written qw qx qy qz, unit norm, qw >= 0; Eigen stores them x y z w in memory, so
// every conversion goes through from_wire() / to_wire() below and nowhere else.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>

namespace evpipe::camera {

/// A quaternion in wire order (qw first).
struct WireQuaternion {
  double qw{1.0};
  double qx{0.0};
  double qy{0.0};
  double qz{0.0};
};

/// Wire order → Eigen, normalised to unit norm. Throws std::invalid_argument for a non-finite or (near) zero
/// quaternion (norm < 1e-12): loaders check first and report the file and field.
[[nodiscard]] Eigen::Quaterniond from_wire(double qw, double qx, double qy, double qz);
[[nodiscard]] Eigen::Quaterniond from_wire(const WireQuaternion& w);

/// Eigen → wire order, unit norm, qw >= 0 (q and -q are the same rotation; the sign is fixed so that files
/// compare equal). When qw == 0 the first non-zero of qx, qy, qz is made positive; -0.0 is written as 0.0.
[[nodiscard]] WireQuaternion to_wire(const Eigen::Quaterniond& q);

/// T_a_b with the frame names of its main use: T_cam_model. In a composition T_a_c = T_a_b * T_b_c read
/// "cam" as the left frame (a) and "model" as the right frame (b).
struct Pose {
  Eigen::Quaterniond q_cam_model{Eigen::Quaterniond::Identity()};  ///< R_cam_model, unit norm
  Eigen::Vector3d t_cam_model_m{Eigen::Vector3d::Zero()};          ///< origin of the model in the camera frame

  [[nodiscard]] static Pose identity() { return {}; }
  /// From a translation (m) and a wire-order quaternion (normalised; throws like from_wire()).
  [[nodiscard]] static Pose from_wire(const Eigen::Vector3d& t_m, double qw, double qx, double qy, double qz);

  [[nodiscard]] Eigen::Matrix3d rotation() const { return q_cam_model.toRotationMatrix(); }
  [[nodiscard]] Eigen::Isometry3d isometry() const;
  [[nodiscard]] static Pose from_isometry(const Eigen::Isometry3d& T);

  /// p_cam = R p_model + t.
  [[nodiscard]] Eigen::Vector3d apply(const Eigen::Vector3d& p_model) const {
    return q_cam_model * p_model + t_cam_model_m;
  }
  /// T_model_cam.
  [[nodiscard]] Pose inverse() const;
};

/// Composition T_a_c = T_a_b * T_b_c (apply T_b_c first). The result's quaternion is re-normalised.
[[nodiscard]] Pose operator*(const Pose& T_a_b, const Pose& T_b_c);

/// Angle (degrees, in [0, 180]) of the rotation taking a's orientation to b's: angle of R_a^T R_b.
[[nodiscard]] double rotation_angle_deg(const Pose& a, const Pose& b);
/// Distance between the two translations (m).
[[nodiscard]] double translation_distance_m(const Pose& a, const Pose& b);

/// Slerp (shortest path) of the rotation and linear interpolation of the translation; s = 0 gives a, s = 1 b.
[[nodiscard]] Pose interpolate(const Pose& a, const Pose& b, double s);

/// A pose at a sensor time.
struct StampedPose {
  std::int64_t t_us{0};
  Pose pose;
};

/// Interpolation at t_us between two stamped poses (a.t_us <= b.t_us). t_us outside [a.t_us, b.t_us] is
/// clamped to the nearer end (no extrapolation); equal stamps return a.
[[nodiscard]] Pose interpolate(const StampedPose& a, const StampedPose& b, std::int64_t t_us);

}  // namespace evpipe::camera
