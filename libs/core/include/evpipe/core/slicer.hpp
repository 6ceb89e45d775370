#pragma once
// Time-window slicing of a shared event stream, in the spirit of dv-processing's EventStreamSlicer:
// batches are retained (shared, never copied) until every window that needs them has been emitted.
//
// Windows are half-open [t0_us, t1_us). Fixed windows: hop_us == window_us. Sliding windows:
// hop_us < window_us (consecutive windows overlap by window_us - hop_us). The first window starts at the
// first event (or Options::start_us); later windows start on the grid start + k * hop_us. A window is
// emitted once an event at or after its end has been seen (input must be time-ordered), or at flush().
// Windows with no events are not emitted (a gap of hours must not produce millions of empty windows);
// the grid stays aligned across gaps. Exception, Options::max_empty_span_us > 0: empty windows ending at most
// that long after the newest event are emitted too, once complete (an event at or after their end, or advance()
// to it): a denoised stream that keeps nothing while the scene is still is still a stream of windows.

#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <vector>

#include "evpipe/core/event.hpp"

namespace evpipe {

/// A view of the events in [t0_us, t1_us): spans into shared batches, kept alive by `owners`.
struct EventWindow {
  std::int64_t t0_us = 0;
  std::int64_t t1_us = 0;
  std::vector<EventSpan> parts;
  std::vector<EventBatchPtr> owners;
  /// True for the first window after a clock discontinuity (or the first window of the stream).
  bool starts_segment = false;
  /// Optional: the same interval's events before a filter (a denoiser) chose `parts` (empty when there is no filter,
  /// or when the window was cut across a clock discontinuity). Spans into the unfiltered batches, kept alive by
  /// raw_owners.
  std::vector<EventSpan> raw_parts;
  std::vector<EventBatchPtr> raw_owners;

  [[nodiscard]] std::size_t size() const noexcept;
  [[nodiscard]] bool empty() const noexcept { return size() == 0; }
  /// Copies the events into one contiguous vector (for algorithms that need a single span).
  [[nodiscard]] std::vector<Event> contiguous() const;
  template <typename F>
  void for_each(F&& f) const {
    for (const auto& part : parts)
      for (const auto& e : part) f(e);
  }
};

class TimeSlicer {
 public:
  struct Options {
    std::int64_t window_us = 30'000;
    std::int64_t hop_us = 30'000;
    std::optional<std::int64_t> start_us;  ///< grid origin; default: first event
    /// Empty windows that end at most this long after the newest event are emitted (0: none, the default).
    std::int64_t max_empty_span_us = 0;
  };
  using Callback = std::function<void(EventWindow&&)>;  ///< the window is the callee's: it may move it on

  /// Throws std::invalid_argument when window_us <= 0 or hop_us <= 0.
  explicit TimeSlicer(Options options, Callback callback);

  /// Adds a time-ordered batch and emits every window that it completes.
  void accept(const EventBatchPtr& batch);
  /// No event before t_us will be accepted any more (a watermark: e.g. the filtered stream's decided time): with
  /// max_empty_span_us > 0 emits the empty windows that this completes; without it, nothing.
  void advance(std::int64_t t_us);
  /// End of stream (or before a discontinuity): emits the remaining windows that hold events.
  void flush();

  [[nodiscard]] const Options& options() const noexcept { return options_; }
  [[nodiscard]] std::uint64_t windows_emitted() const noexcept { return emitted_; }
  /// Batches currently retained (bounded by the window length, not the recording).
  [[nodiscard]] std::size_t retained_batches() const noexcept { return retained_.size(); }

 private:
  void emit_ready(std::int64_t newest_t_us, bool final);
  /// Emits [t0, t1) when it holds events, or when it is empty and allow_empty(t1).
  void emit_window(std::int64_t t0, std::int64_t t1);
  [[nodiscard]] bool allow_empty(std::int64_t t1) const noexcept;
  void drop_before(std::int64_t t_us);

  Options options_;
  Callback callback_;
  std::deque<EventBatchPtr> retained_;
  std::optional<std::int64_t> next_t0_;
  bool segment_start_ = true;
  /// The grid reached the end of the int64 time line (the next start would overflow): no window starts after the
  /// last one emitted, until a discontinuity restarts the grid. Without it `t0 + hop` wrapped and the loop spun.
  bool grid_ended_ = false;
  std::uint64_t emitted_ = 0;
  std::optional<std::int64_t> last_windowed_t_;  ///< newest event of the windows emitted so far (this segment)
};

}  // namespace evpipe
