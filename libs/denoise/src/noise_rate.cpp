#include "evpipe/denoise/noise_rate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <map>
#include <vector>

namespace evpipe::denoise {

namespace {

double site_exposure_us(std::int64_t half_width_us, CurvatureMode mode, std::int64_t window_us) {
  const auto a = static_cast<double>(half_width_us);
  const auto w = static_cast<double>(window_us);
  switch (mode) {
    case CurvatureMode::stream:
      return 2.0 * a;
    case CurvatureMode::causal:
      return a;
    case CurvatureMode::frames:
      return a <= w ? 2.0 * a - a * a / w : w;
  }
  return 0.0;
}

std::int64_t floor_div(std::int64_t a, std::int64_t b) noexcept {
  const std::int64_t q = a / b;
  return (a % b != 0 && (a < 0) != (b < 0)) ? q - 1 : q;
}

}  // namespace

ExposureModel make_exposure_model(const Sphere& sphere, CurvatureMode mode, std::int64_t window_us,
                                  const SensorGeometry& geometry) {
  ExposureModel m;
  std::map<double, double> classes;
  double interior = 0.0;
  for (const auto& s : sphere.sites()) {
    interior += site_exposure_us(s.half_width_us, mode, window_us);
  }
  // A pixel at least `reach` from every border sees every site (the interior class): counted in bulk, so that only
  // the border band is walked site by site (the whole sensor took minutes at a large declared size, issue 17).
  int reach = 0;
  std::vector<double> site_us;
  for (const auto& s : sphere.sites()) {
    reach = std::max({reach, std::abs(s.dx), std::abs(s.dy)});
    site_us.push_back(site_exposure_us(s.half_width_us, mode, window_us));
  }
  const auto inside = [&](int v, int n) { return v >= reach && v < n - reach; };
  double interior_pixels = 0.0;
  for (int y = 0; y < geometry.height; ++y) {
    const bool row_inside = inside(y, geometry.height);
    for (int x = 0; x < geometry.width; ++x) {
      if (row_inside && inside(x, geometry.width)) {
        const int last = geometry.width - reach - 1;  // jump to the end of the interior run of this row
        interior_pixels += static_cast<double>(last - x + 1);
        x = last;
        continue;
      }
      double e = 0.0;
      for (std::size_t k = 0; k < site_us.size(); ++k) {
        const auto& s = sphere.sites()[k];
        if (geometry.contains(x + s.dx, y + s.dy)) e += site_us[k];
      }
      classes[e * 1e-6] += 1.0;
    }
  }
  if (interior_pixels > 0.0) classes[interior * 1e-6] += interior_pixels;
  m.pixels = static_cast<double>(geometry.pixels());
  for (const auto& [e, n] : classes) m.classes.emplace_back(e, n / m.pixels);
  m.interior_s = interior * 1e-6;
  return m;
}

double poisson_cdf(std::int64_t k, double mu) noexcept {
  if (k < 0) return 0.0;
  if (mu <= 0.0) return 1.0;
  // Terms in log space so that large mu does not underflow exp(−mu).
  double sum = 0.0;
  const double log_mu = std::log(mu);
  for (std::int64_t i = 0; i <= k; ++i) {
    const auto di = static_cast<double>(i);
    sum += std::exp(-mu + di * log_mu - std::lgamma(di + 1.0));
    if (di > mu && sum >= 1.0) break;
  }
  return std::min(1.0, sum);
}

double poisson_sf(std::int64_t k, double mu) noexcept {
  if (k <= 0) return 1.0;
  return std::max(0.0, 1.0 - poisson_cdf(k - 1, mu));
}

double noise_fail_share(const ExposureModel& model, double rate_hz, std::int64_t threshold) noexcept {
  double s = 0.0;
  for (const auto& [e, w] : model.classes) s += w * poisson_cdf(threshold - 2, e * rate_hz);
  return s;
}

double estimate_noise_rate(double failed, double seconds, const ExposureModel& model, std::int64_t threshold,
                           double fallback) noexcept {
  if (threshold <= 1 || seconds <= 0.0 || model.pixels <= 0.0 || model.interior_s <= 0.0) return fallback;
  const double y = failed / (model.pixels * seconds);  // failures per pixel·second
  if (y <= 0.0) return 0.0;
  // Maximiser of h(λ) = λ·share(λ): coarse scan over μ = interior·λ, then golden-section refinement.
  const auto h = [&](double lam) { return lam * noise_fail_share(model, lam, threshold); };
  const double mu_top = 4.0 * (static_cast<double>(threshold) + 5.0);
  double best_lam = 0.0;
  double best_h = 0.0;
  constexpr int kSteps = 200;
  for (int i = 1; i <= kSteps; ++i) {
    const double lam = mu_top * i / kSteps / model.interior_s;
    const double v = h(lam);
    if (v > best_h) {
      best_h = v;
      best_lam = lam;
    }
  }
  double lo = std::max(0.0, best_lam - mu_top / kSteps / model.interior_s);
  double hi = best_lam + mu_top / kSteps / model.interior_s;
  const double g = (std::sqrt(5.0) - 1.0) / 2.0;
  for (int i = 0; i < 60; ++i) {
    const double a = hi - g * (hi - lo);
    const double b = lo + g * (hi - lo);
    if (h(a) < h(b)) {
      lo = a;
    } else {
      hi = b;
    }
  }
  const double lam_max = (lo + hi) / 2.0;
  if (y >= h(lam_max)) return lam_max;
  // h increases on [0, lam_max]: bisection finds the smallest root (the limit of the fixed-point iteration
  // λ ← y / share(λ) started at y, but without its slow convergence near the maximum).
  double a = 0.0;
  double b = lam_max;
  for (int i = 0; i < 200 && b - a > 1e-12 * b; ++i) {
    const double m = (a + b) / 2.0;
    if (h(m) < y) {
      a = m;
    } else {
      b = m;
    }
  }
  return (a + b) / 2.0;
}

std::int64_t threshold_for_rate(double rate_hz, const ExposureModel& model, double target) noexcept {
  const double mu = model.interior_s * std::max(0.0, rate_hz);
  std::int64_t th = 2;
  while (th < 100'000 && poisson_sf(th - 1, mu) > target) ++th;
  return th;
}

NoiseRateEstimator::NoiseRateEstimator(ExposureModel model, const CurvatureOptions& options)
    : model_(std::move(model)),
      enabled_(options.adaptive),
      period_us_(options.adaptive_period_us),
      target_(options.target_noise_pass),
      max_threshold_(options.adaptive && options.adaptive_max_threshold > 0 ? options.adaptive_max_threshold
                                                                            : std::numeric_limits<std::int64_t>::max()),
      initial_threshold_(std::min(options.density_threshold, max_threshold_)),
      threshold_(initial_threshold_) {}

void NoiseRateEstimator::reset() noexcept {
  threshold_ = initial_threshold_;
  rate_hz_ = 0.0;
  started_ = false;
  failed_ = 0.0;
  periods_ = 0;
}

void NoiseRateEstimator::start(std::int64_t t_us) noexcept {
  started_ = true;
  period_ = floor_div(t_us, period_us_);
  observed_from_us_ = t_us;
  failed_ = 0.0;
}

std::int64_t NoiseRateEstimator::adaptive_threshold(std::int64_t t_us) noexcept {
  if (!started_) start(t_us);
  const std::int64_t p = floor_div(t_us, period_us_);
  if (p != period_) {
    // The stream's first period is observed only from its first event on.
    const std::int64_t end_us = (period_ + 1) * period_us_;
    const double seconds = static_cast<double>(end_us - observed_from_us_) * 1e-6;
    rate_hz_ = estimate_noise_rate(failed_, seconds, model_, threshold_, rate_hz_);
    threshold_ = std::min(threshold_for_rate(rate_hz_, model_, target_), max_threshold_);
    ++periods_;
    period_ = p;
    observed_from_us_ = p * period_us_;
    failed_ = 0.0;
  }
  return threshold_;
}

}  // namespace evpipe::denoise
