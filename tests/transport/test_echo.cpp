// evpipe-lcm-echo end to end (the real binary): an LCM log written by the publisher, live udpm in a private
// network namespace, and a clear error for an unusable URL. Also tools/lcm-spy.sh --check against the C++ types.
#include "evpipe/pose_t.hpp"
#include "evpipe/queue_stats_t.hpp"
#include "evpipe/stage_stats_t.hpp"
#include "evpipe/stats_t.hpp"
#include "evpipe/transport/codec.hpp"
#include "evpipe/transport/lcm_publisher.hpp"
#include "evpipe_run.hpp"
#include "lcm_log_bytes.hpp"
#include "lcm_net.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

namespace evpipe::transport {
namespace {

namespace fs = std::filesystem;
using evpipe::testing::q;
using evpipe::testing::run;

fs::path temp_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("evpipe_echo_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::vector<std::string> lines(const std::string& s) {
  std::vector<std::string> out;
  std::istringstream in(s);
  for (std::string l; std::getline(in, l);) {
    out.push_back(l);
  }
  return out;
}

PoseRecord pose_at(std::int64_t t_us) {
  PoseRecord r;
  r.t_us = t_us;
  r.status = TrackingStatus::lost;
  r.t_last_update_us = 500;
  r.T_cam_model.t_cam_model_m = {0.5, 0.25, 3.0};
  return r;
}

TEST(LcmEcho, PrintsALogAsJsonLines) {
  const fs::path dir = temp_dir("log");
  const fs::path log = dir / "x.lcmlog";
  {
    LcmPublisher pub("file://" + log.string() + "?mode=w");
    for (int k = 0; k < 4; ++k) {
      ASSERT_TRUE(pub.publish_pose(pose_at(1000 * k)));
    }
    StatsRecord s;
    s.queues = {{"batches", 64, 1, 2, 3, 4, 1000, 300, 700}};
    s.denoise_figures = {{"noise_rate_hz", 0.5}, {"density_threshold_used", 3}};
    ASSERT_TRUE(pub.publish_stats(s));
  }
  const auto r = run(std::string(EVPIPE_LCM_ECHO_EXE) + " --log " + q(log.string()), dir);
  ASSERT_EQ(r.status, 0) << r.err;
  const auto l = lines(r.out);
  ASSERT_EQ(l.size(), 5U) << r.out;
  for (int k = 0; k < 4; ++k) {
    EXPECT_EQ(l[k].rfind("{\"channel\":\"EVPIPE_POSE\",\"type\":\"evpipe.pose_t\"", 0), 0U) << l[k];
    EXPECT_NE(l[k].find("\"seq\":" + std::to_string(k) + ","), std::string::npos) << l[k];
    EXPECT_NE(l[k].find("\"t_us\":" + std::to_string(1000 * k) + ","), std::string::npos) << l[k];
    EXPECT_NE(l[k].find("\"status\":\"lost\""), std::string::npos) << l[k];
    EXPECT_NE(l[k].find("\"t_last_update_us\":500,"), std::string::npos) << l[k];
    EXPECT_NE(l[k].find("\"position_m\":[0.5,0.25,3]"), std::string::npos) << l[k];
  }
  EXPECT_NE(l[4].find("\"type\":\"evpipe.stats_t\""), std::string::npos) << l[4];
  EXPECT_NE(l[4].find("\"poses_published\":4,"), std::string::npos) << l[4];
  EXPECT_NE(l[4].find("\"name\":\"batches\""), std::string::npos) << l[4];
  EXPECT_NE(l[4].find("\"events_budget\":1000,\"events\":300,\"events_max\":700}"), std::string::npos) << l[4];
  EXPECT_NE(l[4].find("\"denoise_figures\":{\"noise_rate_hz\":0.5,\"density_threshold_used\":3}}"), std::string::npos)
      << l[4];

  const auto t = run(std::string(EVPIPE_LCM_ECHO_EXE) + " --text --log " + q(log.string()), dir);
  ASSERT_EQ(t.status, 0) << t.err;
  const auto tl = lines(t.out);
  ASSERT_EQ(tl.size(), 5U) << t.out;
  EXPECT_EQ(tl[1].rfind("EVPIPE_POSE #1 t=0.001000 s lost (invalid) t_m=[0.5000 0.2500 3.0000]", 0), 0U) << tl[1];
  EXPECT_NE(tl[4].find("| batches 1/64 dropped=4 events=300/1000 | noise_rate_hz=0.500 density_threshold_used=3"),
            std::string::npos)
      << tl[4];
  fs::remove_all(dir);
}

TEST(LcmEcho, BadUrlOrMissingLogExitsNonZeroWithOneLineReason) {
  const fs::path dir = temp_dir("bad");
  // An invalid URL is a usage error found at start (issue 17 row 10).
  const auto r = run(std::string(EVPIPE_LCM_ECHO_EXE) + " --url 'udpm://300.1.2.3:7667?ttl=0' --timeout 1", dir);
  EXPECT_EQ(r.status, 2);
  EXPECT_EQ(r.err, "evpipe-lcm-echo: udpm://300.1.2.3:7667?ttl=0: udpm: '300.1.2.3' is not an IPv4 address a.b.c.d\n");
  const auto t = run(std::string(EVPIPE_LCM_ECHO_EXE) + " --url 'udpm://239.255.76.67:7667?ttl=300' --timeout 1", dir);
  EXPECT_EQ(t.status, 2);
  EXPECT_NE(t.err.find("ttl '300' is not an integer 0-255"), std::string::npos) << t.err;
  const auto m = run(std::string(EVPIPE_LCM_ECHO_EXE) + " --log /nonexistent/a.lcmlog", dir);
  EXPECT_EQ(m.status, 1);
  EXPECT_EQ(m.err,
            "evpipe-lcm-echo: /nonexistent/a.lcmlog: cannot open as an LCM log file: cannot open: No such file or "
            "directory\n");
  fs::remove_all(dir);
}

// Issue 17 row 14: a file that is not an LCM log printed nothing and exited 0.
TEST(LcmEcho, AFileThatIsNotAnLcmLogIsAnErrorNamingIt) {
  const fs::path dir = temp_dir("notlog");
  const fs::path text = dir / "notes.txt";
  std::ofstream(text) << "this is not an LCM log\n";
  const auto r = run(std::string(EVPIPE_LCM_ECHO_EXE) + " --log " + text.string(), dir);
  EXPECT_EQ(r.status, 1);
  EXPECT_EQ(r.err, "evpipe-lcm-echo: " + text.string() +
                       ": not an LCM log file (no LCM event sync word 0xEDA1DA01 at byte 0)\n");
  EXPECT_EQ(r.out, "");
  const fs::path fifo = dir / "fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const auto f = run(std::string(EVPIPE_LCM_ECHO_EXE) + " --log " + fifo.string(), dir);
  EXPECT_EQ(f.status, 1);
  EXPECT_NE(f.err.find("is a FIFO, not a regular file"), std::string::npos) << f.err;
  const auto u = run(std::string(EVPIPE_LCM_ECHO_EXE) + " --timeout 1 --url 'file://" + fifo.string() + "'", dir);
  EXPECT_EQ(u.status, 1);
  EXPECT_NE(u.err.find("is a FIFO, not a regular file"), std::string::npos) << u.err;
  fs::remove_all(dir);
}

// Hostile-tester D2-D4: a corrupt or truncated log printed what liblcm could read and exited 0 (or crashed on a
// data length of 0x7fffffff); a stats_t claiming 2^28 queues in 153 bytes took ~15 GB.
TEST(LcmEcho, ACorruptOrTruncatedLogPrintsTheEventsBeforeThenFailsNamingTheOffset) {
  using evpipe::testing::concat;
  using evpipe::testing::lcm_event;
  const fs::path dir = temp_dir("corrupt");
  const auto good = lcm_event("EVPIPE_POSE", encode(pose_at(1000)), 0);
  const auto next = lcm_event("EVPIPE_POSE", encode(pose_at(2000)), 1);
  struct Case {
    const char* name;
    std::vector<std::uint8_t> bytes;
    std::size_t offset;
    std::size_t lines;
    const char* reason;
  };
  const std::vector<Case> cases = {
      {"cut", concat({good, std::vector<std::uint8_t>(next.begin(), next.end() - 1)}), good.size(), 1,
       "truncated or corrupt: channel name and data are 11 + "},
      {"huge_len", lcm_event("EVPIPE_POSE", encode(pose_at(1000)), 0, {}, 0x7fffffffU), 0, 0,
       "truncated or corrupt: channel name and data are 11 + 2147483647 bytes"},
      {"corrupt", concat({good, good, lcm_event("EVPIPE_POSE", {}, 2, {}, 0x80000100U)}), 2 * good.size(), 2,
       "negative data length -2147483392"},
  };
  for (const Case& c : cases) {
    const fs::path log = dir / (std::string(c.name) + ".lcmlog");
    evpipe::testing::write_bytes(log, c.bytes);
    const auto r = run(std::string(EVPIPE_LCM_ECHO_EXE) + " --log " + q(log.string()), dir);
    EXPECT_EQ(r.status, 1) << c.name;
    EXPECT_EQ(lines(r.out).size(), c.lines) << r.out;
    EXPECT_EQ(r.err.rfind(fmt::format("evpipe-lcm-echo: {}: LCM log event at byte {}: ", log.string(), c.offset), 0),
              0U)
        << r.err;
    EXPECT_NE(r.err.find(c.reason), std::string::npos) << r.err;
    EXPECT_EQ(lines(r.err).size(), 1U) << r.err;
  }
  // A stats_t whose queue count cannot fit in its bytes: reported by field, not allocated.
  StatsRecord s;
  s.source = "replay";
  auto stats = encode(s);
  evpipe::testing::set_be32(stats, stats.size() - 8, 0x10000000U);  // num_queues
  const fs::path log = dir / "stats.lcmlog";
  evpipe::testing::write_bytes(log, concat({good, lcm_event("EVPIPE_STATS", stats, 1)}));
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  const std::string limit;  // the sanitizers reserve terabytes of address space
#else
  const std::string limit = "ulimit -v 2000000; ";  // 2 GB: a regression fails here rather than filling the machine
#endif
  const auto r = run(limit + std::string(EVPIPE_LCM_ECHO_EXE) + " --log " + q(log.string()), dir);
  EXPECT_EQ(r.status, 0) << r.err;
  const auto out = lines(r.out);
  ASSERT_EQ(out.size(), 2U) << r.out;
  EXPECT_EQ(
      out[1].rfind(R"({"channel":"EVPIPE_STATS","type":null,"error":"stats_t.num_queues at byte 105 of 113: )", 0), 0U)
      << out[1];
  fs::remove_all(dir);
}

TEST(LcmEcho, LiveOnUdpmLoopback) {
  const auto setup = evpipe::testing::ensure_multicast_route();
  if (!setup.ok) {
    GTEST_SKIP() << "udpm test skipped: " << setup.message;
  }
  const fs::path dir = temp_dir("live");
  const std::string url = "udpm://239.255.76.67:" + std::to_string(20000 + ::getpid() % 20000) + "?ttl=0";
  const fs::path out = dir / "out.txt";
  const pid_t child = fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    const std::string cmd = std::string("exec ") + EVPIPE_LCM_ECHO_EXE + " --url " + q(url) +
                            " --channel EVPIPE_POSE --count 3 --timeout 20 >" + q(out.string());
    ::execl("/bin/sh", "sh", "-c", cmd.c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  // The echo subscribes at some point after it starts: publish until it has printed 3 poses and exited.
  LcmPublisher pub(url);
  ASSERT_EQ(pub.state(), PublisherState::connected) << pub.last_error();
  int status = 0;
  pid_t done = 0;
  for (int k = 0; k < 2000 && done == 0; ++k) {
    pub.publish_pose(pose_at(k));
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
    done = ::waitpid(child, &status, WNOHANG);
  }
  if (done == 0) {
    ::kill(child, SIGKILL);
    ::waitpid(child, &status, 0);
    FAIL() << "evpipe-lcm-echo did not receive 3 poses";
  }
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  const auto l = lines(evpipe::testing::slurp(out));
  ASSERT_EQ(l.size(), 3U);
  std::int64_t prev = -1;
  for (const auto& line : l) {
    const auto at = line.find("\"seq\":");
    ASSERT_NE(at, std::string::npos) << line;
    const std::int64_t seq = std::stoll(line.substr(at + 6));
    EXPECT_EQ(seq, prev < 0 ? seq : prev + 1) << "consecutive poses expected on loopback";
    prev = seq;
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace evpipe::transport

#if EVPIPE_HAVE_LCM_JAR
namespace evpipe::transport {
namespace {

// The Java classes lcm-spy decodes with must be the same types as the C++ ones: equal LCM fingerprints.
TEST(LcmSpy, JavaTypesHaveTheCppFingerprints) {
  const fs::path dir = temp_dir("spy");
  const auto r = run(std::string(EVPIPE_SOURCE_DIR) + "/tools/lcm-spy.sh --check --jar " + q(EVPIPE_LCMTYPES_JAR), dir);
  ASSERT_EQ(r.status, 0) << r.out << r.err;
  const std::pair<const char*, std::int64_t> types[] = {{"evpipe.pose_t", evpipe::pose_t::getHash()},
                                                        {"evpipe.stats_t", evpipe::stats_t::getHash()},
                                                        {"evpipe.stage_stats_t", evpipe::stage_stats_t::getHash()},
                                                        {"evpipe.queue_stats_t", evpipe::queue_stats_t::getHash()}};
  for (const auto& [name, hash] : types) {
    const std::string expect = fmt::format("{} fingerprint 0x{:016x} found by lcm-spy's type database", name,
                                           static_cast<std::uint64_t>(hash));
    EXPECT_NE(r.out.find(expect), std::string::npos) << "expected '" << expect << "' in:\n" << r.out;
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace evpipe::transport
#endif
