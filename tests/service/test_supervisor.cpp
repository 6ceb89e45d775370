// Watchdog supervisor: pings only while every stage progresses (or is idle by declaration). Stepped with
// check() for exact expectations, plus one test of the real thread with a 200 ms watchdog that waits on
// events (generous timeouts), never on durations.
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <functional>
#include <stdexcept>
#include <string>
#include <thread>

#include <gtest/gtest.h>

#include "evpipe/service/supervisor.hpp"
#include "notify_socket.hpp"

using evpipe::testing::has_line;
using evpipe::testing::NotifySocket;
namespace service = evpipe::service;
using namespace std::chrono_literals;

namespace {
service::SupervisorOptions with_watchdog(std::chrono::microseconds usec) {
  service::SupervisorOptions o;
  o.watchdog_usec = usec;
  return o;
}

// Waits until `done()` holds, polling; false after `timeout` (a bound against hangs, not a timing check).
bool wait_for(const std::function<bool()>& done, std::chrono::milliseconds timeout = 10s) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(2ms);
  }
  return true;
}
}  // namespace

TEST(Supervisor, PeriodIsHalfTheWatchdog) {
  ::unsetenv("WATCHDOG_USEC");
  service::Supervisor with(with_watchdog(200ms));
  EXPECT_TRUE(with.watchdog_enabled());
  EXPECT_EQ(with.period(), std::chrono::microseconds(100000));

  service::SupervisorOptions o;
  o.status_period = 750ms;
  service::Supervisor without(o);
  EXPECT_FALSE(without.watchdog_enabled());
  EXPECT_EQ(without.period(), std::chrono::microseconds(750000));

  ::setenv("WATCHDOG_USEC", "5000000", 1);  // what systemd passes for WatchdogSec=5s
  service::Supervisor from_env;
  EXPECT_TRUE(from_env.watchdog_enabled());
  EXPECT_EQ(from_env.period(), std::chrono::microseconds(2500000));
  ::unsetenv("WATCHDOG_USEC");
}

TEST(Supervisor, PingsOnlyWhileEveryStageAdvancesOrIsIdle) {
  NotifySocket sock;
  service::Supervisor sup(with_watchdog(200ms));
  service::Heartbeat source, denoise;
  sup.watch("source", source);
  sup.watch("denoise", denoise);

  source.beat();
  denoise.beat();
  auto r = sup.check();
  EXPECT_TRUE(r.healthy);
  EXPECT_TRUE(r.pinged);
  EXPECT_TRUE(r.stuck.empty());
  EXPECT_EQ(sock.receive(5s).value_or("<none>"), "WATCHDOG=1");

  // denoise hangs: no ping, its name in the result and in STATUS=.
  source.beat();
  r = sup.check();
  EXPECT_FALSE(r.healthy);
  EXPECT_FALSE(r.pinged);
  ASSERT_EQ(r.stuck.size(), 1u);
  EXPECT_EQ(r.stuck[0], "denoise");
  auto m = sock.receive(5s).value_or("<none>");
  EXPECT_FALSE(has_line(m, "WATCHDOG=1")) << m;
  EXPECT_TRUE(has_line(m, "STATUS=STUCK: denoise")) << m;
  EXPECT_EQ(sup.consecutive_stuck(), 1u);

  // Still stuck on the next check (no beat at all now): both stages.
  r = sup.check();
  EXPECT_FALSE(r.pinged);
  EXPECT_EQ(r.stuck, (std::vector<std::string>{"source", "denoise"}));
  EXPECT_EQ(sup.consecutive_stuck(), 2u);
  sock.drain();

  // denoise declares itself idle (empty input queue), source works again: healthy.
  denoise.set_idle(true);
  source.beat();
  r = sup.check();
  EXPECT_TRUE(r.healthy);
  EXPECT_TRUE(r.pinged);
  EXPECT_EQ(sock.receive(5s).value_or("<none>"), "WATCHDOG=1");
  EXPECT_EQ(sup.consecutive_stuck(), 0u);

  // Idle does not cover another stage: source stops without declaring idle.
  r = sup.check();
  EXPECT_FALSE(r.pinged);
  EXPECT_EQ(r.stuck, (std::vector<std::string>{"source"}));
  EXPECT_EQ(sup.checks(), 5u);
}

TEST(Supervisor, ProbeFunctionsAndStatusSummary) {
  NotifySocket sock;
  service::SupervisorOptions o = with_watchdog(200ms);
  std::atomic<int> windows{0};
  o.status = [&windows] { return "tracking, " + std::to_string(windows.load()) + " windows\nignored"; };
  service::Supervisor sup(o);
  std::atomic<std::uint64_t> pose_count{0};
  std::atomic<bool> pose_idle{false};
  sup.watch("pose", [&] { return service::HeartbeatSample{pose_count.load(), pose_idle.load()}; });

  pose_count = 3;
  windows = 7;
  auto r = sup.check();
  EXPECT_TRUE(r.pinged);
  EXPECT_EQ(sock.receive(5s).value_or("<none>"), "WATCHDOG=1\nSTATUS=tracking, 7 windows ignored");

  r = sup.check();  // count still 3
  EXPECT_FALSE(r.pinged);
  EXPECT_EQ(sock.receive(5s).value_or("<none>"), "STATUS=STUCK: pose; tracking, 7 windows ignored");

  pose_idle = true;
  r = sup.check();
  EXPECT_TRUE(r.pinged);
}

TEST(Supervisor, WithoutWatchdogOnlyStatus) {
  NotifySocket sock;
  ::unsetenv("WATCHDOG_USEC");
  service::SupervisorOptions o;
  o.status = [] { return std::string("replaying"); };
  service::Supervisor sup(o);
  ASSERT_FALSE(sup.watchdog_enabled());
  service::Heartbeat hb;
  sup.watch("source", hb);
  hb.beat();
  auto r = sup.check();
  EXPECT_TRUE(r.healthy);
  EXPECT_FALSE(r.pinged);
  EXPECT_EQ(sock.receive(5s).value_or("<none>"), "STATUS=replaying");
}

TEST(Supervisor, WatchAfterStartAndEmptyProbeAreErrors) {
  ::unsetenv("NOTIFY_SOCKET");
  service::Supervisor sup(with_watchdog(200ms));
  EXPECT_THROW(sup.watch("x", std::function<service::HeartbeatSample()>{}), std::invalid_argument);
  EXPECT_FALSE(sup.start());  // outside systemd: no thread
  service::Heartbeat hb;
  EXPECT_THROW(sup.watch("late", hb), std::logic_error);
  sup.stop();
}

TEST(Supervisor, OutsideSystemdNothingIsSent) {
  ::unsetenv("NOTIFY_SOCKET");
  service::Supervisor sup(with_watchdog(200ms));
  service::Heartbeat hb;
  sup.watch("source", hb);
  EXPECT_FALSE(sup.start());
  hb.beat();
  const auto r = sup.check();
  EXPECT_TRUE(r.healthy);
  EXPECT_FALSE(r.pinged);  // healthy, but there is nobody to ping
}

TEST(Supervisor, ThreadPingsWhileStagesRunAndStopsWhenOneHangs) {
  NotifySocket sock;
  ::setenv("WATCHDOG_USEC", "200000", 1);  // as systemd would pass WatchdogSec=200ms
  service::Supervisor sup;
  ::unsetenv("WATCHDOG_USEC");
  ASSERT_TRUE(sup.watchdog_enabled());

  service::Heartbeat a, b;
  sup.watch("a", a);
  sup.watch("b", b);
  std::atomic<bool> run{true}, b_runs{true};
  std::thread worker([&] {
    while (run) {
      a.beat();
      if (b_runs) b.beat();
      std::this_thread::sleep_for(1ms);
    }
  });

  ASSERT_TRUE(sup.start());
  // The first ping goes out at start, then one per healthy check.
  int pings = 0;
  ASSERT_TRUE(wait_for([&] {
    for (const auto& m : sock.drain()) pings += has_line(m, "WATCHDOG=1") ? 1 : 0;
    return pings >= 4;
  })) << "only "
      << pings << " pings";

  // b hangs. Once a check saw it, every following check withholds the ping.
  b_runs = false;
  ASSERT_TRUE(wait_for([&] { return sup.consecutive_stuck() >= 1; }));
  sock.drain();  // pings sent before the hang was seen
  ASSERT_TRUE(wait_for([&] { return sup.consecutive_stuck() >= 4; }));
  bool saw_stuck_status = false;
  for (const auto& m : sock.drain()) {
    EXPECT_FALSE(has_line(m, "WATCHDOG=1")) << "pinged while stage b hangs: " << m;
    saw_stuck_status = saw_stuck_status || m.find("STATUS=STUCK: ") != std::string::npos;
  }
  EXPECT_TRUE(saw_stuck_status);

  // b declares itself idle (waiting on an empty queue): pings resume.
  b.set_idle(true);
  bool resumed = false;
  ASSERT_TRUE(wait_for([&] {
    for (const auto& m : sock.drain()) resumed = resumed || has_line(m, "WATCHDOG=1");
    return resumed;
  }));

  sup.stop();
  run = false;
  worker.join();
  const auto checks_after_stop = sup.checks();
  std::this_thread::sleep_for(250ms);
  EXPECT_EQ(sup.checks(), checks_after_stop) << "the supervisor thread kept checking after stop()";
}
