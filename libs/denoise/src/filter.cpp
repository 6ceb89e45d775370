#include "evpipe/denoise/filter.hpp"

#include <algorithm>

namespace evpipe::denoise {

Decisions run_filter(Filter& filter, EventSpan events, std::size_t chunk_events) {
  Decisions out;
  out.keep.reserve(events.size());
  if (filter.has_score()) {
    out.score.reserve(events.size());
  }
  const std::size_t step = chunk_events == 0 ? std::max<std::size_t>(events.size(), 1) : chunk_events;
  for (std::size_t i = 0; i < events.size(); i += step) {
    filter.push(events.subspan(i, std::min(step, events.size() - i)), out);
  }
  filter.finish(out);
  return out;
}

std::size_t count_kept(const Decisions& decisions) noexcept {
  return static_cast<std::size_t>(std::count(decisions.keep.begin(), decisions.keep.end(), std::uint8_t{1}));
}

}  // namespace evpipe::denoise
