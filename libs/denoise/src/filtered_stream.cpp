#include "evpipe/denoise/filtered_stream.hpp"

#include <utility>

namespace evpipe::denoise {

// Applies the new decisions to the front of the pending queue; the kept events become one output batch.
void FilteredStream::collect(std::vector<EventBatch>& out) {
  EventBatch batch;
  for (; taken_ < decisions_.size(); ++taken_) {
    const Event e = pending_events_.front();
    pending_events_.pop_front();
    const bool labelled = !pending_labels_.empty();
    const Label label = labelled ? pending_labels_.front() : Label::noise;
    if (labelled) {
      pending_labels_.pop_front();
      decided_labels_.push_back(label);
    }
    if (decisions_.keep[taken_] != 0) {
      batch.events.push_back(e);
      if (labelled) {
        batch.labels.push_back(label);
      }
    }
  }
  events_decided_ = events_in_ - pending_events_.size();
  events_kept_ += batch.events.size();
  if (!batch.events.empty()) {
    batch.discontinuity_before = std::exchange(flag_next_, false);
    out.push_back(std::move(batch));
  }
}

void FilteredStream::push(const EventBatch& in, std::vector<EventBatch>& out) {
  decisions_.clear();
  decided_labels_.clear();
  taken_ = 0;
  if (in.discontinuity_before && events_in_ > 0) {
    filter_.discontinuity(decisions_);
    collect(out);
    flag_next_ = true;
  }
  if (in.empty()) {
    return;
  }
  pending_events_.insert(pending_events_.end(), in.events.begin(), in.events.end());
  if (in.labelled()) {
    pending_labels_.insert(pending_labels_.end(), in.labels.begin(), in.labels.end());
  }
  events_in_ += in.size();
  filter_.push(in.span(), decisions_);
  collect(out);
}

void FilteredStream::finish(std::vector<EventBatch>& out) {
  decisions_.clear();
  decided_labels_.clear();
  taken_ = 0;
  filter_.finish(decisions_);
  collect(out);
}

}  // namespace evpipe::denoise
