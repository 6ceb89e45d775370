#include "evpipe/runtime/paced_source.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <thread>

namespace evpipe::runtime {

PacedSource::PacedSource(std::unique_ptr<EventSource> inner, double speed, std::int64_t chunk_us)
    : inner_(std::move(inner)), speed_(speed), chunk_us_(chunk_us) {
  if (!(speed_ > 0)) throw std::invalid_argument("PacedSource: speed must be > 0");
  if (chunk_us_ <= 0) throw std::invalid_argument("PacedSource: chunk_us must be > 0");
}

bool PacedSource::finished() const {
  return stop_.load() || (inner_->finished() && (!pending_ || pending_pos_ >= pending_->size()));
}

bool PacedSource::sleep_until(Clock::time_point due) {
  // Sleep in short steps so stop() takes effect quickly.
  constexpr auto step = std::chrono::milliseconds(50);
  while (!stop_.load()) {
    const auto now = Clock::now();
    if (now >= due) return true;
    std::this_thread::sleep_until(std::min(due, now + step));
  }
  return false;
}

EventBatchPtr PacedSource::next() {
  if (stop_.load()) return nullptr;
  if (!pending_ || pending_pos_ >= pending_->size()) {
    do {
      pending_ = inner_->next();
    } while (pending_ && pending_->empty());
    pending_pos_ = 0;
    if (!pending_) return nullptr;
    if (pending_->discontinuity_before) have_anchor_ = false;
  }
  const auto& ev = pending_->events;
  const bool first_chunk = pending_pos_ == 0;
  const std::int64_t start_t = ev[pending_pos_].t_us;
  if (!have_anchor_) {
    have_anchor_ = true;
    anchor_t_us_ = start_t;
    anchor_wall_ = Clock::now();
  }
  // Chunk: events up to start_t + chunk_us (exclusive), at least one.
  auto begin = ev.begin() + static_cast<std::ptrdiff_t>(pending_pos_);
  // Overflow-safe sums (issue 17): times may sit anywhere on the int64 line.
  const std::int64_t chunk_end = start_t > std::numeric_limits<std::int64_t>::max() - chunk_us_
                                     ? std::numeric_limits<std::int64_t>::max()
                                     : start_t + chunk_us_;
  auto end =
      std::lower_bound(begin + 1, ev.end(), chunk_end, [](const Event& e, std::int64_t t) { return e.t_us < t; });
  auto chunk = std::make_shared<EventBatch>();
  chunk->events.assign(begin, end);
  if (pending_->labelled()) {
    const auto lb = pending_->labels.begin() + static_cast<std::ptrdiff_t>(pending_pos_);
    chunk->labels.assign(lb, lb + (end - begin));
  }
  chunk->discontinuity_before = first_chunk && pending_->discontinuity_before;
  pending_pos_ = static_cast<std::size_t>(end - ev.begin());

  // In double (the difference of two int64 times can overflow), capped at ~31 years so that the steady clock's
  // nanosecond count cannot overflow either (a stop() still ends the wait).
  constexpr double kMaxWait_us = 1e15;
  const double dt_wall_us =
      (static_cast<double>(chunk->events.back().t_us) - static_cast<double>(anchor_t_us_)) / speed_;
  const auto due =
      anchor_wall_ + std::chrono::microseconds(static_cast<std::int64_t>(std::clamp(dt_wall_us, 0.0, kMaxWait_us)));
  if (!sleep_until(due)) return nullptr;
  chunk->read_at = Clock::now();  // released now: what a live camera would have delivered at this moment
  return chunk;
}

}  // namespace evpipe::runtime
