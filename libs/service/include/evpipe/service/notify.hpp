#pragma once
// The sd_notify(3) protocol of a Type=notify systemd service: READY, STATUS, STOPPING and the watchdog
// keep-alive. Every call is a no-op returning false outside systemd (no $NOTIFY_SOCKET), so the same binary runs
// unchanged from a terminal, a test or the service manager.

#include <chrono>
#include <optional>
#include <string>
#include <string_view>

namespace evpipe::service {

/// True when $NOTIFY_SOCKET is set, i.e. a service manager listens for notifications.
[[nodiscard]] bool notify_socket_set();

/// Sends one raw notification ("KEY=value" lines). Returns true when it was delivered, false outside systemd
/// or when sending failed (logged at debug level: losing a notification must never stop the pipeline).
bool notify(std::string_view state);

/// READY=1: start-up finished (systemd leaves "activating" and starts dependent units). `status` (optional) is
/// sent in the same message as STATUS=.
bool ready(std::string_view status = {});

/// STATUS=<text>: the one-line summary `systemctl status evpipe` shows. Line breaks become spaces (a newline
/// would start another KEY=value assignment, e.g. a spurious READY=1).
bool status(std::string_view text);

/// STOPPING=1: shutdown began (sent before draining the queues).
bool stopping();

/// WATCHDOG=1: the keep-alive ping. Normally sent by Supervisor, which pings only while every stage progresses.
bool watchdog_ping();

/// The watchdog period systemd expects pings within ($WATCHDOG_USEC, via sd_watchdog_enabled(3)); nullopt when
/// the watchdog is off (no WatchdogSec=, not under systemd, or $WATCHDOG_PID names another process).
[[nodiscard]] std::optional<std::chrono::microseconds> watchdog_interval();

/// `text` made safe for one STATUS= line: line breaks and other control characters become spaces.
[[nodiscard]] std::string one_line(std::string_view text);

}  // namespace evpipe::service
