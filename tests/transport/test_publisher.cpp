// LcmPublisher on a real LCM without a network: memq:// (shared instance), file:// logs, and the degraded state
// for URLs LCM cannot open.
#include "evpipe/transport/codec.hpp"
#include "evpipe/transport/lcm_capture.hpp"
#include "evpipe/transport/lcm_publisher.hpp"
#include "evpipe/transport/lcm_url.hpp"
#include "lcm_net.hpp"

#include <gtest/gtest.h>
#include <lcm/eventlog.h>
#include <sys/resource.h>
#include <lcm/lcm-cpp.hpp>

#include <csignal>

#include <filesystem>
#include <fstream>
#include <thread>

namespace evpipe::transport {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("evpipe_transport_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

PoseRecord pose_at(std::int64_t t_us) {
  PoseRecord r;
  r.t_us = t_us;
  r.status = TrackingStatus::tracking;
  r.pose_valid = true;
  r.T_cam_model.t_cam_model_m = {0.001 * static_cast<double>(t_us / 1000), 0.0, 2.0};
  r.inliers = static_cast<std::int32_t>(t_us / 100);
  r.latency_us = 500;
  return r;
}

TEST(LcmPublisher, MemqSharedInstanceDeliversPosesAndStats) {
  auto lcm = std::make_shared<lcm::LCM>("memq://");
  ASSERT_TRUE(lcm->good());
  LcmPublisher pub(lcm, "EVPIPE_POSE", "EVPIPE_STATS");
  LcmCapture cap(lcm);
  cap.subscribe("EVPIPE_.*");
  EXPECT_EQ(pub.state(), PublisherState::connected);

  const std::int64_t before_us = wall_clock_utime_us();
  for (int k = 0; k < 5; ++k) {
    EXPECT_TRUE(pub.publish_pose(pose_at(30000 * (k + 1))));
  }
  StatsRecord s;
  s.stages = {{"source", 10, 10, 0, 1, 5, 1.0, 2.0, 3.0}};
  EXPECT_TRUE(pub.publish_stats(s));
  EXPECT_TRUE(pub.publish_stats(s));
  EXPECT_EQ(cap.wait_for(7, std::chrono::seconds(5)), 7U);

  const auto poses = cap.poses("EVPIPE_POSE");
  ASSERT_EQ(poses.size(), 5U);
  for (std::size_t k = 0; k < poses.size(); ++k) {
    EXPECT_EQ(poses[k].seq, static_cast<std::int64_t>(k));  // assigned by the publisher
    EXPECT_EQ(poses[k].t_us, 30000 * static_cast<std::int64_t>(k + 1));
    EXPECT_GE(poses[k].utime_us, before_us);  // set at publication
    EXPECT_EQ(poses[k].latency_us, 500);      // no arrival time given: kept as is
    EXPECT_EQ(poses[k].status, TrackingStatus::tracking);
    EXPECT_EQ(poses[k].inliers, pose_at(30000 * static_cast<std::int64_t>(k + 1)).inliers);
  }
  const auto stats = cap.stats("EVPIPE_STATS");
  ASSERT_EQ(stats.size(), 2U);
  EXPECT_EQ(stats[0].seq, 0);
  EXPECT_EQ(stats[1].seq, 1);
  EXPECT_EQ(stats[1].poses_published, 5);  // filled from the publisher's counters
  EXPECT_EQ(stats[1].publish_failures, 0);
  ASSERT_EQ(stats[1].stages.size(), 1U);
  EXPECT_EQ(stats[1].stages[0].name, "source");

  const PublisherCounters c = pub.counters();
  EXPECT_EQ(c.poses_published, 5);
  EXPECT_EQ(c.stats_published, 2);
  EXPECT_EQ(c.publish_failures, 0);
  EXPECT_EQ(c.connect_failures, 0);
  EXPECT_TRUE(pub.last_error().empty());
}

TEST(LcmPublisher, ExplicitSeqAndUtimeAreKeptAndLatencyIsMeasuredAtPublication) {
  auto lcm = std::make_shared<lcm::LCM>("memq://");
  LcmPublisher pub(lcm, "P", "S");
  LcmCapture cap(lcm);
  cap.subscribe("P");
  PoseRecord r = pose_at(1000);
  r.seq = 77;
  r.utime_us = 123;
  r.newest_event_arrival = std::chrono::steady_clock::now() - std::chrono::milliseconds(50);
  ASSERT_TRUE(pub.publish_pose(r));
  ASSERT_EQ(cap.wait_for(1, std::chrono::seconds(5)), 1U);
  const auto p = cap.poses("P");
  ASSERT_EQ(p.size(), 1U);
  EXPECT_EQ(p[0].seq, 77);
  EXPECT_EQ(p[0].utime_us, 123);
  EXPECT_GE(p[0].latency_us, 50'000);  // at least the 50 ms that had already passed
}

TEST(LcmPublisher, ConfigurableChannels) {
  auto lcm = std::make_shared<lcm::LCM>("memq://");
  LcmPublisher pub(lcm, "MACHINE7_POSE", "MACHINE7_STATS");
  LcmCapture cap(lcm);
  cap.subscribe(".*");
  ASSERT_TRUE(pub.publish_pose(pose_at(1)));
  ASSERT_TRUE(pub.publish_stats(StatsRecord{}));
  ASSERT_EQ(cap.wait_for(2, std::chrono::seconds(5)), 2U);
  EXPECT_EQ(cap.messages()[0].channel, "MACHINE7_POSE");
  EXPECT_EQ(cap.messages()[1].channel, "MACHINE7_STATS");
  EXPECT_EQ(cap.poses("MACHINE7_POSE").size(), 1U);
  EXPECT_EQ(cap.stats("MACHINE7_STATS").size(), 1U);
  EXPECT_TRUE(cap.poses("EVPIPE_POSE").empty());
}

TEST(LcmPublisher, DefaultsAreTheContractChannels) {
  LcmPublisherOptions o;
  EXPECT_EQ(o.pose_channel, "EVPIPE_POSE");
  EXPECT_EQ(o.stats_channel, "EVPIPE_STATS");
  EXPECT_TRUE(o.url.empty());  // LCM's default URL
}

TEST(LcmPublisher, FileLogWrittenByThePublisherReadsBack) {
  const fs::path dir = temp_dir("file");
  const fs::path log = dir / "poses.lcmlog";
  {
    LcmPublisher pub("file://" + log.string() + "?mode=w");
    ASSERT_EQ(pub.state(), PublisherState::connected) << pub.last_error();
    for (int k = 0; k < 10; ++k) {
      ASSERT_TRUE(pub.publish_pose(pose_at(30000 * (k + 1))));
      if (k % 4 == 3) {
        ASSERT_TRUE(pub.publish_stats(StatsRecord{}));
      }
    }
  }  // closes the log
  const std::vector<ReceivedMessage> events = read_lcm_log(log);
  ASSERT_EQ(events.size(), 12U);
  std::int64_t pose_seq = 0;
  std::int64_t stats_seq = 0;
  for (const ReceivedMessage& m : events) {
    if (m.channel == "EVPIPE_POSE") {
      const auto p = decode_pose(m.data.data(), m.data.size());
      ASSERT_TRUE(p);
      EXPECT_EQ(p->seq, pose_seq);
      EXPECT_EQ(p->t_us, 30000 * (pose_seq + 1));
      ++pose_seq;
    } else {
      ASSERT_EQ(m.channel, "EVPIPE_STATS");
      const auto s = decode_stats(m.data.data(), m.data.size());
      ASSERT_TRUE(s);
      EXPECT_EQ(s->seq, stats_seq++);
    }
  }
  EXPECT_EQ(pose_seq, 10);
  EXPECT_EQ(stats_seq, 2);

  // The same log through LCM's file:// reader (as fast as possible) into a subscriber.
  LcmCapture replay("file://" + log.string() + "?speed=0");
  ASSERT_TRUE(replay.good());
  replay.subscribe(".*");
  EXPECT_EQ(replay.wait_for(12, std::chrono::seconds(5)), 12U);
  EXPECT_EQ(replay.poses().size(), 10U);
  EXPECT_EQ(replay.stats().size(), 2U);
  fs::remove_all(dir);
}

TEST(LcmPublisher, MissingLogIsAClearError) {
  try {
    (void)read_lcm_log("/nonexistent/evpipe.lcmlog");
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/evpipe.lcmlog"), std::string::npos) << e.what();
  }
}

// Issue 17 row 10: an invalid URL is not retried (it cannot recover) and says why.
TEST(LcmPublisher, InvalidUrlIsDegradedForGoodWithTheReason) {
  for (const std::string url :
       {"udpm://300.1.2.3:7667?ttl=0", "nosuchprovider://x", "udpm://239.255.76.67:7667?ttl=300",
        "udpm://239.255.76.67:7667?ttl=-1", "file:///tmp/x.lcmlog"}) {
    SCOPED_TRACE(url);
    LcmPublisherOptions o;
    o.url = url;
    o.retry_interval = std::chrono::milliseconds(0);
    LcmPublisher pub(o);
    EXPECT_EQ(pub.state(), PublisherState::degraded);
    EXPECT_FALSE(pub.can_recover());
    EXPECT_NE(pub.last_error().find(url), std::string::npos) << pub.last_error();
    EXPECT_FALSE(pub.publish_pose(pose_at(1)));
    EXPECT_EQ(pub.counters().connect_attempts, 0);
    EXPECT_EQ(pub.counters().publish_failures, 1);
  }
}

TEST(LcmPublisher, MemqUrlConnects) {
  LcmPublisher pub("memq://");
  EXPECT_EQ(pub.state(), PublisherState::connected);
  EXPECT_TRUE(pub.can_recover());
  EXPECT_TRUE(pub.publish_pose(pose_at(1)));
}

TEST(LcmUrl, ChecksEveryPart) {
  const auto why = [](const std::string& url, bool publish = true) {
    return check_lcm_url(url, publish).value_or("ok");
  };
  for (const std::string ok :
       {"udpm://239.255.76.67:7667?ttl=0", "udpm://239.255.76.67:7667?ttl=255&recv_buf_size=1000", "udpm://",
        "udpm://239.255.76.67:7667", "memq://", "file:///tmp/a.lcmlog?mode=w", "tcpq://127.0.0.1:7700"})
    EXPECT_EQ(why(ok), "ok") << ok;
  EXPECT_EQ(why("file:///tmp/a.lcmlog?speed=0", false), "ok");
  // A subscriber opening a log with mode=w: LCM would truncate the recording it was meant to read.
  EXPECT_EQ(why("file:///tmp/a.lcmlog?mode=w", false),
            "file:///tmp/a.lcmlog?mode=w: mode=w would truncate the log: reading it needs mode=r (the default)");
  EXPECT_EQ(why("udpm://239.255.76.67:7667?ttl=300"),
            "udpm://239.255.76.67:7667?ttl=300: ttl '300' is not an integer 0-255");
  EXPECT_EQ(why("udpm://239.255.76.67:7667?ttl=-1"),
            "udpm://239.255.76.67:7667?ttl=-1: ttl '-1' is not an integer 0-255");
  EXPECT_EQ(why("udpm://239.255.76.67:7667?tll=1"),
            "udpm://239.255.76.67:7667?tll=1: unknown udpm option 'tll' (known: ttl, recv_buf_size)");
  EXPECT_EQ(why("udpm://10.0.0.1:7667"),
            "udpm://10.0.0.1:7667: udpm: 10.0.0.1 is not a multicast group (224.0.0.0 to 239.255.255.255)");
  EXPECT_EQ(why("udpm://239.255.76.67:70000"),
            "udpm://239.255.76.67:70000: udpm: port '70000' is not an integer 1-65535");
  EXPECT_EQ(why("garbage"),
            "'garbage' is not an LCM URL (provider://target?options, e.g. udpm://239.255.76.67:7667?ttl=0)");
  EXPECT_EQ(why("file:///tmp/a.lcmlog"),
            "file:///tmp/a.lcmlog: publishing to a log file needs mode=w (read mode is the default)");
  EXPECT_EQ(why("file://?mode=w"), "file://?mode=w: file:// needs a path (file:///var/log/evpipe/run.lcmlog?mode=w)");
  EXPECT_EQ(why("memq://x"), "memq://x: memq:// takes no target or options");
  EXPECT_EQ(why("tcpq://host"), "tcpq://host: tcpq:// needs host:port (e.g. tcpq://127.0.0.1:7700)");
}

// Issue 17 row 8: a log on a full disk was reported as written.
TEST(LcmPublisher, FileLogOnAFullDiskCountsEveryFailure) {
  LcmPublisher pub("file:///dev/full?mode=w");
  EXPECT_EQ(pub.state(), PublisherState::connected);
  EXPECT_TRUE(pub.writes_log());
  for (int k = 0; k < 5; ++k) EXPECT_FALSE(pub.publish_pose(pose_at(k)));
  EXPECT_FALSE(pub.publish_stats(StatsRecord{}));
  const PublisherCounters c = pub.counters();
  EXPECT_EQ(c.poses_published, 0);
  EXPECT_EQ(c.publish_failures, 6);
  EXPECT_NE(pub.last_error().find("No space left on device"), std::string::npos) << pub.last_error();
}

// A disk that fills up in the middle of an event (here: a file size limit) must not leave half an event behind: the
// log stays readable to its end, and writing resumes once there is room again.
TEST(LcmPublisher, FileLogKeepsWholeEventsWhenTheDiskFillsMidEvent) {
  const fs::path dir = temp_dir("logfull");
  const std::string path = (dir / "run.lcmlog").string();
  rlimit old{};
  ASSERT_EQ(::getrlimit(RLIMIT_FSIZE, &old), 0);
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);  // a write past the limit fails with EFBIG instead
  int failures = 0;
  {
    LcmPublisher pub("file://" + path + "?mode=w");
    rlimit small = old;
    small.rlim_cur = 2000;  // a few pose events, then a cut inside one
    ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &small), 0);
    for (int k = 0; k < 20; ++k) failures += pub.publish_pose(pose_at(k)) ? 0 : 1;
    ASSERT_EQ(::setrlimit(RLIMIT_FSIZE, &old), 0);
    EXPECT_TRUE(pub.publish_pose(pose_at(100)));  // room again
  }
  std::signal(SIGXFSZ, old_handler);
  EXPECT_GT(failures, 0);
  lcm_eventlog_t* log = lcm_eventlog_create(path.c_str(), "r");
  ASSERT_NE(log, nullptr);
  int events = 0;
  std::int64_t last_t_us = -1;
  while (lcm_eventlog_event_t* e = lcm_eventlog_read_next_event(log)) {
    const auto r = decode_pose(e->data, static_cast<std::size_t>(e->datalen));
    EXPECT_TRUE(r) << "event " << events;
    if (r) last_t_us = r->t_us;
    ++events;
    lcm_eventlog_free_event(e);
  }
  lcm_eventlog_destroy(log);
  EXPECT_EQ(events, 20 - failures + 1);  // every event written whole, none half
  EXPECT_EQ(last_t_us, pose_at(100).t_us);
}

TEST(LcmPublisher, FileLogThatIsAnInputOrCannotBeCreatedIsRefused) {
  const fs::path dir = temp_dir("loginput");
  const std::string input = (dir / "recording.aedat4").string();
  std::ofstream(input) << "precious";
  LcmPublisherOptions o;
  o.url = "file://" + input + "?mode=w";
  o.inputs = {input};
  LcmPublisher pub(o);
  EXPECT_EQ(pub.state(), PublisherState::degraded);
  EXPECT_FALSE(pub.can_recover());
  EXPECT_NE(pub.last_error().find("is also an input of this program"), std::string::npos) << pub.last_error();
  std::ifstream in(input);
  std::string text;
  in >> text;
  EXPECT_EQ(text, "precious");
  LcmPublisher missing("file://" + (dir / "no/such/dir/x.lcmlog").string() + "?mode=w");
  EXPECT_FALSE(missing.can_recover());
  EXPECT_NE(missing.last_error().find("cannot create"), std::string::npos) << missing.last_error();
  fs::remove_all(dir);
}

// A valid URL LCM cannot create (udpm without a multicast route: a private network namespace without one).
TEST(LcmPublisher, UnusableUrlIsADegradedStateNotACrash) {
  const auto setup = evpipe::testing::enter_private_netns(false);
  if (!setup.ok) GTEST_SKIP() << "needs a private network namespace: " << setup.message;
  for (const std::string url : {"udpm://239.255.76.67:7667?ttl=0"}) {
    SCOPED_TRACE(url);
    LcmPublisherOptions o;
    o.url = url;
    o.retry_interval = std::chrono::milliseconds(0);  // retry on every publish: attempts are countable
    LcmPublisher pub(o);
    EXPECT_EQ(pub.state(), PublisherState::degraded);
    EXPECT_FALSE(pub.last_error().empty());
    EXPECT_NE(pub.last_error().find(url), std::string::npos) << pub.last_error();
    for (int k = 0; k < 3; ++k) {
      EXPECT_FALSE(pub.publish_pose(pose_at(k)));
    }
    EXPECT_FALSE(pub.publish_stats(StatsRecord{}));
    const PublisherCounters c = pub.counters();
    EXPECT_EQ(c.poses_published, 0);
    EXPECT_EQ(c.publish_failures, 4);
    EXPECT_EQ(c.connect_attempts, 5);  // construction + one per publish
    EXPECT_EQ(c.connect_failures, 5);
    EXPECT_NE(pub.status_text().find("unavailable"), std::string::npos) << pub.status_text();
  }
}

TEST(LcmPublisher, RetriesAreRateLimited) {
  LcmPublisherOptions o;
  const auto setup = evpipe::testing::enter_private_netns(false);
  if (!setup.ok) GTEST_SKIP() << "needs a private network namespace: " << setup.message;
  o.url = "udpm://239.255.76.67:7667?ttl=0";  // valid, but no multicast route: retried
  o.retry_interval = std::chrono::hours(1);
  LcmPublisher pub(o);
  for (int k = 0; k < 100; ++k) {
    EXPECT_FALSE(pub.publish_pose(pose_at(k)));
  }
  const PublisherCounters c = pub.counters();
  EXPECT_EQ(c.connect_attempts, 1);  // only the construction: the next try is an hour away
  EXPECT_EQ(c.publish_failures, 100);
}

TEST(LcmPublisher, UnusableSharedInstanceIsDegraded) {
  LcmPublisher pub(std::shared_ptr<lcm::LCM>{}, "P", "S");
  EXPECT_EQ(pub.state(), PublisherState::degraded);
  EXPECT_FALSE(pub.publish_pose(pose_at(1)));
  EXPECT_EQ(pub.counters().publish_failures, 1);
}

TEST(LcmPublisher, ConcurrentPublishersOfPosesAndStats) {
  // The pose stage and the statistics timer may publish from two threads.
  auto lcm = std::make_shared<lcm::LCM>("memq://");
  LcmPublisher pub(lcm, "P", "S");
  std::thread a([&] {
    for (int k = 0; k < 200; ++k) {
      pub.publish_pose(pose_at(k));
    }
  });
  std::thread b([&] {
    for (int k = 0; k < 50; ++k) {
      pub.publish_stats(StatsRecord{});
    }
  });
  a.join();
  b.join();
  const PublisherCounters c = pub.counters();
  EXPECT_EQ(c.poses_published, 200);
  EXPECT_EQ(c.stats_published, 50);
  EXPECT_EQ(c.publish_failures, 0);
}

TEST(LcmPublisher, EffectiveUrl) {
  EXPECT_EQ(effective_lcm_url("memq://"), "memq://");
  ::unsetenv("LCM_DEFAULT_URL");
  EXPECT_EQ(effective_lcm_url(""), "udpm://239.255.76.67:7667?ttl=0");
  ::setenv("LCM_DEFAULT_URL", "udpm://239.255.76.67:7668?ttl=1", 1);
  EXPECT_EQ(effective_lcm_url(""), "udpm://239.255.76.67:7668?ttl=1");
  ::unsetenv("LCM_DEFAULT_URL");
}

}  // namespace
}  // namespace evpipe::transport

namespace evpipe::transport {
namespace {

TEST(LcmCapture, UnsubscribesFromASharedInstanceWhenDestroyed) {
  auto lcm = std::make_shared<lcm::LCM>("memq://");
  LcmPublisher pub(lcm, "P", "S");
  {
    LcmCapture first(lcm);
    first.subscribe("P");
  }  // gone: its callback must not run for the next message
  LcmCapture second(lcm);
  second.subscribe("P");
  ASSERT_TRUE(pub.publish_pose(PoseRecord{}));
  EXPECT_EQ(second.wait_for(1, std::chrono::seconds(5)), 1U);
}

}  // namespace
}  // namespace evpipe::transport
