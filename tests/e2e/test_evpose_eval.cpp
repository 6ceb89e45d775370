// End-to-end: the real evpose-eval binary on trajectory CSVs written here (a smooth truth and estimates perturbed
// by known errors): the numbers of the table and of --json, the status filter, coverage, the PNG, and the
// one-line errors with their exit codes.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <string>
#include <vector>

#include "evpipe/camera/trajectory.hpp"
#include "evpipe_run.hpp"
#include "evpipe_test_data.hpp"

namespace fs = std::filesystem;
using namespace evpipe;
using evpipe::testing::q;
using Result = evpipe::testing::Run;

namespace {

const std::string kEval = EVPOSE_EVAL_EXE;

fs::path dir() {
  static const fs::path d = evpipe::testing::temp_dir("evpose-eval");
  return d;
}

Result run(const std::string& args) {
  return evpipe::testing::run(kEval + " " + args, dir());
}

constexpr std::int64_t kT0 = 1'000'000;  // the truth starts at 1 s and lasts 2 s, at 1 kHz

/// A smooth truth: the target ~0.8 m in front of the camera, swaying by a few cm and turning slowly.
camera::Pose truth_pose(std::int64_t t_us) {
  const double s = static_cast<double>(t_us - kT0) * 1e-6;
  camera::Pose p;
  p.t_cam_model_m = {0.05 * std::sin(2.0 * s), 0.03 * std::cos(3.0 * s), 0.8 + 0.1 * std::sin(s)};
  p.q_cam_model = Eigen::AngleAxisd(0.2 * std::sin(s), Eigen::Vector3d::UnitY()) *
                  Eigen::AngleAxisd(0.1 * s, Eigen::Vector3d::UnitX());
  return p;
}

/// The known error of estimated pose k: even k (3, -4, 0) mm = 5 mm and 1 degree about x; odd k (0, 0, 12) mm.
camera::Pose estimated_pose(std::int64_t t_us, int k) {
  camera::Pose p = truth_pose(t_us);
  if (k % 2 == 0) {
    p.t_cam_model_m += Eigen::Vector3d(0.003, -0.004, 0.0);
    p.q_cam_model = p.q_cam_model * Eigen::AngleAxisd(std::numbers::pi / 180.0, Eigen::Vector3d::UnitX());
  } else {
    p.t_cam_model_m += Eigen::Vector3d(0.0, 0.0, 0.012);
  }
  return p;
}

std::string truth_csv() {
  const auto path = (dir() / "truth.gt.csv").string();
  camera::TrajectoryCsvWriter w(path);
  for (std::int64_t t = kT0; t <= kT0 + 2'000'000; t += 1000) w.write({t, truth_pose(t)});
  return path;
}

/// Poses every 10 ms from 1.1 s to 2.9 s (181, on truth rows) with the known errors, one pose before and one
/// after the truth. With `lost_rows`, every 20th pose inside is followed by a "lost" pose 500 mm off (not on the
/// 10 ms grid), and the inside poses are "tracking", the outside ones "initialising".
std::string estimate_csv(const std::string& name, bool lost_rows) {
  const auto path = (dir() / name).string();
  camera::TrajectoryCsvWriter w(path, lost_rows ? std::vector<std::string>{"status"} : std::vector<std::string>{});
  const auto row = [&](std::int64_t t, const camera::Pose& p, const std::string& status) {
    const std::vector<std::string> extra = {status};
    w.write({t, p}, lost_rows ? std::span<const std::string>(extra) : std::span<const std::string>());
  };
  row(kT0 - 500'000, truth_pose(kT0), "initialising");
  int k = 0;
  for (std::int64_t t = kT0 + 100'000; t <= kT0 + 1'900'000; t += 10'000, ++k) {
    row(t, estimated_pose(t, k), "tracking");
    if (lost_rows && k % 20 == 5) {
      camera::Pose wild = truth_pose(t + 5000);
      wild.t_cam_model_m.z() += 0.5;
      row(t + 5000, wild, "lost");
    }
  }
  row(kT0 + 2'500'000, truth_pose(kT0), "initialising");
  return path;
}

/// The number after `key` (a literal prefix such as "\"ate_mm\":{\"rmse\":") in `json`; NaN when absent.
double num(const std::string& json, const std::string& key) {
  const auto at = json.find(key);
  if (at == std::string::npos) {
    ADD_FAILURE() << "missing " << key << " in " << json;
    return std::nan("");
  }
  return std::strtod(json.c_str() + at + key.size(), nullptr);
}

bool one_line(const std::string& s) {
  return !s.empty() && s.back() == '\n' && s.find('\n') == s.size() - 1;
}

// 181 poses inside: 91 even (5 mm, 1 deg) and 90 odd (12 mm, 0 deg).
constexpr double kEven = 91.0;
constexpr double kOdd = 90.0;
constexpr double kN = kEven + kOdd;
constexpr double kTolMm = 2e-3;  // positions are written with 1 um resolution
constexpr double kTolDeg = 1e-5;

TEST(EvposeEval, JsonNumbersMatchTheKnownErrors) {
  const std::string truth = truth_csv();
  const std::string est = estimate_csv("est.csv", false);
  const Result r = run(q(est) + " " + q(truth) + " --json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(r.err.empty()) << r.err;
  ASSERT_TRUE(one_line(r.out)) << r.out;
  EXPECT_EQ(r.out.front(), '{');
  EXPECT_EQ(r.out[r.out.size() - 2], '}');
  const std::string& j = r.out;
  EXPECT_EQ(num(j, "\"poses_in\":"), 183);
  EXPECT_EQ(num(j, "\"poses_evaluated\":"), kN);
  EXPECT_EQ(num(j, "\"poses_before_truth\":"), 1);
  EXPECT_EQ(num(j, "\"poses_after_truth\":"), 1);
  EXPECT_NE(j.find("\"poses_tracking\":null"), std::string::npos) << j;
  EXPECT_NEAR(num(j, "\"matched_fraction\":"), kN / 183.0, 1e-12);
  EXPECT_NEAR(num(j, "\"time_coverage\":"), 1.8 / 2.0, 1e-12);
  EXPECT_NEAR(num(j, "\"first_pose_delay_ms\":"), 100.0, 1e-12);

  const double mean = (kEven * 5.0 + kOdd * 12.0) / kN;
  EXPECT_NEAR(num(j, "\"ate_mm\":{\"rmse\":"), std::sqrt((kEven * 25.0 + kOdd * 144.0) / kN), kTolMm);
  EXPECT_NEAR(num(j, "\"mean\":"), mean, kTolMm);   // the first "mean" is the ATE's
  EXPECT_NEAR(num(j, "\"median\":"), 5.0, kTolMm);  // 91 of 181 are 5 mm: the middle one is 5
  EXPECT_NEAR(num(j, "\"std\":"), std::sqrt(kEven * kOdd) / kN * 7.0, kTolMm);
  EXPECT_NEAR(num(j, "\"max\":"), 12.0, kTolMm);
  EXPECT_NEAR(num(j, "\"x\":{\"bias\":"), kEven * 3.0 / kN, kTolMm);
  EXPECT_NEAR(num(j, "\"y\":{\"bias\":"), -kEven * 4.0 / kN, kTolMm);
  EXPECT_NEAR(num(j, "\"z\":{\"bias\":"), kOdd * 12.0 / kN, kTolMm);
  EXPECT_NEAR(num(j, "\"rotation_deg\":{\"rmse\":"), std::sqrt(kEven / kN), kTolDeg);
  const std::string rot = j.substr(j.find("\"rotation_deg\""));
  EXPECT_NEAR(num(rot, "\"mean\":"), kEven / kN, kTolDeg);
  EXPECT_NEAR(num(rot, "\"max\":"), 1.0, kTolDeg);
}

TEST(EvposeEval, TableAndCoverageGap) {
  const std::string truth = truth_csv();
  const std::string est = estimate_csv("est-table.csv", false);
  Result r = run(q(est) + " " + q(truth));
  ASSERT_EQ(r.status, 0) << r.err;
  // RMSE sqrt((91*25 + 90*144)/181) = 9.1745, mean 8.4807, median 5, std 3.5000, max 12.
  const auto row = r.out.find("\nATE (mm)");
  ASSERT_NE(row, std::string::npos) << r.out;
  double v[5] = {};
  ASSERT_EQ(std::sscanf(r.out.c_str() + row + 9, "%lf %lf %lf %lf %lf", &v[0], &v[1], &v[2], &v[3], &v[4]), 5) << r.out;
  const double expected[5] = {9.174, 8.481, 5.000, 3.500, 12.000};
  for (int i = 0; i < 5; ++i) EXPECT_NEAR(v[i], expected[i], 0.0015) << i << "\n" << r.out;  // printed to 3 decimals
  EXPECT_NE(r.out.find("181 evaluated, 1 before and 1 after"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("90.0 % of the truth's time span"), std::string::npos) << r.out;
  // Gaps of 10 ms: none counts with a 5 ms limit.
  r = run(q(est) + " " + q(truth) + " --json --max-gap-us 5000");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(num(r.out, "\"time_coverage\":"), 0.0);
}

TEST(EvposeEval, OnlyTrackingSkipsLostRows) {
  const std::string truth = truth_csv();
  const std::string est = estimate_csv("est-status.csv", true);
  Result r = run(q(est) + " " + q(truth) + " --json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(num(r.out, "\"poses_in\":"), 183 + 9);  // lost rows after k = 5, 25, ..., 165
  EXPECT_NEAR(num(r.out, "\"max\":"), 500.0, kTolMm);
  EXPECT_EQ(num(r.out, "\"poses_tracking\":"), kN);

  r = run(q(est) + " " + q(truth) + " --json --only-tracking");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(num(r.out, "\"poses_not_tracking\":"), 2 + 9);  // the two outside are "initialising"
  EXPECT_EQ(num(r.out, "\"poses_evaluated\":"), kN);
  EXPECT_NEAR(num(r.out, "\"ate_mm\":{\"rmse\":"), std::sqrt((kEven * 25.0 + kOdd * 144.0) / kN), kTolMm);
  EXPECT_NEAR(num(r.out, "\"max\":"), 12.0, kTolMm);
  EXPECT_NEAR(num(r.out, "\"matched_fraction\":"), 1.0, 1e-12);
}

TEST(EvposeEval, PngIsWrittenAndDecodes) {
  const std::string truth = truth_csv();
  const std::string est = estimate_csv("est-png.csv", true);
  const auto png = dir() / "plot.png";
  fs::remove(png);
  const Result r = run(q(est) + " " + q(truth) + " --only-tracking --png " + q(png.string()));
  ASSERT_EQ(r.status, 0) << r.err;
  ASSERT_TRUE(fs::exists(png));
  const cv::Mat img = cv::imread(png.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(img.empty());
  EXPECT_EQ(img.cols, 1400);
  EXPECT_GT(img.rows, 800);
  // Something is drawn in the estimate's red (B, G < 100, R > 180).
  int red = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x) {
      const auto p = img.at<cv::Vec3b>(y, x);
      red += p[2] > 180 && p[1] < 100 && p[0] < 100;
    }
  EXPECT_GT(red, 1000);
}

TEST(EvposeEval, BadInputOneLineErrorsAndExitCodes) {
  const std::string truth = truth_csv();
  const std::string est = estimate_csv("est-err.csv", false);
  const auto expect_error = [](const Result& r, int status, const std::string& text) {
    EXPECT_EQ(r.status, status) << r.err;
    EXPECT_TRUE(r.out.empty()) << r.out;
    EXPECT_NE(r.err.find(text), std::string::npos) << r.err;
    if (status == 1) {
      EXPECT_TRUE(one_line(r.err)) << r.err;
      EXPECT_EQ(r.err.rfind("evpose-eval: ", 0), 0u) << r.err;
    }
  };
  const std::string missing = (dir() / "missing.csv").string();
  expect_error(run(q(missing) + " " + q(truth)), 1, missing + ": cannot open");

  const auto bad = (dir() / "bad.csv").string();
  std::ofstream(bad) << "t_us,x_m,y_m,z_m,qw,qx,qy,qz\n1100000,0,0,1,1,0,0,0\n1110000,0,zero,1,1,0,0,0\n";
  expect_error(run(q(bad) + " " + q(truth)), 1, bad + ": line 3: column y_m");
  expect_error(run(q(est) + " " + q(bad)), 1, bad + ": line 3: column y_m");

  const auto header_only = (dir() / "header.csv").string();
  std::ofstream(header_only) << "t_us,x_m,y_m,z_m,qw,qx,qy,qz\n";
  expect_error(run(q(header_only) + " " + q(truth)), 1, header_only + ": no pose rows");

  const auto late = (dir() / "late.csv").string();
  std::ofstream(late) << "t_us,x_m,y_m,z_m,qw,qx,qy,qz\n9000000,0,0,1,1,0,0,0\n9010000,0,0,1,1,0,0,0\n";
  expect_error(run(q(late) + " " + q(truth)), 1, "no pose within the time range of");

  expect_error(run(q(est) + " " + q(truth) + " --only-tracking"), 1, "no status column");
  expect_error(run(q(est) + " " + q(truth) + " --png " + q((dir() / "no/such/dir/p.png").string())), 1,
               "cannot write the image");

  const Result none = run("");
  EXPECT_EQ(none.status, 2);
  EXPECT_EQ(run(q(est) + " " + q(truth) + " --max-gap-us -5").status, 2);
  EXPECT_EQ(run(q(est) + " " + q(truth) + " --bogus").status, 2);
  EXPECT_EQ(run("--help").status, 0);
}

}  // namespace

namespace {

std::string fmt_double(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

// Issue 21: evpipe's poses CSV with status (holding), t_last_update_us and cov_0..cov_35: NEES, wrong confident
// poses, --errors-out, and a malformed covariance row.
TEST(EvposeEval, NeesWrongConfidentAndErrorsOut) {
  const std::string truth = truth_csv();
  const auto path = (dir() / "est-cov.csv").string();
  std::vector<std::string> cols = {"status", "t_last_update_us"};
  for (int k = 0; k < 36; ++k) cols.push_back("cov_" + std::to_string(k));
  {
    camera::TrajectoryCsvWriter w(path, cols);
    for (int i = 0; i < 12; ++i) {
      const std::int64_t t = kT0 + 100'000 + i * 30'000;
      camera::Pose p = truth_pose(t);
      // Tracking rows 3 mm off in depth with sigma_z 3 mm (NEES 1); row 10 holding 25 mm off (wrong); row 11
      // tracking without a covariance.
      p.t_cam_model_m.z() += i == 10 ? 0.025 : 0.003;
      std::vector<std::string> extra = {i == 10 ? "holding" : "tracking", std::to_string(t)};
      for (int k = 0; k < 36; ++k) {
        const bool diag = k % 7 == 0;
        const double v = k == 35 ? 9e-6 : (diag ? 1e-4 : 0.0);
        extra.push_back(i == 11 ? std::string() : (diag ? fmt_double(v) : "0"));
      }
      w.write({t, p}, extra);
    }
  }
  const std::string errors = (dir() / "errors.csv").string();
  const Result r = run(q(path) + " " + q(truth) + " --json --errors-out " + q(errors));
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string& j = r.out;
  EXPECT_EQ(num(j, "\"poses_holding\":"), 1);
  EXPECT_EQ(num(j, "\"confident_evaluated\":"), 12);
  EXPECT_EQ(num(j, "\"wrong_confident\":"), 1);
  EXPECT_EQ(num(j, "\"nees_count\":"), 10);  // tracking rows with a covariance (the holding row does not count)
  EXPECT_NEAR(num(j, "\"nees_mean\":"), 1.0, 2e-3);
  std::ifstream f(errors);
  std::string header, line;
  std::getline(f, header);
  EXPECT_EQ(header, "t_us,status,confident,wrong,error_mm,rotation_deg,ex_mm,ey_mm,ez_mm,nees,symmetry");
  int rows = 0;
  while (std::getline(f, line)) ++rows;
  EXPECT_EQ(rows, 12);

  // Some cov_ cells of a row empty: an error naming the file.
  std::string text;
  {
    std::ifstream in(path);
    std::stringstream ss;
    ss << in.rdbuf();
    text = ss.str();
  }
  const auto second_row = text.find('\n', text.find('\n') + 1) + 1;
  const auto last_comma = text.find('\n', second_row) - 1;
  const std::string broken = (dir() / "est-cov-broken.csv").string();
  std::ofstream(broken) << text.substr(0, text.rfind(',', last_comma) + 1) << text.substr(last_comma + 1);
  const Result bad = run(q(broken) + " " + q(truth));
  EXPECT_EQ(bad.status, 1);
  EXPECT_NE(bad.err.find("est-cov-broken.csv"), std::string::npos) << bad.err;
}

}  // namespace
