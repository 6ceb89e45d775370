#pragma once
// Random thinning: keeps each event with a fixed probability, independently of everything else. Not a
// denoiser: the structure-neutral reference for metrics that depend on how many events are kept. ESR, for
// instance, is computed on chunks of a fixed 30 000 output events, so any filter that keeps fewer events makes
// each chunk span more time; comparing a filter with random thinning to the same kept share separates what the
// filter does to the structure from that effect (docs/results-denoise.md).

#include <cstdint>

#include "evpipe/core/event.hpp"
#include "evpipe/denoise/registry.hpp"

namespace evpipe::denoise {

struct RandomThinningOptions {
  double keep_fraction = 0.5;
  std::uint64_t seed = 1;
};

class RandomThinning {
 public:
  explicit RandomThinning(RandomThinningOptions options) noexcept : options_(options) { reset(); }
  /// The decision for an event depends only on the seed and the event's position in the stream, so it is the same
  /// whatever the pushes are.
  [[nodiscard]] bool accept(const Event& e) noexcept;
  void reset() noexcept { state_ = options_.seed; }

 private:
  RandomThinningOptions options_;
  std::uint64_t state_ = 0;
};

FilterSpec random_spec();

}  // namespace evpipe::denoise
