#pragma once
// BAF, the background-activity filter (Delbruck 2008) as dv-processing 2.0.4 implements it
// (dv::noise::BackgroundActivityNoiseFilter), the version the paper compares with (2 000 µs):
// an event is kept when one of its 8 neighbours (not its own pixel; polarity ignored) fired less than
// `duration_us` before it. Every event then stamps its own pixel, kept or not.

#include <cstdint>
#include <vector>

#include "evpipe/core/event.hpp"
#include "evpipe/denoise/registry.hpp"

namespace evpipe::denoise {

struct BafOptions {
  std::int64_t duration_us = 2000;
  /// dv-processing starts its time surface at 0, so every event with t_us < duration passes at the start of a
  /// stream that begins near 0 (the paper's Table 1 row shows this). `zero_init = false` starts at "never".
  bool zero_init = true;
};

class Baf {
 public:
  Baf(const SensorGeometry& geometry, BafOptions options);
  [[nodiscard]] bool accept(const Event& e) noexcept;
  /// Minus the age in µs of the most recent neighbour event (higher = more signal-like).
  [[nodiscard]] float last_score() const noexcept { return score_; }
  void reset() noexcept;

 private:
  SensorGeometry geometry_;
  BafOptions options_;
  std::int64_t stride_;
  std::vector<std::int64_t> last_t_us_;  // padded by one pixel on every side; the border stays "never"
  float score_ = 0.0F;
};

FilterSpec baf_spec();

}  // namespace evpipe::denoise
