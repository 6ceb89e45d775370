#pragma once
// Background-activity noise: an independent Poisson process per pixel (section 2.2 of the paper: thermal
// and junction-leakage noise), plus hot pixels firing at their own higher rate.

#include <cstdint>
#include <random>
#include <vector>

#include "evpipe/core/event.hpp"

namespace evpipe::sim {

struct NoiseOptions {
  double rate_hz_per_pixel = 1.0;  ///< shot-noise BA rate λ per pixel (both polarities, split by on_share)
  double on_share = 0.5;           ///< share of the shot-noise events with ON polarity
  /// Leak-event rate per pixel: junction leakage slowly drifts the photoreceptor's reset level, so leak
  /// events are ON only (Nozaki & Delbruck 2017). Independent of the shot noise; 0 = none.
  double leak_rate_hz_per_pixel = 0.0;
  int hot_pixels = 0;          ///< number of hot pixels (chosen uniformly at random)
  double hot_rate_hz = 200.0;  ///< firing rate of each hot pixel
};

/// Noise events in [t0_us, t1_us) over the whole sensor, time-ordered. Deterministic for a given rng state.
/// A hot pixel's events are noise too (label noise).
std::vector<Event> background_activity(const SensorGeometry& geometry, std::int64_t t0_us, std::int64_t t1_us,
                                       const NoiseOptions& options, std::mt19937_64& rng);

/// The paper's pure-noise protocol (section 4.1): exactly n events uniform over the sensor within
/// [t0_us, t0_us + span_us), with increasing timestamps.
std::vector<Event> uniform_noise(const SensorGeometry& geometry, std::int64_t t0_us, std::int64_t span_us,
                                 std::size_t n, std::mt19937_64& rng);

}  // namespace evpipe::sim
