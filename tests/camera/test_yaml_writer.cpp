// YAML writers: to_yaml(camera / line model / prior) → parse_* gives back the same value, and the text is stable.

#include "camera_test_util.hpp"
#include "evpipe/camera/trajectory.hpp"
#include "evpipe/camera/yaml_writer.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

namespace evpipe::camera {
namespace {

using ::testing::HasSubstr;

TEST(YamlWriter, CameraRoundTripIsExact) {
  const CameraModel shipped = load_camera(test::config_file("davis346.yaml"));
  const std::string text = to_yaml(shipped);
  EXPECT_EQ(text,
            "camera:\n  width: 346\n  height: 260\n  fx: 243.2\n  fy: 243.2\n  cx: 173.4\n  cy: 128.6\n"
            "  distortion: [-0.08, 0.01, 0.0002, -0.0001, 0]\n");
  EXPECT_EQ(parse_camera(text, "out.yaml"), shipped);

  auto rng = test::test_rng();
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 200; ++i) {
    CameraModel c;
    c.width = 64 + static_cast<int>(rng() % 1985);  // up to kMaxSensorSide (2048)
    c.height = 64 + static_cast<int>(rng() % 1985);
    c.fx = 100.0 + 900.0 * std::abs(u(rng));
    c.fy = c.fx * (1.0 + 0.01 * u(rng));
    c.cx = c.width * (0.5 + 0.1 * u(rng));
    c.cy = c.height * (0.5 + 0.1 * u(rng));
    c.k1 = 0.4 * u(rng);
    c.k2 = 0.2 * u(rng);
    c.p1 = 1e-3 * u(rng);
    c.p2 = 1e-7 * u(rng);  // tiny: exponent notation in the text
    c.k3 = 0.05 * u(rng);
    const std::string t = to_yaml(c);
    const CameraModel back = parse_camera(t, "out.yaml");
    ASSERT_EQ(back, c) << t;
    ASSERT_EQ(to_yaml(back), t);
  }
}

TEST(YamlWriter, ShippedModelsRoundTripBitForBitInMillimetres) {
  for (const char* name : {"target-planar.yaml", "roadheader-wireframe.yaml", "roadheader-wireframe.dxf"}) {
    SCOPED_TRACE(name);
    const LineModel m = load_line_model(test::config_file(name));
    const std::string text = to_yaml(m, "mm");
    const LineModel back = parse_line_model(text, "out.yaml");
    EXPECT_EQ(back.name, m.name);
    ASSERT_EQ(back.segments_m.size(), m.segments_m.size());
    for (std::size_t i = 0; i < m.segments_m.size(); ++i) EXPECT_EQ(back.segments_m[i], m.segments_m[i]) << i;
    EXPECT_EQ(to_yaml(back, "mm"), text);
  }
  // The millimetre values are the ones of the source file, not 196.49999999999997.
  const std::string rh = to_yaml(load_line_model(test::config_file("roadheader-wireframe.yaml")), "mm");
  EXPECT_THAT(rh, HasSubstr("    - [0, -196.5, 0, 600, -196.5, 0]\n"));
  EXPECT_THAT(rh, HasSubstr("  name: \"roadheader-wireframe\"\n  units: mm\n"));
}

TEST(YamlWriter, RandomModelsMetresExactMillimetresWithinAnUlp) {
  auto rng = test::test_rng();
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  LineModel m;
  m.name = "odd \"name\": with\\ escapes\tand: colons # not a comment";
  for (int i = 0; i < 300; ++i) {
    m.segments_m.push_back({Eigen::Vector3d(u(rng), u(rng), u(rng)), Eigen::Vector3d(u(rng), u(rng), 1e-7 * u(rng))});
  }
  const LineModel in_m = parse_line_model(to_yaml(m, "m"), "out.yaml");
  EXPECT_EQ(in_m.name, m.name);
  ASSERT_EQ(in_m.segments_m.size(), m.segments_m.size());
  for (std::size_t i = 0; i < m.segments_m.size(); ++i) ASSERT_EQ(in_m.segments_m[i], m.segments_m[i]) << i;

  const LineModel in_mm = parse_line_model(to_yaml(m, "mm"), "out.yaml");
  EXPECT_EQ(in_mm.name, m.name);
  ASSERT_EQ(in_mm.segments_m.size(), m.segments_m.size());
  std::size_t exact = 0;
  for (std::size_t i = 0; i < m.segments_m.size(); ++i) {
    for (const auto& [a, b] : {std::pair{in_mm.segments_m[i].a_m, m.segments_m[i].a_m},
                               std::pair{in_mm.segments_m[i].b_m, m.segments_m[i].b_m}}) {
      for (int k = 0; k < 3; ++k) {
        ASSERT_LE(std::abs(a[k] - b[k]), 2.5e-16 * std::abs(b[k])) << i;
        exact += a[k] == b[k];
      }
    }
  }
  // Most random doubles have an exact millimetre representation too.
  EXPECT_GT(exact, m.segments_m.size() * 6 * 9 / 10);
}

TEST(YamlWriter, ModelErrors) {
  LineModel m{"m", {{Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX()}}};
  EXPECT_THROW((void)to_yaml(m, "cm"), std::invalid_argument);
  m.segments_m[0].b_m.x() = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW((void)to_yaml(m, "mm"), std::invalid_argument);
  CameraModel c;
  c.fx = std::numeric_limits<double>::infinity();
  EXPECT_THROW((void)to_yaml(c), std::invalid_argument);
}

TEST(YamlWriter, PriorRoundTrip) {
  const PosePrior shipped = load_prior(test::config_file("prior-example.yaml"));
  const std::string text = to_yaml(shipped);
  EXPECT_EQ(text,
            "prior:\n  position: [0, 0, 0.8]\n  orientation: [1, 0, 0, 0]\n  position_tolerance: 0.3\n"
            "  angle_tolerance_deg: 45\n");

  auto rng = test::test_rng();
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < 500; ++i) {
    PosePrior p;
    p.pose.t_cam_model_m = Eigen::Vector3d(u(rng), u(rng), 1.0 + u(rng));
    p.pose.q_cam_model = Eigen::Quaterniond(u(rng), u(rng), u(rng), u(rng)).normalized();
    p.position_tolerance_m = 0.5 + u(rng) * 0.4;
    p.angle_tolerance_deg = 90.0 + u(rng) * 80.0;
    const std::string t = to_yaml(p);
    const PosePrior back = parse_prior(t, "out.yaml");
    ASSERT_EQ(back.pose.t_cam_model_m, p.pose.t_cam_model_m);
    ASSERT_EQ(back.position_tolerance_m, p.position_tolerance_m);
    ASSERT_EQ(back.angle_tolerance_deg, p.angle_tolerance_deg);
    // q and -q are the same rotation; the file holds the one with qw >= 0.
    const double dq = std::min((back.pose.q_cam_model.coeffs() - p.pose.q_cam_model.coeffs()).norm(),
                               (back.pose.q_cam_model.coeffs() + p.pose.q_cam_model.coeffs()).norm());
    ASSERT_LT(dq, 1e-15) << t;
    ASSERT_GE(back.pose.q_cam_model.w(), 0.0);
    // A loaded prior is written back to the same text, and loads to the bit-identical value.
    ASSERT_EQ(to_yaml(back), t);
    ASSERT_EQ(parse_prior(to_yaml(back), "again.yaml").pose.q_cam_model.coeffs(), back.pose.q_cam_model.coeffs());
  }
}

// Not YAML, but the same promise for the trajectory CSV evsim writes its ground truth to: a trajectory read back
// and written again gives the same bytes (the writer picks the quaternion's last digit for it).
TEST(TrajectoryCsvWriter, WriteReadWriteIsByteIdentical) {
  auto rng = test::test_rng();
  std::normal_distribution<double> n(0.0, 1.0);
  const auto dir = ::evpipe::testing::temp_dir("camera");
  const std::string first = (dir / "first.csv").string();
  const std::string second = (dir / "second.csv").string();
  {
    TrajectoryCsvWriter w(first);
    for (int i = 0; i < 5000; ++i) {
      StampedPose sp;
      sp.t_us = i * 1000;
      sp.pose.t_cam_model_m = Eigen::Vector3d(n(rng), n(rng), 1.0 + n(rng));
      sp.pose.q_cam_model = Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized();
      w.write(sp);
    }
  }
  {
    TrajectoryCsvWriter w(second);
    for (const auto& sp : read_trajectory_csv(first)) w.write(sp);
  }
  auto slurp = [](const std::string& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream ss;
    ss << in.rdbuf();
    return ss.str();
  };
  const std::string a = slurp(first);
  ASSERT_GT(a.size(), 5000U * 50U);
  EXPECT_TRUE(a == slurp(second));
}

}  // namespace
}  // namespace evpipe::camera
