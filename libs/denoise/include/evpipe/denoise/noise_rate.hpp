#pragma once
// Adaptive density threshold (the paper's future work): estimate the background-activity rate λ (Hz per
// pixel) from the stream itself and choose ρ_TH from it.
//
// Model: noise is an independent Poisson process of rate λ per pixel. The ball of a noise event then holds
// Poisson(E·λ) other noise events, E being the ball's exposure in pixel·seconds (sum over the sites inside
// the sensor of the time span the ball covers there; mode dependent, see make_exposure_model). A noise event
// fails the density test iff Poisson(E·λ) ≤ ρ_TH − 2, so over a period of T seconds on K pixels the expected
// number of failing events is  F(λ) = K·T·λ·P(Poisson(E·λ) ≤ ρ_TH − 2)  (signal events, which almost always
// pass, are neglected). λ̂ solves F(λ) = observed failures (smallest root, by fixed-point iteration
// λ ← failures / (K·T·P(...)), which increases monotonically to it); when no root exists (more failures
// than any λ explains) λ̂ is the maximiser of F. The next period's threshold is the smallest ρ_TH with
// P(Poisson(E_interior·λ̂) ≥ ρ_TH − 1) ≤ target_noise_pass.

#include <cstdint>
#include <utility>
#include <vector>

#include "evpipe/core/event.hpp"
#include "evpipe/denoise/curvature_options.hpp"
#include "evpipe/denoise/sphere.hpp"

namespace evpipe::denoise {

/// Exposure of the ball per pixel class: (exposure in pixel·seconds, share of the sensor's pixels).
struct ExposureModel {
  std::vector<std::pair<double, double>> classes;
  double interior_s = 0.0;  ///< exposure of a pixel whose whole ball lies on the sensor (the largest)
  double pixels = 0.0;      ///< K
};

/// Per site of half-width a (µs): stream 2a; causal a; frames of length T the mean over the event's
/// position in its frame, 2a − a²/T for a ≤ T, else T.
ExposureModel make_exposure_model(const Sphere& sphere, CurvatureMode mode, std::int64_t window_us,
                                  const SensorGeometry& geometry);

/// P(X ≤ k) and P(X ≥ k) for X ~ Poisson(mu).
double poisson_cdf(std::int64_t k, double mu) noexcept;
double poisson_sf(std::int64_t k, double mu) noexcept;

/// Expected share of pure-noise events (rate λ) that fail ρ ≥ threshold.
double noise_fail_share(const ExposureModel& model, double rate_hz, std::int64_t threshold) noexcept;
/// λ̂ from `failed` events over `seconds` (see above). Returns `fallback` when the threshold carries no
/// information (threshold ≤ 1: nothing can fail).
double estimate_noise_rate(double failed, double seconds, const ExposureModel& model, std::int64_t threshold,
                           double fallback) noexcept;
/// Smallest threshold ≥ 2 with P(Poisson(interior·λ) ≥ threshold − 1) ≤ target.
std::int64_t threshold_for_rate(double rate_hz, const ExposureModel& model, double target) noexcept;

/// Per absolute period [k·P, (k+1)·P): counts density failures, and at each period boundary updates the
/// rate estimate and the threshold for the next period, at most adaptive_max_threshold when that is set (so
/// is the first period's, density_threshold). Call threshold() with non-decreasing periods.
class NoiseRateEstimator {
 public:
  NoiseRateEstimator(ExposureModel model, const CurvatureOptions& options);
  void reset() noexcept;
  /// The stream's first event: its period is observed from t_us on (not from the period's start).
  void start(std::int64_t t_us) noexcept;
  /// The threshold in force for an event at t_us (advancing the period when t_us starts a new one).
  std::int64_t threshold(std::int64_t t_us) noexcept {
    if (!enabled_) return threshold_;
    return adaptive_threshold(t_us);
  }
  void count_failures(std::int64_t n) noexcept { failed_ += static_cast<double>(n); }
  [[nodiscard]] double rate_hz() const noexcept { return rate_hz_; }
  [[nodiscard]] std::int64_t current_threshold() const noexcept { return threshold_; }
  [[nodiscard]] std::int64_t periods() const noexcept { return periods_; }

 private:
  std::int64_t adaptive_threshold(std::int64_t t_us) noexcept;

  ExposureModel model_;
  bool enabled_;
  std::int64_t period_us_;
  double target_;
  std::int64_t max_threshold_;  // adaptive_max_threshold (no limit: int64 max)
  std::int64_t initial_threshold_;
  std::int64_t threshold_;
  double rate_hz_ = 0.0;
  bool started_ = false;
  std::int64_t period_ = 0;
  std::int64_t observed_from_us_ = 0;
  double failed_ = 0.0;
  std::int64_t periods_ = 0;
};

}  // namespace evpipe::denoise
