#include "evpipe/core/stream_stats.hpp"

#include <algorithm>

namespace evpipe {

void StreamStats::add(EventSpan events) noexcept {
  for (const auto& e : events) {
    if (!first_) first_ = e.t_us;
    last_ = std::max(last_.value_or(e.t_us), e.t_us);
    ++events_;
    on_ += e.polarity ? 1U : 0U;
    // Bins are aligned to the first event; a backward jump (kept out-of-order events, clock reset) starts a
    // new bin at that event rather than corrupting the current one.
    if (!bin_start_ || e.t_us < *bin_start_ || e.t_us >= *bin_start_ + bin_us_) {
      peak_count_ = std::max(peak_count_, bin_count_);
      if (bin_start_ && e.t_us >= *bin_start_)
        bin_start_ = *bin_start_ + (e.t_us - *bin_start_) / bin_us_ * bin_us_;
      else
        bin_start_ = e.t_us;
      bin_count_ = 0;
    }
    ++bin_count_;
  }
}

std::int64_t StreamStats::duration_us() const noexcept {
  return (first_ && last_) ? *last_ - *first_ : 0;
}

double StreamStats::mean_rate_hz() const noexcept {
  const auto d = duration_us();
  return d > 0 ? static_cast<double>(events_) * 1e6 / static_cast<double>(d) : 0.0;
}

double StreamStats::peak_rate_hz() const noexcept {
  const auto peak = std::max(peak_count_, bin_count_);
  return static_cast<double>(peak) * 1e6 / static_cast<double>(bin_us_);
}

}  // namespace evpipe
