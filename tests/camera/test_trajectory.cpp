// Trajectory CSV: write → read round trip, exact row text, columns by name, errors, interpolation.

#include "camera_test_util.hpp"
#include "evpipe/camera/trajectory.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <numbers>
#include <random>
#include <sstream>

namespace evpipe::camera {
namespace {

using test::model_error_message;
using test::write_file;
using ::testing::HasSubstr;

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

TEST(TrajectoryCsv, WriteReadRoundTripToThePrintedPrecision) {
  auto rng = test::test_rng();
  std::uniform_real_distribution<double> pos(-2.0, 2.0);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<StampedPose> poses;
  std::int64_t t_us = 1'700'000'000'000'000;  // large stamps must survive too
  for (int i = 0; i < 300; ++i) {
    StampedPose sp;
    t_us += 1 + static_cast<std::int64_t>(rng() % 40000);
    sp.t_us = t_us;
    sp.pose.t_cam_model_m = Eigen::Vector3d(pos(rng), pos(rng), pos(rng));
    sp.pose.q_cam_model = Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized();  // either sign
    poses.push_back(sp);
  }
  const auto path = (::evpipe::testing::temp_dir("camera") / "traj.csv").string();
  {
    TrajectoryCsvWriter w(path);
    for (const auto& p : poses) w.write(p);
  }
  const std::vector<StampedPose> back = read_trajectory_csv(path);
  ASSERT_EQ(back.size(), poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ(back[i].t_us, poses[i].t_us);
    // 6 decimals: |error| <= 0.5e-6 m; 9 decimals + re-normalisation: <= ~2e-9 per component.
    EXPECT_LE((back[i].pose.t_cam_model_m - poses[i].pose.t_cam_model_m).cwiseAbs().maxCoeff(), 0.5e-6 + 1e-15);
    const WireQuaternion a = to_wire(poses[i].pose.q_cam_model);
    const WireQuaternion b = to_wire(back[i].pose.q_cam_model);
    EXPECT_NEAR(a.qw, b.qw, 2e-9);
    EXPECT_NEAR(a.qx, b.qx, 2e-9);
    EXPECT_NEAR(a.qy, b.qy, 2e-9);
    EXPECT_NEAR(a.qz, b.qz, 2e-9);
    EXPECT_GE(back[i].pose.q_cam_model.w(), 0.0);
  }
  // Writing what was read gives the same text, except that re-normalising a printed quaternion can move its
  // 9th decimal by one.
  const auto path2 = (::evpipe::testing::temp_dir("camera") / "traj2.csv").string();
  {
    TrajectoryCsvWriter w(path2);
    for (const auto& p : back) w.write(p);
  }
  std::istringstream text1(slurp(path));
  std::istringstream text2(slurp(path2));
  std::string a;
  std::string b;
  int rows = 0;
  while (std::getline(text1, a) && std::getline(text2, b)) {
    ++rows;
    if (rows == 1) {
      EXPECT_EQ(a, "t_us,x_m,y_m,z_m,qw,qx,qy,qz");
      EXPECT_EQ(b, a);
      continue;
    }
    std::vector<std::string> ca;
    std::vector<std::string> cb;
    std::istringstream sa(a);
    std::istringstream sb(b);
    for (std::string c; std::getline(sa, c, ',');) ca.push_back(c);
    for (std::string c; std::getline(sb, c, ',');) cb.push_back(c);
    ASSERT_EQ(ca.size(), 8u);
    ASSERT_EQ(cb.size(), 8u);
    for (std::size_t k = 0; k < 4; ++k) EXPECT_EQ(ca[k], cb[k]) << "row " << rows;  // t_us and positions
    for (std::size_t k = 4; k < 8; ++k) EXPECT_NEAR(std::stod(ca[k]), std::stod(cb[k]), 1.5e-9) << "row " << rows;
  }
  EXPECT_EQ(rows, 301);
}

TEST(TrajectoryCsv, ExactTextAndExtraColumns) {
  const auto path = (::evpipe::testing::temp_dir("camera") / "poses.csv").string();
  {
    TrajectoryCsvWriter w(path, {"status", "inliers"});
    StampedPose sp;
    sp.t_us = 1000;
    sp.pose = Pose::from_wire({0.1, -0.2, 0.8}, -1.0, 0.0, 0.0, 0.0);  // qw < 0 is written as qw > 0
    const std::vector<std::string> extra = {"tracking", "412"};
    w.write(sp, extra);
    sp.t_us = 2000;
    sp.pose.t_cam_model_m = Eigen::Vector3d(0.1234567, 0.0, 1.0);
    sp.pose.q_cam_model = Eigen::Quaterniond(Eigen::AngleAxisd(std::numbers::pi / 2, Eigen::Vector3d::UnitZ()));
    w.write(sp, extra);
    EXPECT_THROW(w.write(sp), std::invalid_argument);  // 0 extra values for 2 extra columns
  }
  EXPECT_EQ(slurp(path),
            "t_us,x_m,y_m,z_m,qw,qx,qy,qz,status,inliers\n"
            "1000,0.100000,-0.200000,0.800000,1.000000000,0.000000000,0.000000000,0.000000000,tracking,412\n"
            "2000,0.123457,0.000000,1.000000,0.707106781,0.000000000,0.000000000,0.707106781,tracking,412\n");
  const auto back = read_trajectory_csv(path);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_EQ(back[1].pose.t_cam_model_m.x(), 0.123457);
}

TEST(TrajectoryCsv, ColumnsByNameInAnyOrder) {
  const std::string path = write_file("reordered.csv",
                                      "# ground truth from motion capture\r\n"
                                      "frame, qx, qy, qz, qw, t_us, x_m, y_m, z_m\r\n"
                                      "1, 0, 0, 0, 1, 5, 0.1, 0.2, 0.3\r\n"
                                      "\r\n"
                                      "2, 0, 0, 0, -1, 7, 0.4, 0.5, 0.6\r\n");
  const auto t = read_trajectory_csv(path);
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t[0].t_us, 5);
  EXPECT_EQ(t[1].t_us, 7);
  EXPECT_EQ(t[1].pose.t_cam_model_m, Eigen::Vector3d(0.4, 0.5, 0.6));
  EXPECT_EQ(t[1].pose.q_cam_model.w(), 1.0);
}

TEST(TrajectoryCsvErrors, NameFileLineAndColumn) {
  const std::string header = "t_us,x_m,y_m,z_m,qw,qx,qy,qz\n";
  const auto err = [](const std::string& name, const std::string& text) {
    const std::string path = write_file(name, text);
    std::string msg = model_error_message([&] { (void)read_trajectory_csv(path); });
    // Report relative to the file name so the expectations stay readable.
    if (msg.rfind(path, 0) == 0) msg = name + msg.substr(path.size());
    return msg;
  };
  EXPECT_EQ(err("no-qw.csv", "t_us,x_m,y_m,z_m,qx,qy,qz\n0,0,0,0,0,0,0\n"), "no-qw.csv: line 1: missing column qw");
  EXPECT_EQ(err("text.csv", header + "0,0,0,1,1,0,0,0\n10,abc,0,1,1,0,0,0\n"),
            "text.csv: line 3: column x_m: not a finite number: 'abc'");
  EXPECT_EQ(err("frac.csv", header + "0.5,0,0,1,1,0,0,0\n"),
            "frac.csv: line 2: column t_us: not an integer number of microseconds: '0.5'");
  EXPECT_EQ(err("order.csv", header + "20,0,0,1,1,0,0,0\n10,0,0,1,1,0,0,0\n"),
            "order.csv: line 3: column t_us: 10 is before the previous row's 20 (rows must be in time order)");
  EXPECT_EQ(err("short.csv", header + "20,0,0,1,1,0,0\n"), "short.csv: line 2: 7 cells, but the header has 8 columns");
  EXPECT_EQ(err("zeroq.csv", header + "20,0,0,1,0,0,0,0\n"),
            "zeroq.csv: line 2: columns qw,qx,qy,qz: quaternion has zero norm");
  EXPECT_EQ(err("nan.csv", header + "20,0,nan,1,1,0,0,0\n"), "nan.csv: line 2: column y_m: not a finite number: 'nan'");
  EXPECT_EQ(err("dup.csv", "t_us,x_m,y_m,z_m,qw,qx,qy,qz,qw\n"), "dup.csv: line 1: column qw appears more than once");
  EXPECT_EQ(err("empty.csv", ""), "empty.csv: empty file: no header line t_us,x_m,y_m,z_m,qw,qx,qy,qz");
  EXPECT_THAT(model_error_message([] { (void)read_trajectory_csv("/nonexistent/t.csv"); }),
              HasSubstr("/nonexistent/t.csv: cannot open"));
}

TEST(TrajectoryInterpolation, MidpointsEndsAndOutside) {
  std::vector<StampedPose> traj;
  for (int i = 0; i < 5; ++i) {
    StampedPose sp;
    sp.t_us = 1000 + 1000 * i;
    sp.pose.t_cam_model_m = Eigen::Vector3d(0.1 * i, 0.0, 0.8);
    sp.pose.q_cam_model = Eigen::Quaterniond(Eigen::AngleAxisd(0.2 * i, Eigen::Vector3d::UnitY()));
    traj.push_back(sp);
  }
  for (int i = 0; i < 4; ++i) {
    const auto mid = interpolate(traj, 1500 + 1000 * i);
    ASSERT_TRUE(mid.has_value());
    EXPECT_NEAR(mid->t_cam_model_m.x(), 0.1 * i + 0.05, 1e-15);
    EXPECT_NEAR(rotation_angle_deg(traj[static_cast<std::size_t>(i)].pose, *mid), 0.1 * 180.0 / std::numbers::pi, 1e-9);
    const auto exact = interpolate(traj, traj[static_cast<std::size_t>(i)].t_us);
    ASSERT_TRUE(exact.has_value());
    EXPECT_EQ(exact->t_cam_model_m, traj[static_cast<std::size_t>(i)].pose.t_cam_model_m);
  }
  const auto quarter = interpolate(traj, 2250);
  ASSERT_TRUE(quarter.has_value());
  EXPECT_NEAR(quarter->t_cam_model_m.x(), 0.125, 1e-15);
  ASSERT_TRUE(interpolate(traj, 5000).has_value());
  EXPECT_EQ(interpolate(traj, 5000)->t_cam_model_m.x(), 0.4);
  EXPECT_FALSE(interpolate(traj, 999).has_value());
  EXPECT_FALSE(interpolate(traj, 5001).has_value());
  EXPECT_FALSE(interpolate(std::vector<StampedPose>{}, 0).has_value());
}

TEST(TrajectoryCsv, ExtraColumnByNameOneCellPerPoseRow) {
  const std::string path = write_file("status.csv",
                                      "# evpipe poses\n"
                                      "t_us,x_m,y_m,z_m,qw,qx,qy,qz,status,inliers\n"
                                      "10,0,0,1,1,0,0,0,initialising,0\n"
                                      "\n"
                                      "# a comment between rows\n"
                                      "20,0,0,1,1,0,0,0, tracking ,412\r\n"
                                      "30,0,0,1,1,0,0,0,lost,3\n");
  const auto status = read_trajectory_column(path, "status");
  ASSERT_TRUE(status);
  EXPECT_EQ(*status, (std::vector<std::string>{"initialising", "tracking", "lost"}));
  EXPECT_EQ(status->size(), read_trajectory_csv(path).size());
  EXPECT_EQ(read_trajectory_column(path, "inliers")->at(1), "412");
  EXPECT_FALSE(read_trajectory_column(path, "sigma_px"));
  const std::string bad = write_file("status-short.csv", "t_us,x_m,y_m,z_m,qw,qx,qy,qz,status\n10,0,0,1,1,0,0,0\n");
  EXPECT_EQ(model_error_message([&] { (void)read_trajectory_column(bad, "status"); }),
            bad + ": line 2: 8 cells, but the header has 9 columns");
  EXPECT_THAT(model_error_message([] { (void)read_trajectory_column("/nonexistent/t.csv", "status"); }),
              HasSubstr("/nonexistent/t.csv: cannot open"));
}

}  // namespace
}  // namespace evpipe::camera
