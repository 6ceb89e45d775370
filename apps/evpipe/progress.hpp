#pragma once
// A one-line progress bar on a terminal (stderr), redrawn at most 10 times a second; nothing when stderr
// is not a TTY (piped, journald) so logs stay clean.

#include <chrono>
#include <cstdint>
#include <optional>
#include <string_view>

namespace evpipe::app {

class ProgressBar {
 public:
  /// enabled=false, or stderr not a TTY → all calls are no-ops.
  explicit ProgressBar(bool enabled);
  /// fraction: share of the input consumed (nullopt for live); events: total so far.
  /// extra: appended as is (kept share, pose status).
  void update(std::optional<double> fraction, std::uint64_t events, std::int64_t stream_time_us,
              std::string_view extra = {});
  /// Clears the line.
  void finish();
  [[nodiscard]] bool active() const noexcept { return active_; }

 private:
  using Clock = std::chrono::steady_clock;
  bool active_;
  Clock::time_point start_ = Clock::now();
  Clock::time_point last_draw_{};
  std::uint64_t last_events_ = 0;
  Clock::time_point last_rate_t_ = Clock::now();
  double rate_mevs_ = 0;
};

}  // namespace evpipe::app
