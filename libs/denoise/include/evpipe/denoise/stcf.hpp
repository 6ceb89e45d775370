#pragma once
// STCF, the spatio-temporal correlation filter (Guo & Delbruck, "Low cost and latency event camera background
// activity denoising", IEEE TPAMI 2023) as jAER's SpatioTemporalCorrelationFilter implements it: an event is kept
// when at least k pixels of the (2r+1)² block around it (its own pixel excluded when filter_hot_pixels) had an
// event less than tau_us before (strict <), of the same polarity when polarity_match. The first event at a pixel
// only stamps it and is dropped (let_first_event_through = false). Every event then stamps its pixel.
//
// Borders: the block is clipped to the sensor on every side. jAER's clipping shrinks the block by one column /
// row at the right and bottom borders (x1 = x >= sx − d ? sx − d : x + d); that quirk is not reproduced.
// Defaults are jAER's: k = 2, tau 25 ms, polarity match, own pixel excluded, r = 1 (sigmaDistPixels).

#include <cstdint>
#include <vector>

#include "evpipe/core/event.hpp"
#include "evpipe/denoise/registry.hpp"

namespace evpipe::denoise {

struct StcfOptions {
  int k = 2;  ///< numMustBeCorrelated
  std::int64_t tau_us = 25'000;
  bool polarity_match = true;
  bool filter_hot_pixels = true;  ///< own pixel does not support itself
  bool let_first_event_through = false;
  int radius = 1;
};

class Stcf {
 public:
  Stcf(const SensorGeometry& geometry, StcfOptions options);
  [[nodiscard]] bool accept(const Event& e) noexcept;
  /// Number of correlated pixels; −1 for the first event at a pixel (no history).
  [[nodiscard]] float last_score() const noexcept { return score_; }
  void reset() noexcept;

 private:
  SensorGeometry geometry_;
  StcfOptions options_;
  std::int64_t stride_;
  // Last event per pixel packed as t·2 + polarity, padded by the radius with "never".
  std::vector<std::int64_t> last_;
  float score_ = 0.0F;
};

FilterSpec stcf_spec();

}  // namespace evpipe::denoise
