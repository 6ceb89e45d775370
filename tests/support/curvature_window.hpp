#pragma once
// A window of events through the paper's curvature filter as evpipe runs it (paper parameters, singular fits
// kept): what the pose stage receives. For the tracker's tests and benchmark.

#include <utility>
#include <vector>

#include "evpipe/core/event.hpp"
#include "evpipe/denoise/registry.hpp"

namespace evpipe::testing {

inline std::vector<Event> curvature_filtered(const std::vector<Event>& events, const SensorGeometry& geometry) {
  auto filter = denoise::make_filter_chain("curvature", {{"singular", "keep"}}, geometry);
  denoise::Decisions decided, rest;
  filter->push(events, decided);
  filter->finish(rest);
  decided.keep.insert(decided.keep.end(), rest.keep.begin(), rest.keep.end());
  std::vector<Event> kept;
  for (std::size_t i = 0; i < events.size() && i < decided.keep.size(); ++i) {
    if (decided.keep[i]) kept.push_back(events[i]);
  }
  return kept;
}

}  // namespace evpipe::testing
