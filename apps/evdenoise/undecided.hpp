#pragma once
// The events a filter has been given but not yet decided, in input order, so that each decision can be matched
// with its event (filters that look ahead decide later: Filter::pending()). Holds the reader's batches, shared
// and never copied; the filter's window bounds how many are held.

#include <algorithm>
#include <cstddef>
#include <deque>
#include <stdexcept>
#include <utility>

#include "evpipe/core/event.hpp"

namespace evdenoise {

class Undecided {
 public:
  void push(evpipe::EventBatchPtr batch) {
    if (batch->empty()) return;
    size_ += batch->size();
    batches_.push_back(std::move(batch));
  }
  [[nodiscard]] std::size_t size() const noexcept { return size_; }

  /// Hands the oldest `n` events to `segment(batch, first, count, decision_index)` as runs within one batch
  /// and forgets them. Throws std::logic_error when fewer than `n` are held.
  template <class Segment>
  void take(std::size_t n, Segment&& segment) {
    if (n > size_) throw std::logic_error("more decisions than undecided events");
    std::size_t done = 0;
    while (done < n) {
      const evpipe::EventBatch& b = *batches_.front();
      const std::size_t count = std::min(n - done, b.size() - offset_);
      segment(b, offset_, count, done);
      done += count;
      offset_ += count;
      size_ -= count;
      if (offset_ == b.size()) {
        batches_.pop_front();
        offset_ = 0;
      }
    }
  }

 private:
  std::deque<evpipe::EventBatchPtr> batches_;
  std::size_t offset_ = 0;  // events of batches_.front() already decided
  std::size_t size_ = 0;
};

}  // namespace evdenoise
