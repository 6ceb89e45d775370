#pragma once
// A stand-in for systemd's notification socket: an AF_UNIX datagram socket bound to a fresh path, exported as
// $NOTIFY_SOCKET for this test process (sd_notify reads the variable at every call).

#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace evpipe::testing {

class NotifySocket {
 public:
  NotifySocket() {
    static std::atomic<int> serial{0};
    path_ = (std::filesystem::temp_directory_path() /
             ("evpipe-notify-" + std::to_string(::getpid()) + "-" + std::to_string(serial++) + ".sock"))
                .string();
    std::filesystem::remove(path_);
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    if (fd_ < 0) throw std::runtime_error("socket(AF_UNIX, SOCK_DGRAM) failed");
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    if (path_.size() >= sizeof(addr.sun_path)) throw std::runtime_error("socket path too long: " + path_);
    path_.copy(addr.sun_path, path_.size());
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) != 0)
      throw std::runtime_error("bind " + path_ + " failed");
    ::setenv("NOTIFY_SOCKET", path_.c_str(), 1);
  }
  ~NotifySocket() {
    ::unsetenv("NOTIFY_SOCKET");
    ::close(fd_);
    std::filesystem::remove(path_);
  }
  NotifySocket(const NotifySocket&) = delete;
  NotifySocket& operator=(const NotifySocket&) = delete;

  /// Every datagram already queued, without waiting.
  std::vector<std::string> drain() {
    std::vector<std::string> out;
    while (auto m = receive(std::chrono::milliseconds(0))) out.push_back(*m);
    return out;
  }

  /// The next datagram, waiting at most `timeout` (a generous bound, not a timing assertion).
  std::optional<std::string> receive(std::chrono::milliseconds timeout) {
    timeval tv{};
    tv.tv_sec = static_cast<time_t>(timeout.count() / 1000);
    tv.tv_usec = static_cast<suseconds_t>((timeout.count() % 1000) * 1000);
    const int flags = timeout.count() == 0 ? MSG_DONTWAIT : 0;
    if (timeout.count() > 0) ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof(tv));
    char buf[4096];
    const ssize_t n = ::recv(fd_, buf, sizeof(buf), flags);
    if (n < 0) return std::nullopt;
    return std::string(buf, static_cast<std::size_t>(n));
  }

  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  std::string path_;
  int fd_ = -1;
};

/// The lines of one notification ("KEY=value\nKEY=value").
inline std::vector<std::string> lines_of(const std::string& message) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= message.size()) {
    const auto end = message.find('\n', start);
    const auto line = message.substr(start, end == std::string::npos ? std::string::npos : end - start);
    if (!line.empty()) out.push_back(line);
    if (end == std::string::npos) break;
    start = end + 1;
  }
  return out;
}

inline bool has_line(const std::string& message, const std::string& line) {
  for (const auto& l : lines_of(message))
    if (l == line) return true;
  return false;
}

}  // namespace evpipe::testing
