#pragma once
// Subscribes to LCM channels and keeps what arrives: for tests, evpipe-lcm-echo and other tools. Also reads LCM
// log files (lcm-logger, file:// provider).

#include "evpipe/transport/records.hpp"

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace lcm {
class LCM;
}

namespace evpipe::transport {

struct ReceivedMessage {
  std::string channel;
  std::vector<std::uint8_t> data;
  std::int64_t recv_utime_us{0};  ///< host wall clock at reception (log files: the logged timestamp)
};

class LcmCapture {
 public:
  /// Own instance on `url` ("" = LCM's default). Check good() (no multicast route -> false).
  explicit LcmCapture(const std::string& url);
  /// Shares an instance (memq:// is private to one instance).
  explicit LcmCapture(std::shared_ptr<lcm::LCM> lcm);
  ~LcmCapture();
  LcmCapture(const LcmCapture&) = delete;
  LcmCapture& operator=(const LcmCapture&) = delete;

  [[nodiscard]] bool good() const;
  /// Subscribes to a channel name or POSIX regex (LCM matches the whole name: ".*" = all).
  void subscribe(const std::string& channel_regex);
  /// Called for every message as it arrives (before it is stored); optional.
  void on_message(std::function<void(const ReceivedMessage&)> callback);
  /// Keep messages in messages() (default true; an echo tool that only streams turns it off).
  void keep_messages(bool keep) { keep_ = keep; }

  /// Handles incoming messages until `count` messages have been received in total or `timeout` has passed.
  /// Returns the total received.
  std::size_t wait_for(std::size_t count, std::chrono::milliseconds timeout);
  /// Handles incoming messages for `duration`; returns the total received.
  std::size_t drain(std::chrono::milliseconds duration);

  [[nodiscard]] std::size_t received() const noexcept { return received_; }
  [[nodiscard]] const std::vector<ReceivedMessage>& messages() const noexcept { return messages_; }
  /// The stored messages of `channel` decoded (messages of other types are skipped; DecodeError propagates).
  [[nodiscard]] std::vector<PoseRecord> poses(const std::string& channel = std::string(kDefaultPoseChannel)) const;
  [[nodiscard]] std::vector<StatsRecord> stats(const std::string& channel = std::string(kDefaultStatsChannel)) const;

 private:
  struct Handler;
  std::shared_ptr<lcm::LCM> lcm_;
  std::unique_ptr<Handler> handler_;
  std::vector<ReceivedMessage> messages_;
  std::function<void(const ReceivedMessage&)> callback_;
  std::size_t received_{0};
  bool keep_{true};
};

/// A log file whose content is not a sequence of whole LCM events: a bad sync word, a length beyond the end of
/// the file, a truncated event. what() = "<path>: LCM log event at byte <offset>: <reason>" (or, at byte 0,
/// "<path>: not an LCM log file (...)").
class LcmLogError : public std::runtime_error {
 public:
  LcmLogError(const std::string& what, std::uint64_t offset, std::vector<ReceivedMessage> before = {});
  /// Byte offset of the event that could not be read.
  [[nodiscard]] std::uint64_t offset() const noexcept { return offset_; }
  /// The events read before it (read_lcm_log(path) only: the callback form has delivered them already).
  [[nodiscard]] const std::vector<ReceivedMessage>& messages() const noexcept { return messages_; }

 private:
  std::uint64_t offset_;
  std::vector<ReceivedMessage> messages_;
};

/// Every event of an LCM log file (lcm-logger, file://...?mode=w), in order (an empty file has none), passed to
/// `on_event` as it is read. Every length is checked against the bytes left in the file before anything is
/// allocated or read. Throws std::runtime_error naming the file when it cannot be opened or is not a regular file,
/// and LcmLogError (file and byte offset) at the first event that is not whole; the events before it have been
/// passed to `on_event`.
void read_lcm_log(const std::filesystem::path& path, const std::function<void(ReceivedMessage&&)>& on_event);

/// The same, collected. On LcmLogError, its messages() holds the events read before the bad one.
[[nodiscard]] std::vector<ReceivedMessage> read_lcm_log(const std::filesystem::path& path);

}  // namespace evpipe::transport
