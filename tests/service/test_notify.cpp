// sd_notify wrapper: the messages a service manager receives, read back from a socket bound in the test.
#include <unistd.h>

#include <cstdlib>
#include <string>

#include <gtest/gtest.h>

#include "evpipe/service/notify.hpp"
#include "notify_socket.hpp"

using evpipe::testing::NotifySocket;
namespace service = evpipe::service;

TEST(Notify, OutsideSystemdEveryCallIsANoOp) {
  ::unsetenv("NOTIFY_SOCKET");
  EXPECT_FALSE(service::notify_socket_set());
  EXPECT_FALSE(service::ready("starting"));
  EXPECT_FALSE(service::status("running"));
  EXPECT_FALSE(service::watchdog_ping());
  EXPECT_FALSE(service::stopping());
}

TEST(Notify, SendsReadyStatusWatchdogStopping) {
  NotifySocket sock;
  ASSERT_TRUE(service::notify_socket_set());

  ASSERT_TRUE(service::ready());
  EXPECT_EQ(sock.receive(std::chrono::seconds(5)).value_or("<none>"), "READY=1");

  ASSERT_TRUE(service::ready("live: DAVIS346 00000001"));
  EXPECT_EQ(sock.receive(std::chrono::seconds(5)).value_or("<none>"), "READY=1\nSTATUS=live: DAVIS346 00000001");

  ASSERT_TRUE(service::status("tracking 12.3 Mev/s"));
  EXPECT_EQ(sock.receive(std::chrono::seconds(5)).value_or("<none>"), "STATUS=tracking 12.3 Mev/s");

  ASSERT_TRUE(service::watchdog_ping());
  EXPECT_EQ(sock.receive(std::chrono::seconds(5)).value_or("<none>"), "WATCHDOG=1");

  ASSERT_TRUE(service::stopping());
  EXPECT_EQ(sock.receive(std::chrono::seconds(5)).value_or("<none>"), "STOPPING=1");
  EXPECT_TRUE(sock.drain().empty());
}

TEST(Notify, StatusCannotInjectAnotherAssignment) {
  NotifySocket sock;
  // A newline in the summary would otherwise make systemd read "READY=1" as a second assignment.
  ASSERT_TRUE(service::status("bad\nREADY=1\r\tend"));
  const auto message = sock.receive(std::chrono::seconds(5)).value_or("<none>");
  EXPECT_EQ(message, "STATUS=bad READY=1  end");
  EXPECT_FALSE(evpipe::testing::has_line(message, "READY=1"));
}

TEST(Notify, OneLineReplacesControlCharacters) {
  EXPECT_EQ(service::one_line("a\nb\rc\td\x7f"), "a b c d ");
  EXPECT_EQ(service::one_line("plain 42 %"), "plain 42 %");
  EXPECT_EQ(service::one_line(""), "");
}

TEST(Notify, WatchdogIntervalFromEnvironment) {
  ::unsetenv("WATCHDOG_PID");
  ::unsetenv("WATCHDOG_USEC");
  EXPECT_FALSE(service::watchdog_interval().has_value());

  ::setenv("WATCHDOG_USEC", "200000", 1);
  ASSERT_TRUE(service::watchdog_interval().has_value());
  EXPECT_EQ(service::watchdog_interval()->count(), 200000);

  // WATCHDOG_PID names the process the watchdog is meant for: a child must not ping on the parent's behalf.
  ::setenv("WATCHDOG_PID", std::to_string(::getpid()).c_str(), 1);
  ASSERT_TRUE(service::watchdog_interval().has_value());
  EXPECT_EQ(service::watchdog_interval()->count(), 200000);
  ::setenv("WATCHDOG_PID", std::to_string(::getpid() + 1).c_str(), 1);
  EXPECT_FALSE(service::watchdog_interval().has_value());

  ::unsetenv("WATCHDOG_PID");
  ::setenv("WATCHDOG_USEC", "not-a-number", 1);
  EXPECT_FALSE(service::watchdog_interval().has_value());
  ::unsetenv("WATCHDOG_USEC");
}
