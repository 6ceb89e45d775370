// The robust loss (robust_loss.hpp): Tukey bisquare rho / psi / weights against their identities, the
// normal-consistency constant b(c) against a numerical integral and the classic values, and the batched sums
// against the pointwise functions.

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <random>
#include <vector>

#include "evpipe/pose/robust_loss.hpp"

using namespace evpipe::pose;

namespace {

double normal_pdf(double u) {
  return std::exp(-0.5 * u * u) * 0.5 * std::numbers::inv_sqrtpi * std::numbers::sqrt2;
}

// E[f(u)], u ~ N(0, 1), by composite Simpson on [-12, -c], [-c, c], [c, 12] (each piece smooth: the loss's kinks
// at ±c fall on a boundary; the mass beyond 12 is < 1e-32).
double normal_expectation(const std::function<double(double)>& f, double c) {
  const auto simpson = [&](double a, double b) {
    const int n = 20'000;  // even
    const double h = (b - a) / n;
    double s = f(a) * normal_pdf(a) + f(b) * normal_pdf(b);
    for (int i = 1; i < n; ++i) {
      const double u = a + i * h;
      s += (i % 2 == 1 ? 4.0 : 2.0) * f(u) * normal_pdf(u);
    }
    return s * h / 3.0;
  };
  return simpson(-12.0, -c) + simpson(-c, c) + simpson(c, 12.0);
}

}  // namespace

TEST(TukeyBisquare, RhoPsiWeightIdentities) {
  for (const double c : {loss::kTukeyS, loss::kTukeyMM}) {
    SCOPED_TRACE(c);
    EXPECT_DOUBLE_EQ(loss::tukey_rho(0.0, c), 0.0);
    EXPECT_DOUBLE_EQ(loss::tukey_weight(0.0, c), 1.0);
    EXPECT_NEAR(loss::tukey_rho(c, c), c * c / 6.0, 1e-15);
    EXPECT_DOUBLE_EQ(loss::tukey_rho(10.0 * c, c), c * c / 6.0);
    EXPECT_DOUBLE_EQ(loss::tukey_psi(1.01 * c, c), 0.0);
    EXPECT_DOUBLE_EQ(loss::tukey_weight(-1.01 * c, c), 0.0);
    EXPECT_NEAR(loss::tukey_s_weight(0.0, c), 0.5, 1e-15);
    for (double u = -1.2 * c; u <= 1.2 * c; u += 0.037 * c) {
      // The paper's polynomial form (eq. 42) equals the textbook (c²/6)[1 - (1 - (u/c)²)³] inside [-c, c].
      if (std::abs(u) <= c) {
        const double poly = u * u / 2 - std::pow(u, 4) / (2 * c * c) + std::pow(u, 6) / (6 * std::pow(c, 4));
        EXPECT_NEAR(loss::tukey_rho(u, c), poly, 1e-12);
      }
      // psi = rho' (central difference), w = psi / u, w_S = rho / u².
      const double h = 1e-6;
      EXPECT_NEAR(loss::tukey_psi(u, c), (loss::tukey_rho(u + h, c) - loss::tukey_rho(u - h, c)) / (2 * h), 1e-6);
      if (std::abs(u) > 1e-9) {
        EXPECT_NEAR(loss::tukey_weight(u, c) * u, loss::tukey_psi(u, c), 1e-14);
        EXPECT_NEAR(loss::tukey_s_weight(u, c) * u * u, loss::tukey_rho(u, c), 1e-14);
      }
      EXPECT_DOUBLE_EQ(loss::tukey_rho(u, c), loss::tukey_rho(-u, c));
    }
  }
}

TEST(TukeyBisquare, NormalConsistencyMatchesTheIntegral) {
  for (const double c : {0.5, 1.0, loss::kTukeyS, 2.5, loss::kTukeyMM, 8.0}) {
    SCOPED_TRACE(c);
    const double b = loss::tukey_normal_consistency(c);
    EXPECT_NEAR(b, normal_expectation([c](double u) { return loss::tukey_rho(u, c); }, c), 1e-12);
    EXPECT_GT(b, 0.0);
    EXPECT_LT(b, loss::tukey_rho_max(c));
  }
  // Large c: rho -> u²/2 on the bulk of the normal, so b -> 1/2.
  EXPECT_NEAR(loss::tukey_normal_consistency(50.0), 0.5, 1e-3);
}

TEST(TukeyBisquare, ClassicConstants) {
  // c = 1.547: b = rho(inf) / 2, the 50 % breakdown S-estimator (1.547 is rounded from 1.5476: 0.50016).
  const double b = loss::tukey_normal_consistency(loss::kTukeyS);
  EXPECT_NEAR(b / loss::tukey_rho_max(loss::kTukeyS), 0.5, 2e-4);
  EXPECT_NEAR(b, 0.19950, 1e-5);  // the paper's "0.199"; the old typed option was 0.1994
  EXPECT_NEAR(loss::tukey_normal_consistency(1.5476) / loss::tukey_rho_max(1.5476), 0.5, 2e-5);
  // c = 4.685: 95 % asymptotic efficiency at the Gaussian, (E psi')² / E psi², with E psi' = E[u psi(u)] (Stein).
  const double c = loss::kTukeyMM;
  const double e_upsi = normal_expectation([c](double u) { return u * loss::tukey_psi(u, c); }, c);
  const double e_psi2 = normal_expectation([c](double u) { return std::pow(loss::tukey_psi(u, c), 2); }, c);
  EXPECT_NEAR(e_upsi * e_upsi / e_psi2, 0.95, 1e-3);
}

TEST(TukeyBisquare, SumsEqualThePointwiseFunctions) {
  const std::uint64_t seed = 19;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> nd(0.0, 1.0);
  std::uniform_real_distribution<double> ud(-20.0, 20.0);
  std::vector<double> r(2'000);
  for (std::size_t i = 0; i < r.size(); ++i) r[i] = i % 4 == 0 ? ud(rng) : nd(rng);
  r[0] = 0.0;
  for (const double c : {loss::kTukeyS, loss::kTukeyMM}) {
    for (const double sigma : {0.3, 1.0, 2.7}) {
      SCOPED_TRACE(c * 1000 + sigma);
      double rho_sum = 0.0;
      for (const double d : r) rho_sum += loss::tukey_rho(d / sigma, c);
      EXPECT_NEAR(loss::tukey_s_sum(r, sigma, c), rho_sum * sigma * sigma, 1e-10 * rho_sum * sigma * sigma);
      std::vector<double> w(r.size(), -1.0);
      EXPECT_NEAR(loss::tukey_cost_and_weights(r, sigma, c, w), rho_sum, 1e-10 * rho_sum);
      for (std::size_t j = 0; j < r.size(); ++j) EXPECT_NEAR(w[j], loss::tukey_weight(r[j] / sigma, c), 1e-14);
    }
  }
}
