#pragma once
// A filter applied to a stream of batches: holds the events whose decision is still pending (look-ahead filters
// decide late) and matches each decision with its event. The one place that does this bookkeeping, for evpipe's
// denoise stage and for evdenoise, so both keep exactly the same events. Two outputs, usable together:
//  - the kept events, unchanged and in input order, as new batches (labels carried): what a pipeline consumes;
//  - an observer called with every run of decided events (DecidedSegment): what metrics consume, without copies.
//
//   FilteredStream s(*filter, [&](const DecidedSegment& d) { counts.add(d.keep(), d.labels()); });
//   s.push(batch, kept);  // kept: zero or more new batches of kept events
//   s.finish(kept);

#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <optional>
#include <span>
#include <vector>

#include "evpipe/core/event.hpp"
#include "evpipe/denoise/filter.hpp"

namespace evpipe::denoise {

/// Consecutive events of one input batch decided together: batch.events[first, first + count) with
/// decisions.keep[at, at + count) (and decisions.score, when the filter has a score), where `decisions` holds every
/// decision of the current FilteredStream::push()/finish(). Valid during the observer call only.
struct DecidedSegment {
  const EventBatch& batch;
  std::size_t first;
  std::size_t count;
  const Decisions& decisions;
  std::size_t at;

  [[nodiscard]] EventSpan events() const noexcept { return EventSpan(batch.events).subspan(first, count); }
  /// Empty when the batch is unlabelled.
  [[nodiscard]] std::span<const Label> labels() const noexcept {
    return batch.labelled() ? std::span<const Label>(batch.labels).subspan(first, count) : std::span<const Label>{};
  }
  [[nodiscard]] std::span<const std::uint8_t> keep() const noexcept {
    return std::span<const std::uint8_t>(decisions.keep).subspan(at, count);
  }
  /// Empty when the filter has no score.
  [[nodiscard]] std::span<const float> score() const noexcept {
    return decisions.score.empty() ? std::span<const float>{}
                                   : std::span<const float>(decisions.score).subspan(at, count);
  }
};

class FilteredStream {
 public:
  using Observer = std::function<void(const DecidedSegment&)>;

  /// `filter` must outlive this object. `on_decided`, if set, sees every decided event once, in input order.
  explicit FilteredStream(Filter& filter, Observer on_decided = {});

  /// Feeds one batch (held shared until all its events are decided; never null) and appends to `out` the kept
  /// events whose decisions became final (from this batch or earlier ones): zero or one batch, or two when `in`
  /// starts after a clock discontinuity while events from before it were pending. At a discontinuity the filter
  /// first decides everything pending as at the end of a stream and restarts, so that no neighbourhood spans the
  /// jump; the first output batch after it carries the flag. Throws std::logic_error, naming the filter, when the
  /// filter returns more decisions than events pending or a score count that does not match.
  void push(EventBatchPtr in, std::vector<EventBatch>& out);
  /// End of the stream: the kept events of everything still pending. Throws std::logic_error as push() does, and
  /// when the filter leaves events undecided.
  void finish(std::vector<EventBatch>& out);

  [[nodiscard]] std::uint64_t events_in() const noexcept { return events_in_; }
  [[nodiscard]] std::uint64_t events_decided() const noexcept { return events_in_ - pending_events_; }
  [[nodiscard]] std::uint64_t events_kept() const noexcept { return events_kept_; }
  /// Events waiting for a decision (bounded by the filter's look-ahead).
  [[nodiscard]] std::size_t pending() const noexcept { return pending_events_; }
  /// The time below which no kept event can come out any more: the oldest pending event's time, or one past the
  /// newest event pushed when nothing is pending (nullopt before the first event). A slicer's watermark.
  [[nodiscard]] std::optional<std::int64_t> decided_until_us() const noexcept;

 private:
  void collect(std::vector<EventBatch>& out);
  void collect_all(std::vector<EventBatch>& out, const char* where);

  Filter& filter_;
  Observer on_decided_;
  std::deque<EventBatchPtr> pending_;  // batches holding undecided events, oldest first
  std::size_t front_decided_ = 0;      // events of pending_.front() already decided
  std::size_t pending_events_ = 0;
  Decisions decisions_;     // of the current push()/finish()
  std::size_t taken_ = 0;   // decisions_ already matched with their events
  bool flag_next_ = false;  // the next non-empty output batch starts after a discontinuity
  std::uint64_t events_in_ = 0;
  std::uint64_t events_kept_ = 0;
  std::optional<std::int64_t> newest_in_t_us_;  // newest event pushed
};

}  // namespace evpipe::denoise
