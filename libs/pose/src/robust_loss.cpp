#include "evpipe/pose/robust_loss.hpp"

#include <cmath>
#include <numbers>

namespace evpipe::pose::loss {

double tukey_rho(double u, double c) noexcept {
  const double c2 = c * c;
  if (!(std::abs(u) <= c)) return c2 / 6.0;
  const double t = 1.0 - (u * u) / c2;
  return (c2 / 6.0) * (1.0 - t * t * t);
}

double tukey_psi(double u, double c) noexcept {
  if (!(std::abs(u) <= c)) return 0.0;
  const double t = 1.0 - (u * u) / (c * c);
  return u * t * t;
}

double tukey_weight(double u, double c) noexcept {
  if (!(std::abs(u) <= c)) return 0.0;
  const double t = 1.0 - (u * u) / (c * c);
  return t * t;
}

double tukey_s_weight(double u, double c) noexcept {
  // With t = 1 - u²/c², 1 - t³ = (u²/c²)(1 + t + t²), so for |u| <= c rho/u² = (1 + t + t²) / 6 (exact, no
  // cancellation at u = 0, where it is 1/2), and c² / (6u²) beyond.
  const double u2 = u * u;
  const double c2 = c * c;
  if (!(u2 <= c2)) return c2 / (6.0 * u2);
  const double t = 1.0 - u2 / c2;
  return (1.0 + t + t * t) / 6.0;
}

double tukey_normal_consistency(double c) noexcept {
  const double phi = std::exp(-0.5 * c * c) * (0.5 * std::numbers::inv_sqrtpi * std::numbers::sqrt2);
  const double p = std::erf(c / std::numbers::sqrt2);  // P(|u| <= c)
  const double c2 = c * c;
  // Truncated moments E[u^k; |u| <= c] by parts: m_k = (k - 1) m_(k-2) - 2 c^(k-1) phi(c).
  const double m2 = p - 2.0 * c * phi;
  const double m4 = 3.0 * m2 - 2.0 * c * c2 * phi;
  const double m6 = 5.0 * m4 - 2.0 * c * c2 * c2 * phi;
  return m2 / 2.0 - m4 / (2.0 * c2) + m6 / (6.0 * c2 * c2) + (c2 / 6.0) * (1.0 - p);
}

double tukey_s_sum(std::span<const double> residuals, double sigma, double c) noexcept {
  // w_S(d/σ) d² for a fixed σ: (1 + t + t²) d² / 6 with t = 1 - d²/(cσ)² inside, (cσ)² / 6 outside.
  const double cs2 = c * c * sigma * sigma;
  const double inv_cs2 = 1.0 / cs2;
  double acc = 0.0;
  for (const double d : residuals) {
    const double d2 = d * d;
    const double t = 1.0 - d2 * inv_cs2;
    acc += d2 <= cs2 ? (1.0 + t + t * t) * d2 : cs2;
  }
  return acc / 6.0;
}

double tukey_cost_and_weights(std::span<const double> residuals, double sigma, double c,
                              std::span<double> weights) noexcept {
  // rho and w share t = 1 - (r / cσ)²: rho = (c²/6)(1 - t³), w = t²; the c²/6 is applied once to the sum.
  const double inv_cs2 = 1.0 / (c * c * sigma * sigma);
  double cost = 0.0;
  for (std::size_t j = 0; j < residuals.size(); ++j) {
    const double t = 1.0 - residuals[j] * residuals[j] * inv_cs2;
    const bool in = t >= 0.0;
    cost += in ? 1.0 - t * t * t : 1.0;
    weights[j] = in ? t * t : 0.0;
  }
  return cost * (c * c / 6.0);
}

}  // namespace evpipe::pose::loss
