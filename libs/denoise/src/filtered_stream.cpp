#include "evpipe/denoise/filtered_stream.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <utility>

namespace evpipe::denoise {

FilteredStream::FilteredStream(Filter& filter, Observer on_decided)
    : filter_(filter), on_decided_(std::move(on_decided)) {}

// Matches the decisions not yet taken with the oldest pending events, run by run within each held batch; the kept
// events become one output batch.
void FilteredStream::collect(std::vector<EventBatch>& out) {
  const std::size_t n = decisions_.size() - taken_;
  if (n > pending_events_) {
    throw std::logic_error(
        fmt::format("filter '{}' returned {} decisions for {} undecided events", filter_.name(), n, pending_events_));
  }
  // Earlier calls were checked, so the score count of this call starts at taken_.
  if (filter_.has_score() && decisions_.score.size() != decisions_.size()) {
    throw std::logic_error(fmt::format("filter '{}' returned {} scores for {} decisions", filter_.name(),
                                       decisions_.score.size() - taken_, n));
  }
  EventBatch kept;
  // Sized exactly: a block's kept events at 12 Mev/s are ~280 000 (4.5 MB), and growing by doubling would leave
  // up to as much again unused while the batch travels down the pipeline.
  std::size_t keep_count = 0;
  for (std::size_t i = taken_; i < decisions_.size(); ++i) keep_count += decisions_.keep[i] != 0 ? 1U : 0U;
  kept.events.reserve(keep_count);
  while (taken_ < decisions_.size()) {
    const EventBatch& b = *pending_.front();
    const std::size_t count = std::min(decisions_.size() - taken_, b.size() - front_decided_);
    if (on_decided_) {
      on_decided_(DecidedSegment{b, front_decided_, count, decisions_, taken_});
    }
    const std::size_t kept_before = kept.events.size();
    for (std::size_t i = 0; i < count; ++i) {
      if (decisions_.keep[taken_ + i] == 0) continue;
      kept.events.push_back(b.events[front_decided_ + i]);
      if (b.labelled()) kept.labels.push_back(b.labels[front_decided_ + i]);
    }
    if (kept.events.size() > kept_before) kept.read_at = b.read_at;  // the input batch holding the newest kept event
    taken_ += count;
    front_decided_ += count;
    pending_events_ -= count;
    if (front_decided_ == b.size()) {
      pending_.pop_front();
      front_decided_ = 0;
    }
  }
  if (kept.labels.size() != kept.events.size()) {
    kept.labels.clear();  // labelled and unlabelled input mixed: a batch is labelled whole or not at all
  }
  events_kept_ += kept.size();
  if (!kept.empty()) {
    kept.discontinuity_before = std::exchange(flag_next_, false);
    out.push_back(std::move(kept));
  }
}

// After the filter's finish(), which must decide everything pending (end of the stream, or a discontinuity).
void FilteredStream::collect_all(std::vector<EventBatch>& out, const char* where) {
  collect(out);
  if (pending_events_ != 0) {
    throw std::logic_error(
        fmt::format("filter '{}' left {} events undecided after finish(){}", filter_.name(), pending_events_, where));
  }
}

void FilteredStream::push(EventBatchPtr in, std::vector<EventBatch>& out) {
  if (!in) {
    throw std::invalid_argument("FilteredStream::push: null batch");
  }
  decisions_.clear();
  taken_ = 0;
  if (in->discontinuity_before && events_in_ > 0) {
    filter_.discontinuity(decisions_);
    collect_all(out, " at a discontinuity");
    flag_next_ = true;
  }
  if (in->empty()) {
    return;
  }
  events_in_ += in->size();
  pending_events_ += in->size();
  newest_in_t_us_ = in->events.back().t_us;
  const EventSpan events = in->span();
  pending_.push_back(std::move(in));
  filter_.push(events, decisions_);
  collect(out);
}

std::optional<std::int64_t> FilteredStream::decided_until_us() const noexcept {
  if (pending_events_ > 0 && !pending_.empty()) return pending_.front()->events[front_decided_].t_us;
  if (!newest_in_t_us_ || *newest_in_t_us_ == std::numeric_limits<std::int64_t>::max()) return newest_in_t_us_;
  return *newest_in_t_us_ + 1;
}

void FilteredStream::finish(std::vector<EventBatch>& out) {
  decisions_.clear();
  taken_ = 0;
  filter_.finish(decisions_);
  collect_all(out, "");
}

}  // namespace evpipe::denoise
