#include "evpipe/pose/mm_estimator.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace evpipe::pose::mm {

double median(std::span<const double> values, std::span<double> scratch) {
  if (values.empty()) return 0.0;
  const std::size_t n = values.size();
  std::copy(values.begin(), values.end(), scratch.begin());
  auto first = scratch.begin();
  auto mid = first + static_cast<std::ptrdiff_t>(n / 2);
  std::nth_element(first, mid, first + static_cast<std::ptrdiff_t>(n));
  const double upper = *mid;
  if (n % 2 == 1) return upper;
  const double lower = *std::max_element(first, mid);
  return 0.5 * (lower + upper);
}

double mad(std::span<const double> values) {
  if (values.empty()) return 0.0;
  std::vector<double> scratch(values.size());
  const double med = median(values, scratch);
  std::vector<double> dev(values.size());
  for (std::size_t i = 0; i < values.size(); ++i) dev[i] = std::abs(values[i] - med);
  return median(dev, scratch);
}

SScaleResult s_scale(std::span<const double> residuals, const SScaleOptions& options) {
  SScaleResult r;
  if (residuals.empty()) return r;
  double sigma = options.start > 0.0 && std::isfinite(options.start) ? options.start : kMadToSigma * mad(residuals);
  if (!(sigma > 0.0)) {
    double ss = 0.0;
    for (double d : residuals) ss += d * d;
    sigma = std::sqrt(ss / static_cast<double>(residuals.size()));
  }
  r.sigma_start = sigma;
  if (!(sigma > 0.0) || !std::isfinite(sigma)) {
    r.sigma = std::isfinite(sigma) ? sigma : 0.0;
    r.converged = r.sigma == 0.0;
    return r;
  }
  const double b = loss::tukey_normal_consistency(options.c);
  const double inv_nb = 1.0 / (static_cast<double>(residuals.size()) * b);
  for (int it = 0; it < options.max_iterations; ++it) {
    const double acc = loss::tukey_s_sum(residuals, sigma, options.c);
    const double next = std::sqrt(acc * inv_nb);
    ++r.iterations;
    if (!(next > 0.0)) {  // every residual 0 (reachable from a positive start): the scale is 0
      sigma = 0.0;
      r.converged = true;
      break;
    }
    const double change = std::abs(next / sigma - 1.0);
    sigma = next;
    if (change < options.relative_tolerance) {
      r.converged = true;
      break;
    }
  }
  r.sigma = sigma;
  return r;
}

double lopet_scale(std::span<const double> residuals) {
  if (residuals.empty()) return 0.0;
  const double s0 = kMadToSigma * mad(residuals);
  double acc = 0.0;
  for (double d : residuals) {
    const double w0 = s0 > 0.0 ? loss::tukey_weight(d / s0, loss::kTukeyMM) : (d == 0.0 ? 1.0 : 0.0);
    acc += w0 * d * d;
  }
  return std::sqrt(acc / static_cast<double>(residuals.size()) / kLopetB);
}

void mm_weights(std::span<const double> residuals, double sigma, std::span<double> weights, double c) {
  if (!(sigma > 0.0)) {
    for (std::size_t i = 0; i < residuals.size(); ++i) weights[i] = residuals[i] == 0.0 ? 1.0 : 0.0;
    return;
  }
  const double inv = 1.0 / sigma;
  for (std::size_t i = 0; i < residuals.size(); ++i) weights[i] = loss::tukey_weight(residuals[i] * inv, c);
}

double lopet_weights(std::span<const double> residuals, std::span<double> weights) {
  const double sigma = lopet_scale(residuals);
  mm_weights(residuals, sigma, weights, loss::kTukeyMM);
  double sum = 0.0;
  for (std::size_t i = 0; i < residuals.size(); ++i) sum += weights[i];
  for (std::size_t i = 0; i < residuals.size(); ++i) weights[i] = sum > 0.0 ? weights[i] / sum : 0.0;
  return sigma;
}

}  // namespace evpipe::pose::mm
