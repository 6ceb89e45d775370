#pragma once
// Replay pacing: wraps any EventSource and hands its events out no earlier than their recorded time
// allows (`--speed 1` = real time, 2 = twice as fast). Readers stay pacing-free.
//
// Batches are re-cut into chunks of at most `chunk_us` of event time, so that a low-rate recording is not
// delivered in bursts of a whole file batch (8192 events can span a second). Each chunk is released when
// its newest event is due. The time anchor restarts at every clock discontinuity.

#include <atomic>
#include <chrono>
#include <cstdint>
#include <memory>

#include "evpipe/core/source.hpp"

namespace evpipe::runtime {

class PacedSource final : public EventSource {
 public:
  /// Throws std::invalid_argument when speed <= 0 or chunk_us <= 0.
  PacedSource(std::unique_ptr<EventSource> inner, double speed, std::int64_t chunk_us = 1000);

  /// Sleeps until the next chunk is due, then returns it; nullptr at the end or after stop().
  EventBatchPtr next() override;
  [[nodiscard]] bool finished() const override;
  [[nodiscard]] const SourceInfo& info() const override { return inner_->info(); }
  [[nodiscard]] const SourceStats& stats() const override { return inner_->stats(); }
  [[nodiscard]] std::optional<double> progress() const override { return inner_->progress(); }
  [[nodiscard]] SourceConnection connection() const noexcept override { return inner_->connection(); }
  [[nodiscard]] std::uint64_t reconnects() const noexcept override { return inner_->reconnects(); }

  /// Wakes a pending sleep (within 50 ms) and makes next() return nullptr; also stops the inner source.
  void stop() noexcept override {
    stop_.store(true);
    inner_->stop();
  }

 private:
  using Clock = std::chrono::steady_clock;
  bool sleep_until(Clock::time_point due);

  std::unique_ptr<EventSource> inner_;
  double speed_;
  std::int64_t chunk_us_;
  EventBatchPtr pending_;
  std::size_t pending_pos_ = 0;
  bool have_anchor_ = false;
  std::int64_t anchor_t_us_ = 0;
  Clock::time_point anchor_wall_{};
  std::atomic<bool> stop_{false};
};

}  // namespace evpipe::runtime
