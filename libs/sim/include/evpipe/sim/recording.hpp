#pragma once
// Putting a simulated recording together: signal and noise merged with their labels, and the event frame evsim
// previews (evsim --png).

#include <cstdint>
#include <vector>

#include "evpipe/core/event.hpp"

namespace evpipe::sim {

struct LabelledEvents {
  std::vector<Event> events;
  std::vector<Label> labels;  ///< one per event
};

/// Merges two time-ordered streams into one, labelling signal 1 and noise 0. At equal timestamps signal comes
/// first, so the result is deterministic.
LabelledEvents merge_labelled(EventSpan signal, EventSpan noise);

/// Per-pixel polarity of the last event in [t0_us, t1_us): +1 ON, -1 OFF, 0 no event; row-major, width x height.
/// Events outside the geometry are ignored.
std::vector<std::int8_t> event_frame(EventSpan events, const SensorGeometry& geometry, std::int64_t t0_us,
                                     std::int64_t t1_us);

}  // namespace evpipe::sim
