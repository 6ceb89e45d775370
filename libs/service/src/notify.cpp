#include "evpipe/service/notify.hpp"

#include <cerrno>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include <spdlog/spdlog.h>
#include <systemd/sd-daemon.h>

namespace evpipe::service {

bool notify_socket_set() {
  const char* socket = std::getenv("NOTIFY_SOCKET");
  return socket != nullptr && *socket != '\0';
}

bool notify(std::string_view state) {
  if (!notify_socket_set()) return false;
  // unset_environment = 0: the supervisor thread and later calls keep using the socket.
  const std::string message(state);
  const int rc = sd_notify(0, message.c_str());
  if (rc < 0) {
    spdlog::debug("sd_notify(\"{}\") failed: {}", one_line(message), std::strerror(-rc));
    return false;
  }
  return rc > 0;
}

bool ready(std::string_view status_text) {
  if (status_text.empty()) return notify("READY=1");
  return notify("READY=1\nSTATUS=" + one_line(status_text));
}

bool status(std::string_view text) {
  return notify("STATUS=" + one_line(text));
}

bool stopping() {
  return notify("STOPPING=1");
}

bool watchdog_ping() {
  return notify("WATCHDOG=1");
}

std::optional<std::chrono::microseconds> watchdog_interval() {
  std::uint64_t usec = 0;
  // > 0: enabled for this process; 0: off; < 0: malformed WATCHDOG_USEC / WATCHDOG_PID (treated as off).
  if (sd_watchdog_enabled(0, &usec) <= 0 || usec == 0) return std::nullopt;
  return std::chrono::microseconds(static_cast<std::int64_t>(usec));
}

std::string one_line(std::string_view text) {
  std::string line(text);
  for (char& c : line) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = ' ';
  }
  return line;
}

}  // namespace evpipe::service
