#pragma once
// The robust loss of the pose tracker: Tukey's bisquare, in one place. The S-scale and MM weights
// (mm_estimator.hpp), the tracker's MM cost and IRLS weights and its covariance weights (tracker.cpp) all evaluate
// it through these functions; no other copy of the formulas exists. Plain functions, no state; u is a residual
// divided by its scale, c the tuning constant.
//
//   rho_c(u) = u²/2 - u⁴/(2c²) + u⁶/(6c⁴) = (c²/6) [1 - (1 - (u/c)²)³]   for |u| <= c,   c²/6 otherwise
//   psi_c(u) = rho_c'(u) = u (1 - (u/c)²)²                                 for |u| <= c,   0 otherwise
//   w_c(u)   = psi_c(u) / u = (1 - (u/c)²)²                                for |u| <= c,   0 otherwise
//   w_S,c(u) = rho_c(u) / u² = (1 + t + t²) / 6, t = 1 - (u/c)²            for |u| <= c,   c² / (6u²) otherwise
//
// The S-scale's constant b is not a free parameter: the M-scale equation mean rho_c(d / sigma) = b gives the
// standard deviation at the Gaussian only for b(c) = E_Phi[rho_c(u)], u ~ N(0, 1) (Fisher consistency), and its
// breakdown point is then b(c) / rho_c(inf). tukey_normal_consistency() evaluates b(c) in closed form from the
// truncated moments of the standard normal. c = 1.547 gives b = 0.19950 = 0.50016 rho(inf) (50 % breakdown);
// c = 4.685 gives the MM-step 95 % efficiency at the Gaussian.

#include <span>

namespace evpipe::pose::loss {

inline constexpr double kTukeyS = 1.547;   ///< c of the S-step (50 % breakdown)
inline constexpr double kTukeyMM = 4.685;  ///< c of the MM-step (95 % efficiency at the Gaussian)

[[nodiscard]] double tukey_rho(double u, double c) noexcept;
[[nodiscard]] double tukey_psi(double u, double c) noexcept;
[[nodiscard]] double tukey_weight(double u, double c) noexcept;
/// rho_c(u) / u², the S-step weight; its limit 1/2 at u = 0 (exact, no cancellation).
[[nodiscard]] double tukey_s_weight(double u, double c) noexcept;
/// rho_c(inf) = c² / 6.
[[nodiscard]] constexpr double tukey_rho_max(double c) noexcept {
  return c * c / 6.0;
}

/// b(c) = E[rho_c(u)] for u ~ N(0, 1), closed form: with P = erf(c / sqrt 2), phi the normal density and the
/// truncated moments m_k = E[u^k; |u| <= c] (m_0 = P, m_k = (k - 1) m_(k-2) - 2 c^(k-1) phi(c)),
/// b = m_2 / 2 - m_4 / (2c²) + m_6 / (6c⁴) + (c² / 6)(1 - P).
[[nodiscard]] double tukey_normal_consistency(double c) noexcept;

/// Sum over the residuals d of rho_c(d / sigma) sigma² = sum w_S,c(d / sigma) d² (the S-scale iteration's sum),
/// evaluated without divisions per residual. sigma > 0.
[[nodiscard]] double tukey_s_sum(std::span<const double> residuals, double sigma, double c) noexcept;

/// The MM cost sum rho_c(r / sigma) over the residuals and, in the same pass, weights[j] = w_c(r_j / sigma)
/// (weights.size() >= residuals.size()). sigma > 0.
double tukey_cost_and_weights(std::span<const double> residuals, double sigma, double c,
                              std::span<double> weights) noexcept;

}  // namespace evpipe::pose::loss
