// End-to-end over a real LCM (issue 6): the real evpipe binary replays the bundled roadheader sample at
// --speed max and publishes on udpm:// over loopback; the test subscribes, decodes every message with the
// generated types, and checks the poses against the --poses-out CSV and the ground truth.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <map>
#include <thread>

#include "evpipe/camera/trajectory.hpp"
#include "evpipe/transport/lcm_capture.hpp"
#include "evpipe_run.hpp"
#include "evpipe_test_data.hpp"
#include "lcm_net.hpp"

using evpipe::testing::q;

namespace {

const std::string kEvpipe = EVPIPE_EXE;

using evpipe::testing::json_field;

}  // namespace

TEST(EvpipeLcm, EveryPoseArrivesDecodedAndMatchesTheCsvAndTheTruth) {
  // Before any LCM thread exists: a private network namespace with a multicast route on lo.
  const auto net = evpipe::testing::ensure_multicast_route();
  if (!net.ok) GTEST_SKIP() << "no multicast route for udpm:// on loopback: " << net.message;
  const std::string url = "udpm://239.255.76.67:7667?ttl=0";
  evpipe::transport::LcmCapture capture(url);
  ASSERT_TRUE(capture.good()) << net.message;
  capture.subscribe("EVPIPE_POSE|EVPIPE_STATS");

  const auto dir = evpipe::testing::temp_dir("e2e-lcm");
  const std::string stem = (evpipe::testing::source_dir() / "tests/data/roadheader-sample").string();
  const std::string csv = (dir / "poses.csv").string();
  evpipe::testing::Run r;
  std::atomic<bool> done{false};
  std::thread evpipe_thread([&] {
    r = evpipe::testing::run(kEvpipe + " --replay " + q(stem + ".aedat4") + " --speed max --no-progress --json" +
                                 " --camera " + q(stem + ".camera.yaml") + " --model " + q(stem + ".model.yaml") +
                                 " --prior " + q(stem + ".prior.yaml") + " --poses-out " + q(csv) + " --lcm-url " +
                                 q(url),
                             dir);
    done = true;
  });
  while (!done) capture.drain(std::chrono::milliseconds(50));
  evpipe_thread.join();
  capture.drain(std::chrono::milliseconds(300));  // anything still in flight
  ASSERT_EQ(r.status, 0) << r.err;

  const auto poses = capture.poses("EVPIPE_POSE");
  const auto stats = capture.stats("EVPIPE_STATS");
  // Every window's estimate is published (initialising / tracking / lost), none lost on the way.
  ASSERT_EQ(std::to_string(poses.size()), json_field(r.out, "lcm_poses")) << r.out;
  ASSERT_EQ(json_field(r.out, "windows"), std::to_string(poses.size()));
  for (std::size_t i = 0; i < poses.size(); ++i) ASSERT_EQ(poses[i].seq, static_cast<std::int64_t>(i));
  EXPECT_GE(stats.size(), 1u);
  EXPECT_EQ(stats.back().source, "replay");
  EXPECT_EQ(stats.back().stages.size(), 4u);
  EXPECT_EQ(stats.back().queues.size(), 3u);
  EXPECT_GT(stats.back().queues[0].events_budget, 0);  // the source queue's event bound (pipeline.source_queue_events)
  // The filter's figures travel with the statistics: the sample's ~1 Hz/px noise estimate (the default filter,
  // significance, reports it as curvature does).
  std::map<std::string, double> figures(stats.back().denoise_figures.begin(), stats.back().denoise_figures.end());
  ASSERT_TRUE(figures.count("noise_rate_hz") && figures.count("kept_edge_line")) << r.out;
  EXPECT_NEAR(figures["noise_rate_hz"], 1.0, 0.3);

  // The CSV holds exactly the valid poses, with the same times and values.
  const auto rows = evpipe::camera::read_trajectory_csv(csv);
  const auto truth = evpipe::camera::read_trajectory_csv(stem + ".gt.csv");
  std::map<std::int64_t, const evpipe::transport::PoseRecord*> valid;
  for (const auto& p : poses) {
    ASSERT_TRUE(p.T_cam_model.t_cam_model_m.allFinite());
    if (!p.pose_valid) {
      EXPECT_NE(p.status, evpipe::transport::TrackingStatus::holding);  // holding promises a valid pose
      continue;
    }
    // Valid: measured in this window (tracking), or the target still and the last measurement repeated (holding).
    ASSERT_TRUE(p.status == evpipe::transport::TrackingStatus::tracking ||
                p.status == evpipe::transport::TrackingStatus::holding);
    EXPECT_TRUE(p.covariance_known);
    if (p.status == evpipe::transport::TrackingStatus::tracking) {
      EXPECT_GT(p.inliers, 0);
      EXPECT_EQ(p.t_last_update_us, p.t_us);
    } else {
      EXPECT_LT(p.t_last_update_us, p.t_us);
    }
    EXPECT_GT(p.sigma_px, 0.0);
    EXPECT_GE(p.latency_us, 0);
    valid[p.t_us] = &p;
  }
  ASSERT_EQ(rows.size(), valid.size());
  ASSERT_GE(rows.size(), 60u);  // 100 windows of 30 ms
  double sum_sq_mm = 0;
  for (const auto& row : rows) {
    ASSERT_TRUE(valid.count(row.t_us)) << "CSV row at " << row.t_us << " us not published";
    const auto& p = *valid.at(row.t_us);
    EXPECT_LT((p.T_cam_model.t_cam_model_m - row.pose.t_cam_model_m).norm(), 1e-6);  // CSV: 6 decimals
    EXPECT_LT(evpipe::camera::rotation_angle_deg(p.T_cam_model, row.pose), 1e-5);
    const auto gt = evpipe::camera::interpolate(truth, row.t_us);
    ASSERT_TRUE(gt.has_value());
    const double e_mm = 1000.0 * evpipe::camera::translation_distance_m(p.T_cam_model, *gt);
    sum_sq_mm += e_mm * e_mm;
  }
  const double rmse_mm = std::sqrt(sum_sq_mm / static_cast<double>(rows.size()));
  std::cout << poses.size() << " pose messages (" << rows.size() << " valid), " << stats.size()
            << " statistics messages; ATE RMSE of the LCM poses " << rmse_mm << " mm (" << net.message << ")\n";
  EXPECT_LT(rmse_mm, 15.0);
}

// The real binary under a fake systemd: READY=1 once running, WATCHDOG=1 while the stages progress, STATUS=
// lines, and on SIGTERM STOPPING=1, a drained pipeline and exit 0 promptly.
TEST(EvpipeService, NotifiesSystemdAndStopsOnSigterm) {
  const auto dir = evpipe::testing::temp_dir("e2e-notify");
  const std::string sock_path = (dir / "notify.sock").string();
  ::unlink(sock_path.c_str());
  const int sock = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  ASSERT_GE(sock, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", sock_path.c_str());
  ASSERT_EQ(::bind(sock, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0) << std::strerror(errno);
  const timeval tv{0, 100'000};
  ::setsockopt(sock, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);

  const std::string stem = (evpipe::testing::source_dir() / "tests/data/roadheader-sample").string();
  const std::string cmd = "NOTIFY_SOCKET=" + q(sock_path) + " WATCHDOG_USEC=400000 exec " + kEvpipe + " --replay " +
                          q(stem + ".aedat4") + " --speed 1 --no-progress --no-lcm --camera " +
                          q(stem + ".camera.yaml") + " --model " + q(stem + ".model.yaml") + " --prior " +
                          q(stem + ".prior.yaml") + " >" + q((dir / "out.txt").string()) + " 2>" +
                          q((dir / "err.txt").string());
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  std::vector<std::string> messages;
  auto receive_for = [&](std::chrono::milliseconds d) {
    const auto until = std::chrono::steady_clock::now() + d;
    char buf[4096];
    while (std::chrono::steady_clock::now() < until) {
      const auto n = ::recv(sock, buf, sizeof buf, 0);
      if (n > 0) messages.emplace_back(buf, static_cast<std::size_t>(n));
    }
  };
  auto count = [&](const std::string& what) {
    return std::count_if(messages.begin(), messages.end(),
                         [&](const std::string& m) { return m.find(what) != std::string::npos; });
  };
  receive_for(std::chrono::milliseconds(1500));  // READY, then pings every 200 ms while the replay runs
  EXPECT_EQ(count("READY=1"), 1);
#if !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
  // Pings go out only while every stage progresses; under a sanitizer one initialisation step can outlast the
  // 200 ms check period, so the count is only checked in normal builds.
  EXPECT_GE(count("WATCHDOG=1"), 2);
#endif
  EXPECT_GE(count("STATUS="), 1);
  const auto t_term = std::chrono::steady_clock::now();
  ASSERT_EQ(::kill(pid, SIGTERM), 0);
  // Keep reading while it stops, as systemd does: a full notification socket would block its sd_notify().
  int wstatus = 0;
  pid_t done = 0;
  while ((done = ::waitpid(pid, &wstatus, WNOHANG)) == 0) {
    receive_for(std::chrono::milliseconds(20));
    if (std::chrono::steady_clock::now() - t_term > std::chrono::seconds(120)) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &wstatus, 0);
      FAIL() << "evpipe did not stop within 120 s of SIGTERM";
    }
  }
  ASSERT_EQ(done, pid);
  const double stop_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_term).count();
  receive_for(std::chrono::milliseconds(200));
  ::close(sock);
  std::cout << messages.size() << " notifications; SIGTERM to exit " << stop_s << " s\n";
  ASSERT_TRUE(WIFEXITED(wstatus));
  EXPECT_EQ(WEXITSTATUS(wstatus), 0) << evpipe::testing::slurp(dir / "err.txt");
  EXPECT_EQ(count("STOPPING=1"), 1);
  // 1 s in the issue, plus slack for a loaded CI machine (the drain deadline is 0.8 s). A pose step already
  // running is not interrupted: under ASan/TSan an initialisation takes seconds, so only a hang is caught there.
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  EXPECT_LT(stop_s, 60.0);
#else
  EXPECT_LT(stop_s, 2.0);
#endif
  const auto out = evpipe::testing::slurp(dir / "out.txt");
  EXPECT_NE(out.find("evpipe summary (interrupted)"), std::string::npos) << out;
}
