#include "evpipe/sim/recording.hpp"

#include <algorithm>

namespace evpipe::sim {

LabelledEvents merge_labelled(EventSpan signal, EventSpan noise) {
  LabelledEvents out;
  out.events.reserve(signal.size() + noise.size());
  out.labels.reserve(signal.size() + noise.size());
  std::size_t i = 0, j = 0;
  while (i < signal.size() || j < noise.size()) {
    if (j >= noise.size() || (i < signal.size() && signal[i].t_us <= noise[j].t_us)) {
      out.events.push_back(signal[i++]);
      out.labels.push_back(Label::signal);
    } else {
      out.events.push_back(noise[j++]);
      out.labels.push_back(Label::noise);
    }
  }
  return out;
}

std::vector<std::int8_t> event_frame(EventSpan events, const SensorGeometry& g, std::int64_t t0_us,
                                     std::int64_t t1_us) {
  std::vector<std::int8_t> frame(g.pixels(), 0);
  // Events are time-ordered: find the window by binary search, then the last event per pixel wins.
  const auto first =
      std::lower_bound(events.begin(), events.end(), t0_us, [](const Event& e, std::int64_t t) { return e.t_us < t; });
  for (auto it = first; it != events.end() && it->t_us < t1_us; ++it) {
    if (!g.contains(it->x, it->y)) continue;
    frame[static_cast<std::size_t>(it->y) * static_cast<std::size_t>(g.width) + it->x] = it->polarity ? 1 : -1;
  }
  return frame;
}

}  // namespace evpipe::sim
