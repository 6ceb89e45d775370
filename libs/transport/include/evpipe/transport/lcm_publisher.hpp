#pragma once
// Publishes pose and statistics records as LCM messages (pose_t on the pose channel, stats_t on the stats
// channel).
//
// LCM fails to construct when the host has no multicast route (an industrial PC booting without network, see
// docs/operations.md "LCM"). That is a degraded state, not an error: publish_*() never throw, count the message
// as failed, and re-try creating the LCM instance at most once per retry_interval. The caller polls state() /
// counters() for its status line (sd_notify STATUS, stats message).
//
// Only what can recover is retried (udpm/mpudpm: a missing route; tcpq: a server not up yet): a URL that
// check_lcm_url() rejects, or a log file that cannot be created, leaves the publisher degraded for good with
// can_recover() false, so that the application can refuse to start. A file:// log (mode=w) is written by the
// publisher itself in LCM's log format (what lcm-logger writes), through evpipe/core/file.hpp (never one of
// `inputs`): each message is flushed whole as it is published, and a write error (full disk) is counted as a
// failure and logged once, not hidden in a buffer.
//
// Thread safety: every member may be called from any thread (one mutex; a publish is a single UDP send).

#include "evpipe/transport/records.hpp"

#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace lcm {
class LCM;
}

namespace evpipe::transport {

struct LcmPublisherOptions {
  /// LCM URL. Empty = LCM's default: $LCM_DEFAULT_URL, else udpm://239.255.76.67:7667?ttl=0.
  std::string url;
  std::string pose_channel{kDefaultPoseChannel};
  std::string stats_channel{kDefaultStatsChannel};
  /// Minimum time between two attempts to create the LCM instance while degraded.
  std::chrono::milliseconds retry_interval{1000};
  /// file:// logs: the program's input files, which the log must not be (refused before truncating).
  std::vector<std::string> inputs;
};

enum class PublisherState : std::uint8_t {
  connected,  ///< an LCM instance exists (lcm.good())
  degraded,   ///< no LCM instance (construction failed); messages are counted as failed, retried later
};

struct PublisherCounters {
  std::int64_t poses_published{0};
  std::int64_t stats_published{0};
  std::int64_t publish_failures{0};  ///< messages not sent: degraded, or lcm publish() returned an error
  std::int64_t connect_attempts{0};  ///< LCM instance creations tried (including the first)
  std::int64_t connect_failures{0};
};

class LcmPublisher {
 public:
  /// Creates the LCM instance now; a failure leaves the publisher degraded (no throw).
  explicit LcmPublisher(LcmPublisherOptions options);
  LcmPublisher(std::string url, std::string pose_channel = std::string(kDefaultPoseChannel),
               std::string stats_channel = std::string(kDefaultStatsChannel));
  /// Publishes through an existing instance (memq:// in tests, where the subscriber must share the instance).
  /// A null or !good() instance gives a permanently degraded publisher (nothing to retry with).
  LcmPublisher(std::shared_ptr<lcm::LCM> lcm, std::string pose_channel, std::string stats_channel);
  ~LcmPublisher();
  LcmPublisher(const LcmPublisher&) = delete;
  LcmPublisher& operator=(const LcmPublisher&) = delete;

  /// Assigns seq (when r.seq < 0), utime (when 0) and latency (when newest_event_arrival is set), encodes and
  /// sends. Returns true when LCM accepted the message.
  bool publish_pose(const PoseRecord& r);
  /// As publish_pose; also fills poses_published / publish_failures when they are negative.
  bool publish_stats(const StatsRecord& r);

  [[nodiscard]] PublisherState state() const;
  /// False when the publisher is degraded for good (an invalid URL, a log file that cannot be created): nothing
  /// is retried; last_error() says why.
  [[nodiscard]] bool can_recover() const;
  /// True for a file:// log.
  [[nodiscard]] bool writes_log() const;
  [[nodiscard]] PublisherCounters counters() const;
  /// Why the publisher is degraded or the last send failed; empty when all is well.
  [[nodiscard]] std::string last_error() const;
  [[nodiscard]] const LcmPublisherOptions& options() const noexcept { return options_; }
  /// Human-readable one-liner: "LCM ok (udpm://...)" / "LCM unavailable since ...: retrying".
  [[nodiscard]] std::string status_text() const;

 private:
  struct LogSink;
  bool ensure_connected_locked();
  bool send_locked(const std::string& channel, const void* data, std::size_t size);

  LcmPublisherOptions options_;
  bool can_retry_{true};
  mutable std::mutex mutex_;
  std::shared_ptr<lcm::LCM> lcm_;
  std::unique_ptr<LogSink> log_;  ///< a file:// log written by the publisher (then lcm_ stays null)
  bool is_log_{false};
  std::chrono::steady_clock::time_point last_attempt_{};
  std::int64_t next_pose_seq_{0};
  std::int64_t next_stats_seq_{0};
  PublisherCounters counters_;
  std::string last_error_;
};

/// The URL LCM will use for `url` (resolves "" through $LCM_DEFAULT_URL and the compiled-in default), for logs.
[[nodiscard]] std::string effective_lcm_url(const std::string& url);

}  // namespace evpipe::transport
