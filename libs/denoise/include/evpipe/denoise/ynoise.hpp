#pragma once
// YNoise (Feng et al., "Event density based denoising method for dynamic vision sensor", Appl. Sci. 2020) as
// CUKE (cuke-emlb yang_noise.hpp) implements it, the version E-MLB evaluates: the density of an event is the
// number of pixels of the L×L window centred on it (clipped to the sensor, its own pixel INCLUDED) whose last
// event has the same polarity and came at most `duration_us` before (t − T ≤ duration, inclusive); the event is
// kept when density ≥ threshold. Every event then stamps its pixel (time and polarity), kept or not.
// Feng's second (hot-pixel) step is not part of it (use the `hotpixel` filter in front).
//
// Defaults are the paper's: 10 000 µs, L = 3, threshold 1 (CUKE's DV module uses threshold 2).
// Start-up: CUKE starts its maps at t = 0 with polarity OFF, so an OFF event with t ≤ duration is supported by
// every untouched pixel of its window and passes (init = zero, the default, to match the reference);
// init = never starts every pixel without history.

#include <cstdint>
#include <vector>

#include "evpipe/core/event.hpp"
#include "evpipe/denoise/registry.hpp"

namespace evpipe::denoise {

struct YnoiseOptions {
  std::int64_t duration_us = 10'000;
  int window = 3;  ///< L, odd; radius (L − 1) / 2
  int threshold = 1;
  bool zero_init = true;
};

class Ynoise {
 public:
  Ynoise(const SensorGeometry& geometry, YnoiseOptions options);
  [[nodiscard]] bool accept(const Event& e) noexcept;
  /// The density (higher = more signal-like).
  [[nodiscard]] float last_score() const noexcept { return score_; }
  void reset() noexcept;

 private:
  SensorGeometry geometry_;
  YnoiseOptions options_;
  int radius_;
  std::int64_t stride_;
  // Last event per pixel packed as t·2 + polarity (polarity test and time test on one load); padded by the
  // radius on every side with "never" so that the window needs no clipping.
  std::vector<std::int64_t> last_;
  float score_ = 0.0F;
};

FilterSpec ynoise_spec();

}  // namespace evpipe::denoise
