// Pose: the wire-order quaternion conversion, group identities on random poses (Sophus-style), interpolation.

#include "camera_test_util.hpp"
#include "evpipe/camera/pose.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <stdexcept>

namespace evpipe::camera {
namespace {

using test::test_rng;

Eigen::Quaterniond random_quaternion(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized();  // uniform on SO(3), either sign
}

Pose random_pose(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  Pose p;
  p.q_cam_model = random_quaternion(rng);
  p.t_cam_model_m = Eigen::Vector3d(u(rng), u(rng), u(rng));
  return p;
}

/// Same transform: same translation and same rotation (q and -q are equal).
void expect_pose_near(const Pose& a, const Pose& b, double tol) {
  EXPECT_LT((a.t_cam_model_m - b.t_cam_model_m).norm(), tol);
  EXPECT_LT((a.rotation() - b.rotation()).norm(), tol);
}

Eigen::Quaterniond axis_angle_deg(const Eigen::Vector3d& axis, double deg) {
  return Eigen::Quaterniond(Eigen::AngleAxisd(deg * std::numbers::pi / 180.0, axis.normalized()));
}

TEST(QuaternionWire, OrderIsWFirstAndEigenStoresXyzw) {
  const double n = std::sqrt(0.1 * 0.1 + 0.2 * 0.2 + 0.3 * 0.3 + 0.9 * 0.9);
  const Eigen::Quaterniond q = from_wire(0.9, 0.1, 0.2, 0.3);
  EXPECT_DOUBLE_EQ(q.w(), 0.9 / n);
  EXPECT_DOUBLE_EQ(q.x(), 0.1 / n);
  EXPECT_DOUBLE_EQ(q.y(), 0.2 / n);
  EXPECT_DOUBLE_EQ(q.z(), 0.3 / n);
  // Eigen's storage order is x y z w: the reason this conversion exists.
  EXPECT_DOUBLE_EQ(q.coeffs()[0], 0.1 / n);
  EXPECT_DOUBLE_EQ(q.coeffs()[3], 0.9 / n);
  const WireQuaternion w = to_wire(q);
  EXPECT_DOUBLE_EQ(w.qw, 0.9 / n);
  EXPECT_DOUBLE_EQ(w.qx, 0.1 / n);
  EXPECT_DOUBLE_EQ(w.qy, 0.2 / n);
  EXPECT_DOUBLE_EQ(w.qz, 0.3 / n);
  // A 90 degree rotation about z written on the wire rotates x onto y.
  const Eigen::Quaterniond rz = from_wire(std::sqrt(0.5), 0.0, 0.0, std::sqrt(0.5));
  EXPECT_LT((rz * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 1e-15);
}

TEST(QuaternionWire, NormalisesAndMakesQwNonNegative) {
  const WireQuaternion a = to_wire(from_wire(2.0, 0.0, 0.0, 0.0));
  EXPECT_EQ(a.qw, 1.0);
  EXPECT_EQ(a.qx, 0.0);
  const WireQuaternion b = to_wire(from_wire(-0.5, -0.5, 0.5, -0.5));
  EXPECT_DOUBLE_EQ(b.qw, 0.5);
  EXPECT_DOUBLE_EQ(b.qx, 0.5);
  EXPECT_DOUBLE_EQ(b.qy, -0.5);
  EXPECT_DOUBLE_EQ(b.qz, 0.5);
  // qw == 0: the first non-zero vector component is made positive; no negative zeros.
  const WireQuaternion c = to_wire(Eigen::Quaterniond(0.0, 0.0, -1.0, 0.0));
  EXPECT_EQ(c.qw, 0.0);
  EXPECT_FALSE(std::signbit(c.qw));
  EXPECT_FALSE(std::signbit(c.qx));
  EXPECT_EQ(c.qy, 1.0);
  EXPECT_FALSE(std::signbit(c.qz));
  const WireQuaternion d = to_wire(Eigen::Quaterniond(-1.0, 0.0, 0.0, 0.0));
  EXPECT_EQ(d.qw, 1.0);
  EXPECT_FALSE(std::signbit(d.qx));
  EXPECT_THROW((void)from_wire(0.0, 0.0, 0.0, 0.0), std::invalid_argument);
  EXPECT_THROW((void)from_wire(std::nan(""), 0.0, 0.0, 0.0), std::invalid_argument);
}

TEST(QuaternionWire, RandomRoundTrip) {
  auto rng = test_rng();
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Quaterniond q = random_quaternion(rng);
    const WireQuaternion w = to_wire(q);
    ASSERT_GE(w.qw, 0.0);
    ASSERT_NEAR(std::sqrt(w.qw * w.qw + w.qx * w.qx + w.qy * w.qy + w.qz * w.qz), 1.0, 1e-15);
    const Eigen::Quaterniond back = from_wire(w);
    ASSERT_LT((back.toRotationMatrix() - q.toRotationMatrix()).norm(), 1e-14);  // same rotation
    const WireQuaternion again = to_wire(back);
    ASSERT_NEAR(again.qw, w.qw, 1e-15);
    ASSERT_NEAR(again.qx, w.qx, 1e-15);
    ASSERT_NEAR(again.qy, w.qy, 1e-15);
    ASSERT_NEAR(again.qz, w.qz, 1e-15);
  }
}

TEST(PoseGroup, PropertiesOnRandomPoses) {
  auto rng = test_rng();
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for (int i = 0; i < 500; ++i) {
    SCOPED_TRACE(::testing::Message() << "case " << i << ", EVPIPE_TEST_SEED=" << test::suite_seed());
    const Pose A = random_pose(rng);
    const Pose B = random_pose(rng);
    const Pose C = random_pose(rng);
    const Eigen::Vector3d p(u(rng), u(rng), u(rng));
    expect_pose_near(A * A.inverse(), Pose::identity(), 1e-13);
    expect_pose_near(A.inverse() * A, Pose::identity(), 1e-13);
    expect_pose_near(A * Pose::identity(), A, 1e-14);
    expect_pose_near(Pose::identity() * A, A, 1e-14);
    expect_pose_near((A * B) * C, A * (B * C), 1e-13);
    expect_pose_near((A * B).inverse(), B.inverse() * A.inverse(), 1e-13);
    expect_pose_near(A.inverse().inverse(), A, 1e-14);
    EXPECT_LT(((A * B).apply(p) - A.apply(B.apply(p))).norm(), 1e-13);
    EXPECT_LT((A.inverse().apply(A.apply(p)) - p).norm(), 1e-13);
    // apply() is p_cam = R p_model + t.
    EXPECT_LT((A.apply(p) - (A.rotation() * p + A.t_cam_model_m)).norm(), 1e-14);
    EXPECT_LT((A.isometry() * p - A.apply(p)).norm(), 1e-14);
    expect_pose_near(Pose::from_isometry(A.isometry()), A, 1e-14);
    EXPECT_NEAR((A * B).q_cam_model.norm(), 1.0, 1e-15);
    // The angle between A and A·R(axis, theta) is theta; it is symmetric and 0 for equal poses.
    const double theta_deg = std::uniform_real_distribution<double>(0.0, 179.0)(rng);
    Pose AR = A;
    AR.q_cam_model = A.q_cam_model * axis_angle_deg(Eigen::Vector3d(u(rng), u(rng), u(rng)), theta_deg);
    EXPECT_NEAR(rotation_angle_deg(A, AR), theta_deg, 1e-9);
    EXPECT_NEAR(rotation_angle_deg(AR, A), theta_deg, 1e-9);
    EXPECT_NEAR(rotation_angle_deg(A, A), 0.0, 1e-12);
    // -q is the same rotation.
    Pose A_neg = A;
    A_neg.q_cam_model.coeffs() = -A.q_cam_model.coeffs();
    EXPECT_NEAR(rotation_angle_deg(A, A_neg), 0.0, 1e-6);
  }
}

TEST(PoseGroup, KnownTransform) {
  // Model rotated 90 deg about the camera's y axis, 0.8 m in front: the model's x axis points along -z_cam.
  Pose T = Pose::from_wire(Eigen::Vector3d(0.0, 0.0, 0.8), std::sqrt(0.5), 0.0, std::sqrt(0.5), 0.0);
  const Eigen::Vector3d p_cam = T.apply(Eigen::Vector3d(0.1, 0.0, 0.0));
  EXPECT_NEAR(p_cam.x(), 0.0, 1e-15);
  EXPECT_NEAR(p_cam.z(), 0.7, 1e-15);
  EXPECT_NEAR(T.inverse().t_cam_model_m.x(), 0.8, 1e-15);  // camera origin in model coordinates
  EXPECT_NEAR(rotation_angle_deg(Pose::identity(), T), 90.0, 1e-12);
  EXPECT_NEAR(translation_distance_m(Pose::identity(), T), 0.8, 1e-15);
}

TEST(PoseInterpolation, MidpointsAndEnds) {
  auto rng = test_rng();
  for (int i = 0; i < 200; ++i) {
    const Pose a = random_pose(rng);
    Pose b = a;
    const double total_deg = std::uniform_real_distribution<double>(1.0, 170.0)(rng);
    const Eigen::Vector3d axis(1.0, -2.0, 0.5);
    b.q_cam_model = a.q_cam_model * axis_angle_deg(axis, total_deg);
    b.t_cam_model_m = a.t_cam_model_m + Eigen::Vector3d(0.3, -0.1, 0.2);
    const Pose mid = interpolate(a, b, 0.5);
    EXPECT_NEAR(rotation_angle_deg(a, mid), total_deg / 2.0, 1e-9);
    EXPECT_NEAR(rotation_angle_deg(mid, b), total_deg / 2.0, 1e-9);
    EXPECT_LT((mid.t_cam_model_m - (a.t_cam_model_m + Eigen::Vector3d(0.15, -0.05, 0.1))).norm(), 1e-14);
    // The rotation stays about the same axis (geodesic): a^-1 mid = R(axis, total/2).
    const Eigen::Quaterniond half = a.q_cam_model.conjugate() * mid.q_cam_model;
    EXPECT_NEAR(Eigen::AngleAxisd(half).axis().dot(axis.normalized()) * (half.w() >= 0 ? 1 : -1), 1.0, 1e-9);
    expect_pose_near(interpolate(a, b, 0.0), a, 1e-14);
    expect_pose_near(interpolate(a, b, 1.0), b, 1e-13);
    // Shortest path whatever the sign of the stored quaternions.
    Pose b_neg = b;
    b_neg.q_cam_model.coeffs() = -b.q_cam_model.coeffs();
    expect_pose_near(interpolate(a, b_neg, 0.5), mid, 1e-12);
  }
}

TEST(PoseInterpolation, StampedClampsAndHandlesEqualStamps) {
  Pose a;
  Pose b;
  b.t_cam_model_m = Eigen::Vector3d(1.0, 0.0, 0.0);
  b.q_cam_model = axis_angle_deg(Eigen::Vector3d::UnitZ(), 40.0);
  const StampedPose sa{1000, a};
  const StampedPose sb{3000, b};
  EXPECT_NEAR(interpolate(sa, sb, 1500).t_cam_model_m.x(), 0.25, 1e-15);
  EXPECT_NEAR(rotation_angle_deg(a, interpolate(sa, sb, 1500)), 10.0, 1e-12);
  EXPECT_NEAR(interpolate(sa, sb, 0).t_cam_model_m.x(), 0.0, 0.0);                       // clamped to a
  EXPECT_NEAR(interpolate(sa, sb, 9000).t_cam_model_m.x(), 1.0, 1e-15);                  // clamped to b
  EXPECT_NEAR(interpolate(sa, StampedPose{1000, b}, 1000).t_cam_model_m.x(), 0.0, 0.0);  // equal stamps → a
}

}  // namespace
}  // namespace evpipe::camera
