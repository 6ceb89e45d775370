#pragma once
// A filter applied to a stream of batches: holds the events whose decision is still pending (look-ahead
// filters decide late) and hands out the kept ones, unchanged and in input order, as new batches. Used by
// evdenoise and by evpipe's denoise stage, so both keep exactly the same events.

#include <cstdint>
#include <deque>

#include "evpipe/core/event.hpp"
#include "evpipe/denoise/filter.hpp"

namespace evpipe::denoise {

class FilteredStream {
 public:
  /// `filter` must outlive this object.
  explicit FilteredStream(Filter& filter) : filter_(filter) {}

  /// Feeds one batch and appends to `out` the kept events whose decisions became final (from this batch or
  /// earlier ones): zero or one batch, or two when `in` starts after a clock discontinuity while events from before
  /// it were pending. At a discontinuity the filter first decides everything pending as at the end of a stream and
  /// restarts, so that no neighbourhood spans the jump; the first output batch after it carries the flag.
  void push(const EventBatch& in, std::vector<EventBatch>& out);
  /// End of the stream: the kept events of everything still pending.
  void finish(std::vector<EventBatch>& out);

  [[nodiscard]] std::uint64_t events_in() const noexcept { return events_in_; }
  [[nodiscard]] std::uint64_t events_decided() const noexcept { return events_decided_; }
  [[nodiscard]] std::uint64_t events_kept() const noexcept { return events_kept_; }
  /// Events waiting for a decision (bounded by the filter's look-ahead).
  [[nodiscard]] std::size_t pending() const noexcept { return pending_events_.size(); }
  /// The decisions made during the last push()/finish(), in input order (keep and, if the filter has one,
  /// score), and the labels of those events when the input is labelled (else empty): for metrics.
  [[nodiscard]] const Decisions& last_decisions() const noexcept { return decisions_; }
  [[nodiscard]] const std::vector<Label>& last_labels() const noexcept { return decided_labels_; }

 private:
  void collect(std::vector<EventBatch>& out);

  Filter& filter_;
  std::deque<Event> pending_events_;
  std::deque<Label> pending_labels_;
  Decisions decisions_;
  std::vector<Label> decided_labels_;
  std::size_t taken_ = 0;   // decisions_ already applied to the pending queue
  bool flag_next_ = false;  // the next non-empty output batch starts after a discontinuity
  std::uint64_t events_in_ = 0;
  std::uint64_t events_decided_ = 0;
  std::uint64_t events_kept_ = 0;
};

}  // namespace evpipe::denoise
