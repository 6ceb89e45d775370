#include "evpipe/core/slicer.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>

namespace evpipe {

namespace {
__extension__ typedef __int128 Wide;  // NOLINT(modernize-use-using): __extension__ keeps -Wpedantic quiet
constexpr Wide kMaxTime = std::numeric_limits<std::int64_t>::max();
}  // namespace

std::size_t EventWindow::size() const noexcept {
  std::size_t n = 0;
  for (const auto& p : parts) n += p.size();
  return n;
}

std::vector<Event> EventWindow::contiguous() const {
  std::vector<Event> out;
  out.reserve(size());
  for (const auto& p : parts) out.insert(out.end(), p.begin(), p.end());
  return out;
}

TimeSlicer::TimeSlicer(Options options, Callback callback) : options_(options), callback_(std::move(callback)) {
  if (options_.window_us <= 0) throw std::invalid_argument("TimeSlicer: window_us must be > 0");
  if (options_.hop_us <= 0) throw std::invalid_argument("TimeSlicer: hop_us must be > 0");
  next_t0_ = options_.start_us;
}

void TimeSlicer::accept(const EventBatchPtr& batch) {
  if (!batch || batch->empty()) return;
  if (batch->discontinuity_before && (!retained_.empty() || grid_ended_)) {
    flush();
    retained_.clear();
    next_t0_.reset();
    grid_ended_ = false;
    segment_start_ = true;
    last_windowed_t_.reset();
  }
  if (grid_ended_) return;  // past the end of the time line: nothing more can be cut (and nothing is kept)
  if (!next_t0_) next_t0_ = batch->events.front().t_us;
  retained_.push_back(batch);
  emit_ready(batch->events.back().t_us, false);
}

bool TimeSlicer::allow_empty(std::int64_t t1) const noexcept {
  return options_.max_empty_span_us > 0 && last_windowed_t_ &&
         Wide{t1} <= Wide{*last_windowed_t_} + options_.max_empty_span_us;
}

void TimeSlicer::advance(std::int64_t t_us) {
  if (options_.max_empty_span_us <= 0 || !next_t0_ || grid_ended_) return;
  // Time alone completes the windows holding the events retained and the empty ones within the span after the
  // newest event; later windows wait for an event (the cap also bounds this call's work).
  // The newest event seen: the last retained one, or the newest windowed when nothing is retained any more.
  const std::optional<std::int64_t> base =
      retained_.empty() ? last_windowed_t_ : std::optional(retained_.back()->events.back().t_us);
  if (!base) return;
  const Wide cap = Wide{*base} + std::max(options_.max_empty_span_us, options_.window_us);
  emit_ready(static_cast<std::int64_t>(std::min<Wide>(Wide{t_us}, std::min<Wide>(cap, kMaxTime))), false);
}

void TimeSlicer::flush() {
  if (retained_.empty() || !next_t0_ || grid_ended_) return;
  emit_ready(retained_.back()->events.back().t_us, true);
  retained_.clear();
}

void TimeSlicer::emit_ready(std::int64_t newest_t_us, bool final) {
  // Times are int64 microseconds from any origin, so every sum below is computed in 128 bits: a window end or grid
  // start past INT64_MAX (a recording stamped near the end of the time line, or a huge window) must end the grid,
  // not wrap around (a wrapped start made this loop spin for ever).
  constexpr Wide kMax = kMaxTime;
  const std::int64_t w = options_.window_us;
  const std::int64_t h = options_.hop_us;
  while (next_t0_ && !grid_ended_) {
    const std::int64_t t0 = *next_t0_;
    const auto t1 = static_cast<std::int64_t>(std::min<Wide>(Wide{t0} + w, kMax));
    // Complete once an event at or after t1 exists; at the end, any window still holding events.
    if (!final && newest_t_us < t1) break;
    if (final && newest_t_us < t0) break;
    emit_window(t0, t1);
    // Next grid start; jump over empty stretches (no event in [next, next + w)).
    const Wide next_wide = Wide{t0} + h;
    if (next_wide > kMax) {
      grid_ended_ = true;
      retained_.clear();
      break;
    }
    auto next = static_cast<std::int64_t>(next_wide);
    drop_before(next);
    if (!retained_.empty()) {
      // First retained event at or after `next`.
      std::optional<std::int64_t> first_after;
      for (const auto& b : retained_) {
        auto it = std::lower_bound(b->events.begin(), b->events.end(), next,
                                   [](const Event& e, std::int64_t t) { return e.t_us < t; });
        if (it != b->events.end()) {
          first_after = it->t_us;
          break;
        }
      }
      // ... unless empty windows are wanted there (within max_empty_span_us of the newest event windowed).
      if (first_after && Wide{*first_after} >= Wide{next} + w &&
          !allow_empty(static_cast<std::int64_t>(std::min<Wide>(Wide{next} + w, kMax)))) {
        // Smallest grid start whose window still contains first_after.
        const Wide k = (Wide{*first_after} - w - t0) / h + 1;
        const Wide jumped = Wide{t0} + std::max<Wide>(k, 1) * h;
        if (jumped > kMax) {
          grid_ended_ = true;
          retained_.clear();
          break;
        }
        next = static_cast<std::int64_t>(jumped);
        drop_before(next);
      }
    }
    next_t0_ = next;
  }
}

void TimeSlicer::emit_window(std::int64_t t0, std::int64_t t1) {
  EventWindow win;
  win.t0_us = t0;
  win.t1_us = t1;
  for (const auto& b : retained_) {
    const auto& ev = b->events;
    auto lo = std::lower_bound(ev.begin(), ev.end(), t0, [](const Event& e, std::int64_t t) { return e.t_us < t; });
    auto hi = std::lower_bound(lo, ev.end(), t1, [](const Event& e, std::int64_t t) { return e.t_us < t; });
    if (lo != hi) {
      win.parts.emplace_back(&*lo, static_cast<std::size_t>(hi - lo));
      win.owners.push_back(b);
    }
  }
  if (win.parts.empty() && !allow_empty(t1)) return;
  if (!win.parts.empty()) last_windowed_t_ = win.parts.back().back().t_us;
  win.starts_segment = segment_start_;
  segment_start_ = false;
  ++emitted_;
  callback_(std::move(win));
}

void TimeSlicer::drop_before(std::int64_t t_us) {
  while (!retained_.empty() && retained_.front()->events.back().t_us < t_us) retained_.pop_front();
}

}  // namespace evpipe
