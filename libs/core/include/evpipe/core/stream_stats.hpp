#pragma once
// Running statistics of an event stream (the replay summary): count, time span, mean and peak rate,
// ON share. Peak rate is the largest count in a fixed bin (default 10 ms) of event time, divided by the
// bin length: a sustained-burst figure, not an instantaneous one.

#include <cstdint>
#include <optional>

#include "evpipe/core/event.hpp"

namespace evpipe {

class StreamStats {
 public:
  explicit StreamStats(std::int64_t peak_bin_us = 10'000) : bin_us_(peak_bin_us > 0 ? peak_bin_us : 10'000) {}

  void add(EventSpan events) noexcept;

  [[nodiscard]] std::uint64_t events() const noexcept { return events_; }
  [[nodiscard]] std::uint64_t on_events() const noexcept { return on_; }
  [[nodiscard]] std::optional<std::int64_t> first_t_us() const noexcept { return first_; }
  [[nodiscard]] std::optional<std::int64_t> last_t_us() const noexcept { return last_; }
  /// last - first, 0 for fewer than two events.
  [[nodiscard]] std::int64_t duration_us() const noexcept;
  /// Events per second over the duration; 0 when the duration is 0.
  [[nodiscard]] double mean_rate_hz() const noexcept;
  /// Largest events-per-bin, as events per second.
  [[nodiscard]] double peak_rate_hz() const noexcept;
  [[nodiscard]] double on_share() const noexcept {
    return events_ ? static_cast<double>(on_) / static_cast<double>(events_) : 0.0;
  }
  [[nodiscard]] std::int64_t peak_bin_us() const noexcept { return bin_us_; }

 private:
  std::int64_t bin_us_;
  std::uint64_t events_ = 0;
  std::uint64_t on_ = 0;
  std::optional<std::int64_t> first_;
  std::optional<std::int64_t> last_;
  std::optional<std::int64_t> bin_start_;
  std::uint64_t bin_count_ = 0;
  std::uint64_t peak_count_ = 0;
};

}  // namespace evpipe
