// Pose prior: the shipped example, a prior inside a run configuration, normalisation, errors.

#include "camera_test_util.hpp"
#include "evpipe/camera/prior.hpp"

#include <gtest/gtest.h>

namespace evpipe::camera {
namespace {

using test::model_error_message;
using ::testing::HasSubstr;

TEST(Prior, ShippedExample) {
  const PosePrior p = load_prior(test::config_file("prior-example.yaml"));
  EXPECT_EQ(p.pose.t_cam_model_m, Eigen::Vector3d(0.0, 0.0, 0.8));
  EXPECT_EQ(p.pose.q_cam_model.coeffs(), Eigen::Quaterniond::Identity().coeffs());
  EXPECT_EQ(p.position_tolerance_m, 0.3);
  EXPECT_EQ(p.angle_tolerance_deg, 45.0);
}

TEST(Prior, SectionOfARunConfigurationAndNormalisation) {
  const std::string text =
      "log:\n  level: info\nsource:\n  replay: rec.aedat4\npose:\n  camera: davis346.yaml\n"
      "prior:\n  position: [0.1, -0.05, 0.9]\n  orientation: [-2.0, 0.0, 0.0, 0.0]\n  angle_tolerance_deg: 30\n";
  const PosePrior p = parse_prior(text, "run.yaml");
  EXPECT_EQ(p.pose.t_cam_model_m, Eigen::Vector3d(0.1, -0.05, 0.9));
  // [-2, 0, 0, 0] → unit norm and qw >= 0.
  EXPECT_EQ(p.pose.q_cam_model.w(), 1.0);
  EXPECT_EQ(p.pose.q_cam_model.vec(), Eigen::Vector3d::Zero());
  EXPECT_EQ(p.position_tolerance_m, 0.3);  // default
  EXPECT_EQ(p.angle_tolerance_deg, 30.0);
  const PosePrior q = parse_prior("prior:\n  position: [0, 0, 1]\n  orientation: [0, 0, 0, 3]\n", "p.yaml");
  EXPECT_EQ(q.pose.q_cam_model.z(), 1.0);
}

TEST(PriorErrors, NameFileAndField) {
  const auto err = [](const std::string& body) {
    return model_error_message([&] { (void)parse_prior("prior:\n" + body, "prior.yaml"); });
  };
  const std::string pos = "  position: [0, 0, 0.8]\n";
  const std::string ori = "  orientation: [1, 0, 0, 0]\n";
  EXPECT_EQ(err(ori), "prior.yaml: prior.position: missing ([x, y, z] in metres, camera frame)");
  EXPECT_EQ(err(pos), "prior.yaml: prior.orientation: missing ([qw, qx, qy, qz])");
  EXPECT_EQ(err("  position: [0, 0.8]\n" + ori), "prior.yaml: prior.position: expected 3 numbers [x, y, z], got 2");
  EXPECT_EQ(err(pos + "  orientation: [1, 0, 0]\n"),
            "prior.yaml: prior.orientation: expected 4 numbers [qw, qx, qy, qz], got 3");
  EXPECT_EQ(err(pos + "  orientation: [0, 0, 0, 0]\n"), "prior.yaml: prior.orientation: quaternion has zero norm");
  EXPECT_EQ(err(pos + ori + "  position_tolerance: 0\n"), "prior.yaml: prior.position_tolerance: must be > 0, got 0");
  EXPECT_EQ(err(pos + ori + "  angle_tolerance_deg: 200\n"),
            "prior.yaml: prior.angle_tolerance_deg: must be in (0, 180], got 200");
  EXPECT_EQ(err(pos + ori + "  position_tolerance: x\n"),
            "prior.yaml: prior.position_tolerance: not a finite number: 'x'");
  EXPECT_THAT(err(pos + ori + "  angle_tolerance: 3\n"), HasSubstr("prior.yaml: prior.angle_tolerance: unknown key"));
  EXPECT_EQ(model_error_message([] { (void)parse_prior("pose:\n  prior: p.yaml\n", "run.yaml"); }),
            "run.yaml: prior: missing");
  EXPECT_EQ(model_error_message([] { (void)parse_prior("prior: p.yaml\n", "run.yaml"); }),
            "run.yaml: prior: must be a map of keys");
  const std::string path = test::write_file("bad-prior.yaml", "prior:\n" + pos);
  EXPECT_THAT(model_error_message([&] { (void)load_prior(path); }), HasSubstr(path + ": prior.orientation: missing"));
}

}  // namespace
}  // namespace evpipe::camera
