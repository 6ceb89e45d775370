#include "evpipe/transport/lcm_publisher.hpp"

#include "evpipe/core/file.hpp"
#include "evpipe/transport/codec.hpp"
#include "evpipe/transport/lcm_url.hpp"

#include <fmt/format.h>
#include <lcm/eventlog.h>
#include <spdlog/spdlog.h>
#include <lcm/lcm-cpp.hpp>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <utility>

#include <sys/types.h>
#include <unistd.h>

namespace evpipe::transport {

namespace {
constexpr const char* kLcmBuiltinDefaultUrl = "udpm://239.255.76.67:7667?ttl=0";
}

std::string effective_lcm_url(const std::string& url) {
  if (!url.empty()) {
    return url;
  }
  const char* env = std::getenv("LCM_DEFAULT_URL");
  if (env != nullptr && *env != '\0') {
    return env;
  }
  return kLcmBuiltinDefaultUrl;
}

struct LcmPublisher::LogSink {
  UniqueFile file;
  lcm_eventlog_t log{};
  bool failing{false};
  off_t whole_size{0};  ///< the file's size after its last whole event: a failed write is cut back to it
};

LcmPublisher::LcmPublisher(LcmPublisherOptions options) : options_(std::move(options)) {
  const std::lock_guard lock(mutex_);
  const std::string url = effective_lcm_url(options_.url);
  LcmUrl parsed;
  if (auto why = check_lcm_url(url, true, &parsed)) {
    can_retry_ = false;
    last_error_ = *why;
    spdlog::warn("LCM: {}; nothing will be published", last_error_);
    return;
  }
  if (parsed.provider == "file") {
    can_retry_ = false;
    is_log_ = true;
    ++counters_.connect_attempts;
    try {
      auto sink = std::make_unique<LogSink>();
      sink->file = open_output_file(parsed.target, options_.inputs);
      // Unbuffered: an event is written by a few write() calls at once, so that a failed one can be cut off the
      // file (a buffered stream would keep the part it could not write and retry it before the next event).
      std::setvbuf(sink->file.get(), nullptr, _IONBF, 0);
      sink->log.f = sink->file.get();
      log_ = std::move(sink);
    } catch (const FileError& e) {
      ++counters_.connect_failures;
      last_error_ = fmt::format("LCM log {}", e.what());
      spdlog::warn("LCM: {}; nothing will be published", last_error_);
    }
    return;
  }
  ensure_connected_locked();
  can_retry_ = parsed.provider != "memq";  // memq:// cannot fail for a reason that goes away
}

LcmPublisher::LcmPublisher(std::string url, std::string pose_channel, std::string stats_channel)
    : LcmPublisher(LcmPublisherOptions{std::move(url), std::move(pose_channel), std::move(stats_channel), {}, {}}) {}

LcmPublisher::LcmPublisher(std::shared_ptr<lcm::LCM> lcm, std::string pose_channel, std::string stats_channel)
    : can_retry_(false) {
  options_.pose_channel = std::move(pose_channel);
  options_.stats_channel = std::move(stats_channel);
  options_.url = "(shared instance)";
  counters_.connect_attempts = 1;
  if (lcm && lcm->good()) {
    lcm_ = std::move(lcm);
  } else {
    counters_.connect_failures = 1;
    last_error_ = "the shared LCM instance is not usable (null or !good())";
    spdlog::warn("LCM: {}; nothing will be published", last_error_);
  }
}

LcmPublisher::~LcmPublisher() = default;

bool LcmPublisher::ensure_connected_locked() {
  if (lcm_) {
    return true;
  }
  if (!can_retry_) {
    return false;
  }
  const auto now = std::chrono::steady_clock::now();
  // Back off from retry_interval up to 10x it: LCM 1.3.1 prints its own error on every failed creation, and an
  // unplugged network can last hours.
  const auto failures = std::min<std::int64_t>(counters_.connect_failures, 10);
  const auto wait = options_.retry_interval * std::max<std::int64_t>(1, failures);
  if (counters_.connect_attempts > 0 && now - last_attempt_ < wait) {
    return false;
  }
  last_attempt_ = now;
  ++counters_.connect_attempts;
  const std::string url = effective_lcm_url(options_.url);
  auto lcm = std::make_shared<lcm::LCM>(options_.url);
  if (lcm->good()) {
    lcm_ = std::move(lcm);
    if (counters_.connect_failures > 0) {
      spdlog::info("LCM: connected to {} after {} failed attempt(s)", url, counters_.connect_failures);
    } else {
      spdlog::debug("LCM: connected to {}", url);
    }
    last_error_.clear();
    return true;
  }
  ++counters_.connect_failures;
  last_error_ = fmt::format(
      "cannot create LCM on {} (for udpm: is there a multicast route, e.g. 224.0.0.0/4 on lo or the NIC?)", url);
  if (counters_.connect_failures == 1) {
    spdlog::warn("LCM: {}; publishing degraded, retrying every {} ms or more", last_error_,
                 options_.retry_interval.count());
  } else {
    spdlog::debug("LCM: attempt {} failed: {}", counters_.connect_attempts, last_error_);
  }
  return false;
}

bool LcmPublisher::send_locked(const std::string& channel, const void* data, std::size_t size) {
  if (log_) {
    lcm_eventlog_event_t e{};
    e.timestamp = wall_clock_utime_us();
    e.channellen = static_cast<std::int32_t>(channel.size());
    e.channel = const_cast<char*>(channel.c_str());  // NOLINT(cppcoreguidelines-pro-type-const-cast): read only
    e.datalen = static_cast<std::int32_t>(size);
    e.data = const_cast<void*>(data);  // NOLINT(cppcoreguidelines-pro-type-const-cast): read only
    // Whole events: each one is flushed as it is written (a kill loses none; a full disk shows at once).
    errno = 0;
    if (lcm_eventlog_write_event(&log_->log, &e) != 0 || std::fflush(log_->file.get()) != 0 ||
        std::ferror(log_->file.get()) != 0) {
      const int err = errno;
      std::clearerr(log_->file.get());
      // A disk that filled up mid-event left part of it: cut it off, so that the log stays a sequence of whole
      // events (readers such as lcm-logplayer stop at a partial one). Not possible on every file (/dev/full).
      if (::ftruncate(::fileno(log_->file.get()), log_->whole_size) == 0) {
        (void)::fseeko(log_->file.get(), log_->whole_size, SEEK_SET);
      }
      if (!log_->failing) {
        last_error_ = fmt::format("cannot write the LCM log: {}", err != 0 ? std::strerror(err) : "write error");
        spdlog::warn("LCM: {}; counting failures", last_error_);
      }
      log_->failing = true;
      ++counters_.publish_failures;
      return false;
    }
    log_->whole_size = ::ftello(log_->file.get());
    if (log_->failing) {
      spdlog::info("LCM: writing the log again");
      last_error_.clear();
      log_->failing = false;
    }
    return true;
  }
  if (!ensure_connected_locked()) {
    ++counters_.publish_failures;
    return false;
  }
  if (lcm_->publish(channel, data, static_cast<unsigned int>(size)) != 0) {
    if (last_error_.empty()) {
      spdlog::warn("LCM: publish on {} failed (network down?); counting failures", channel);
    }
    last_error_ = fmt::format("publish on {} failed", channel);
    ++counters_.publish_failures;
    return false;
  }
  if (!last_error_.empty()) {
    spdlog::info("LCM: publishing again on {}", channel);
    last_error_.clear();
  }
  return true;
}

bool LcmPublisher::publish_pose(const PoseRecord& r) {
  const std::lock_guard lock(mutex_);
  PoseRecord m = r;
  if (m.seq < 0) {
    m.seq = next_pose_seq_++;
  }
  if (m.utime_us == 0) {
    m.utime_us = wall_clock_utime_us();
  }
  if (m.newest_event_arrival != std::chrono::steady_clock::time_point{}) {
    m.latency_us =
        std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::steady_clock::now() - m.newest_event_arrival)
            .count();
  }
  const std::vector<std::uint8_t> bytes = encode(m);
  const bool ok = send_locked(options_.pose_channel, bytes.data(), bytes.size());
  if (ok) {
    ++counters_.poses_published;
  }
  return ok;
}

bool LcmPublisher::publish_stats(const StatsRecord& r) {
  const std::lock_guard lock(mutex_);
  StatsRecord m = r;
  if (m.seq < 0) {
    m.seq = next_stats_seq_++;
  }
  if (m.utime_us == 0) {
    m.utime_us = wall_clock_utime_us();
  }
  if (m.poses_published < 0) {
    m.poses_published = counters_.poses_published;
  }
  if (m.publish_failures < 0) {
    m.publish_failures = counters_.publish_failures;
  }
  const std::vector<std::uint8_t> bytes = encode(m);
  const bool ok = send_locked(options_.stats_channel, bytes.data(), bytes.size());
  if (ok) {
    ++counters_.stats_published;
  }
  return ok;
}

PublisherState LcmPublisher::state() const {
  const std::lock_guard lock(mutex_);
  return (lcm_ || log_) ? PublisherState::connected : PublisherState::degraded;
}

bool LcmPublisher::can_recover() const {
  const std::lock_guard lock(mutex_);
  return lcm_ || log_ || can_retry_;
}

bool LcmPublisher::writes_log() const {
  const std::lock_guard lock(mutex_);
  return is_log_;
}

PublisherCounters LcmPublisher::counters() const {
  const std::lock_guard lock(mutex_);
  return counters_;
}

std::string LcmPublisher::last_error() const {
  const std::lock_guard lock(mutex_);
  return last_error_;
}

std::string LcmPublisher::status_text() const {
  const std::lock_guard lock(mutex_);
  const std::string url = options_.url == "(shared instance)" ? options_.url : effective_lcm_url(options_.url);
  if (!lcm_ && !log_) {
    if (!can_retry_) return fmt::format("LCM unavailable on {}: {}", url, last_error_);
    return fmt::format("LCM unavailable on {} ({} attempt(s)), retrying", url, counters_.connect_attempts);
  }
  if (!last_error_.empty()) {
    return fmt::format("LCM on {}: {}", url, last_error_);
  }
  return fmt::format("LCM ok on {}", url);
}

}  // namespace evpipe::transport
