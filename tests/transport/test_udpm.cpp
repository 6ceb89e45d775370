// LCM over real UDP multicast on loopback, in a private network namespace when root (tests/support/lcm_net.hpp):
// publisher -> subscriber, lcm-logger recording + lcm-logplayer replay, and the boot case "no multicast route yet"
// recovering once the route appears. Skips with the reason when multicast cannot be set up.
#include "evpipe/transport/codec.hpp"
#include "evpipe/transport/lcm_capture.hpp"
#include "evpipe/transport/lcm_publisher.hpp"
#include "lcm_net.hpp"

#include <gtest/gtest.h>

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <thread>
#include <vector>

extern char** environ;

namespace evpipe::transport {
namespace {

namespace fs = std::filesystem;

// A port of our own: in the (fallback) host namespace other test processes must not hear us.
std::string test_url() {
  return "udpm://239.255.76.67:" + std::to_string(20000 + ::getpid() % 20000) + "?ttl=0";
}

#define REQUIRE_MULTICAST()                                       \
  do {                                                            \
    const auto setup = evpipe::testing::ensure_multicast_route(); \
    if (!setup.ok) {                                              \
      GTEST_SKIP() << "udpm test skipped: " << setup.message;     \
    }                                                             \
    std::printf("multicast: %s\n", setup.message.c_str());        \
  } while (0)

PoseRecord pose_at(std::int64_t t_us) {
  PoseRecord r;
  r.t_us = t_us;
  r.status = TrackingStatus::tracking;
  r.pose_valid = true;
  r.T_cam_model.t_cam_model_m = {0.1, -0.2, 2.0};
  r.T_cam_model.q_cam_model = Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY());
  return r;
}

pid_t spawn(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (const auto& a : args) {
    argv.push_back(const_cast<char*>(a.c_str()));
  }
  argv.push_back(nullptr);
  pid_t pid = -1;
  if (posix_spawnp(&pid, argv[0], nullptr, nullptr, argv.data(), environ) != 0) {
    return -1;
  }
  return pid;
}

int wait_exit(pid_t pid) {
  int st = 0;
  if (waitpid(pid, &st, 0) != pid) {
    return -1;
  }
  return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

TEST(LcmUdpm, LoopbackPublisherToSubscriber) {
  REQUIRE_MULTICAST();
  const std::string url = test_url();
  LcmCapture cap(url);
  ASSERT_TRUE(cap.good());
  cap.subscribe("EVPIPE_.*");
  LcmPublisher pub(url);
  ASSERT_EQ(pub.state(), PublisherState::connected) << pub.last_error();
  for (int k = 0; k < 20; ++k) {
    ASSERT_TRUE(pub.publish_pose(pose_at(30000 * k)));
  }
  ASSERT_TRUE(pub.publish_stats(StatsRecord{}));
  EXPECT_EQ(cap.wait_for(21, std::chrono::seconds(5)), 21U);
  const auto poses = cap.poses();
  ASSERT_EQ(poses.size(), 20U);
  for (std::size_t k = 0; k < poses.size(); ++k) {
    EXPECT_EQ(poses[k].seq, static_cast<std::int64_t>(k));
    EXPECT_EQ(poses[k].t_us, 30000 * static_cast<std::int64_t>(k));
    EXPECT_NEAR(camera::rotation_angle_deg(poses[k].T_cam_model, pose_at(0).T_cam_model), 0.0, 1e-9);
  }
  EXPECT_EQ(cap.stats().size(), 1U);
}

TEST(LcmUdpm, DefaultUrlWorksWithTheRoute) {
  // Only in a private namespace: on the host's default group/port a real evpipe or another test may listen.
  const auto setup = evpipe::testing::enter_private_netns(true);
  if (!setup.ok) {
    GTEST_SKIP() << "needs a private network namespace: " << setup.message;
  }
  ::unsetenv("LCM_DEFAULT_URL");
  LcmPublisher pub("");  // LCM's default udpm://239.255.76.67:7667?ttl=0
  EXPECT_EQ(pub.state(), PublisherState::connected) << pub.last_error();
  EXPECT_TRUE(pub.publish_pose(pose_at(0)));
}

TEST(LcmUdpm, NoMulticastRouteAtBootThenRouteAppears) {
  const auto setup = evpipe::testing::enter_private_netns(false);
  if (!setup.ok) {
    GTEST_SKIP() << "needs a private network namespace: " << setup.message;
  }
  LcmPublisherOptions o;
  o.url = test_url();
  o.retry_interval = std::chrono::milliseconds(0);
  LcmPublisher pub(o);
  EXPECT_EQ(pub.state(), PublisherState::degraded);  // "connect: Network is unreachable" inside LCM
  EXPECT_FALSE(pub.publish_pose(pose_at(0)));
  EXPECT_FALSE(pub.publish_pose(pose_at(1)));
  EXPECT_EQ(pub.counters().publish_failures, 2);

  ASSERT_EQ(std::system("ip route add 224.0.0.0/4 dev lo"), 0);  // the network comes up
  LcmCapture cap(o.url);
  ASSERT_TRUE(cap.good());
  cap.subscribe("EVPIPE_POSE");
  EXPECT_TRUE(pub.publish_pose(pose_at(2)));
  EXPECT_EQ(pub.state(), PublisherState::connected);
  ASSERT_EQ(cap.wait_for(1, std::chrono::seconds(5)), 1U);
  const auto p = cap.poses();
  ASSERT_EQ(p.size(), 1U);
  EXPECT_EQ(p[0].seq, 2);  // sequence numbers count attempts: the two lost poses show as a gap
  const PublisherCounters c = pub.counters();
  EXPECT_EQ(c.poses_published, 1);
  EXPECT_EQ(c.publish_failures, 2);
  EXPECT_EQ(c.connect_failures, 3);
}

TEST(LcmUdpm, LcmLoggerRecordsAndLcmLogplayerReplays) {
  REQUIRE_MULTICAST();
  const std::string url = test_url();
  const fs::path dir = fs::temp_directory_path() / ("evpipe_lcmlog_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path log = dir / "session.lcmlog";

  const pid_t logger =
      spawn({"lcm-logger", "--quiet", "--force", "--flush-interval=10", "--lcm-url=" + url, log.string()});
  ASSERT_GT(logger, 0) << "cannot start lcm-logger (package liblcm-bin)";

  // lcm-logger subscribes asynchronously: publish probes until one is on disk, then the measured messages.
  LcmPublisher pub(url, "EVPIPE_POSE", "EVPIPE_STATS");
  ASSERT_EQ(pub.state(), PublisherState::connected) << pub.last_error();
  bool logging = false;
  for (int k = 0; k < 500 && !logging; ++k) {
    PoseRecord probe = pose_at(0);
    probe.model_frame = "probe";
    pub.publish_pose(probe);
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    logging = fs::exists(log) && fs::file_size(log) > 0;
  }
  ASSERT_TRUE(logging) << "lcm-logger recorded nothing in 5 s";
  constexpr int kPoses = 30;
  for (int k = 0; k < kPoses; ++k) {
    PoseRecord r = pose_at(1000 + k);
    r.seq = 1000 + k;
    ASSERT_TRUE(pub.publish_pose(r));
    std::this_thread::sleep_for(std::chrono::milliseconds(2));  // ~500 Hz, well inside what UDP loopback keeps
  }
  ASSERT_TRUE(pub.publish_stats(StatsRecord{}));
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // > flush interval
  ::kill(logger, SIGINT);
  EXPECT_EQ(wait_exit(logger), 0);

  auto measured = [](const std::vector<PoseRecord>& poses) {
    std::vector<std::int64_t> seqs;
    for (const auto& p : poses) {
      if (p.model_frame != "probe") {
        seqs.push_back(p.seq);
      }
    }
    return seqs;
  };
  std::vector<std::int64_t> expected;
  for (int k = 0; k < kPoses; ++k) {
    expected.push_back(1000 + k);
  }
  std::vector<PoseRecord> logged;
  std::size_t logged_stats = 0;
  std::size_t logged_total = 0;
  for (const ReceivedMessage& m : read_lcm_log(log)) {
    ++logged_total;
    if (auto p = decode_pose(m.data.data(), m.data.size())) {
      logged.push_back(*p);
    } else if (decode_stats(m.data.data(), m.data.size())) {
      ++logged_stats;
    }
  }
  EXPECT_EQ(measured(logged), expected);
  EXPECT_EQ(logged_stats, 1U);

  // Replay: every logged message arrives again, in order.
  LcmCapture cap(url);
  ASSERT_TRUE(cap.good());
  cap.subscribe(".*");
  const pid_t player = spawn({"lcm-logplayer", "--speed=4", "--lcm-url=" + url, log.string()});
  ASSERT_GT(player, 0);
  EXPECT_EQ(cap.wait_for(logged_total, std::chrono::seconds(20)), logged_total);
  EXPECT_EQ(wait_exit(player), 0);
  EXPECT_EQ(measured(cap.poses()), expected);
  EXPECT_EQ(cap.stats().size(), 1U);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace evpipe::transport
