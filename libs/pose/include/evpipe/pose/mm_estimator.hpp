#pragma once
// Tukey-bisquare S- and MM-estimation on residual spans (paper eqs. 40-44; Yohai's MM-estimator): the robust
// scale and the IRLS weights the tracker uses. Plain functions, no state; units are the residuals' units. The loss
// itself (rho, psi, weights, the consistency constant b(c)) is robust_loss.hpp's.
//
// S-scale (50 % breakdown, c0 = 1.547, b = E_Phi[rho_c0] = 0.19950 ≈ rho_c0(inf) / 2): the fixed point of
//   sigma² <- (1 / (N b)) sum_i w_S(u_i) d_i²,   u_i = d_i / sigma,   w_S(u) = rho_c0(u) / u²
// (equivalently sigma² <- sigma² mean(rho_c0(u_i)) / b), started at 1.4826 MAD.
// MM weights (95 % Gaussian efficiency): w_4.685(d_i / sigma_S).
//
// LOPET-compatible variant (the authors' demo code, Zibin6/LOPET func/MM_estimation.m; reference notes
// pose.md §7.4/7.5): w0 = w_4.685(d / (1.4826 MAD)), sigma = sqrt(mean(w0 d²) / 0.199), then
// w = w_4.685(d / sigma) normalised to sum 1. No c = 1.547 anywhere; sigma is ~2x the inlier scale.

#include "evpipe/pose/robust_loss.hpp"

#include <span>

namespace evpipe::pose::mm {

inline constexpr double kMadToSigma = 1.4826;  ///< 1 / Phi^-1(3/4): MAD -> sigma at the Gaussian
inline constexpr double kLopetB = 0.199;       ///< the constant as written in the paper and the demo code

/// Median of the values (0 for an empty span). O(N), uses `scratch` (resized) for the copy.
[[nodiscard]] double median(std::span<const double> values, std::span<double> scratch);
/// Median absolute deviation from the median, median(|d - median(d)|), unscaled. 0 for an empty span.
[[nodiscard]] double mad(std::span<const double> values);

struct SScaleOptions {
  /// Tukey c; the equation's b = loss::tukey_normal_consistency(c) follows from it (consistent at the Gaussian).
  double c = loss::kTukeyS;
  int max_iterations = 10;
  double relative_tolerance = 1e-3;  ///< stop when |sigma_new / sigma - 1| < this
  /// > 0: start the iteration here instead of at 1.4826 MAD (the fixed point is the same: mean rho(d/sigma) is
  /// decreasing in sigma, so the equation has one root, and the iteration reaches it from any positive start).
  double start = 0.0;
};

struct SScaleResult {
  double sigma{0.0};        ///< the S-scale (residual units); 0 when every residual is 0 or none given
  double sigma_start{0.0};  ///< options.start, else 1.4826 MAD (or the RMS when MAD = 0)
  int iterations{0};
  bool converged{false};
};

/// The S-scale fixed point above. When MAD = 0 (over half the residuals identical) it starts from the RMS.
[[nodiscard]] SScaleResult s_scale(std::span<const double> residuals, const SScaleOptions& options = {});

/// The LOPET demo code's scale sigma = sqrt(mean(w0 d²) / 0.199) with w0 = w_4.685(d / (1.4826 MAD)).
[[nodiscard]] double lopet_scale(std::span<const double> residuals);

/// weights[i] = w_c(residuals[i] / sigma). sigma <= 0 gives weight 1 for zero residuals, 0 otherwise.
void mm_weights(std::span<const double> residuals, double sigma, std::span<double> weights, double c = loss::kTukeyMM);

/// The LOPET demo code's weights: w_4.685(d / lopet_scale(d)), normalised to sum 1 (all 0 if they sum to 0).
/// Returns the scale used.
double lopet_weights(std::span<const double> residuals, std::span<double> weights);

}  // namespace evpipe::pose::mm
