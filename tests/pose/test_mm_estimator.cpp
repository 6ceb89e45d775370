// S/MM estimation (scale, weights, LOPET variant) against identities and the reference notes' numbers
// (pose.md §7.5). The loss itself: test_robust_loss.cpp.

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <numeric>
#include <random>
#include <vector>

#include "evpipe/pose/mm_estimator.hpp"

using namespace evpipe::pose;

namespace {

std::vector<double> gaussian(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> nd(0.0, 1.0);
  std::vector<double> r(n);
  for (auto& x : r) x = nd(rng);
  return r;
}

// 70 % N(0, 1) + 30 % U(-20, 20): the reference notes' contaminated sample.
std::vector<double> contaminated(std::size_t n, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> nd(0.0, 1.0);
  std::uniform_real_distribution<double> ud(-20.0, 20.0);
  std::bernoulli_distribution outlier(0.3);
  std::vector<double> r(n);
  for (auto& x : r) x = outlier(rng) ? ud(rng) : nd(rng);
  return r;
}

}  // namespace

TEST(Mad, KnownValues) {
  const std::vector<double> odd{1, 2, 3, 4, 100};
  EXPECT_DOUBLE_EQ(mm::mad(odd), 1.0);  // median 3, deviations {2, 1, 0, 1, 97}
  const std::vector<double> even{1, 2, 3, 4};
  EXPECT_DOUBLE_EQ(mm::mad(even), 1.0);  // median 2.5, deviations {1.5, 0.5, 0.5, 1.5}
  const std::vector<double> shifted{-7, 5, 5, 5, 6};
  EXPECT_DOUBLE_EQ(mm::mad(shifted), 0.0);
  EXPECT_DOUBLE_EQ(mm::mad(std::vector<double>{}), 0.0);
  std::vector<double> scratch(5);
  EXPECT_DOUBLE_EQ(mm::median(odd, scratch), 3.0);
}

TEST(SScale, ReferenceTable) {
  // pose.md §7.5 (200 000 residuals): 1.4826 MAD / textbook S-scale / LOPET-code sigma.
  const std::uint64_t seed = 20250107;
  std::cout << "seed " << seed << "\n";
  const auto g = gaussian(200'000, seed);
  const auto c = contaminated(200'000, seed + 1);
  const auto sg = mm::s_scale(g), sc = mm::s_scale(c);
  std::cout << "N(0,1): MAD-scale " << mm::kMadToSigma * mm::mad(g) << " S " << sg.sigma << " (" << sg.iterations
            << " it) LOPET " << mm::lopet_scale(g) << "\n";
  std::cout << "70/30 : MAD-scale " << mm::kMadToSigma * mm::mad(c) << " S " << sc.sigma << " (" << sc.iterations
            << " it) LOPET " << mm::lopet_scale(c) << "\n";
  EXPECT_NEAR(mm::kMadToSigma * mm::mad(g), 1.002, 0.01);
  EXPECT_NEAR(sg.sigma, 1.00, 0.01);
  EXPECT_NEAR(mm::lopet_scale(g), 1.954, 0.015);
  EXPECT_NEAR(mm::kMadToSigma * mm::mad(c), 1.516, 0.015);
  EXPECT_NEAR(sc.sigma, 1.614, 0.02);
  EXPECT_NEAR(mm::lopet_scale(c), 2.274, 0.02);
  EXPECT_TRUE(sg.converged);
  EXPECT_TRUE(sc.converged);
  EXPECT_LE(sc.iterations, 10);
}

TEST(SScale, EquivarianceAndEdgeCases) {
  const std::uint64_t seed = 7;
  std::cout << "seed " << seed << "\n";
  auto r = contaminated(5'000, seed);
  const double s1 = mm::s_scale(r).sigma;
  for (auto& x : r) x *= 3.5;
  // Scale equivariance holds up to the stopping tolerance (relative change < 1e-3 per iteration).
  EXPECT_NEAR(mm::s_scale(r).sigma / s1, 3.5, 3.5 * 3e-3);
  EXPECT_DOUBLE_EQ(mm::s_scale(std::vector<double>{}).sigma, 0.0);
  const auto z = mm::s_scale(std::vector<double>(10, 0.0));
  EXPECT_DOUBLE_EQ(z.sigma, 0.0);
  EXPECT_FALSE(std::isnan(z.sigma));
  // MAD = 0 (most residuals equal) falls back to the RMS start and still gives a finite positive scale.
  std::vector<double> mostly_zero(10, 0.0);
  mostly_zero[0] = 1.0;
  mostly_zero[1] = -2.0;
  const auto mz = mm::s_scale(mostly_zero);
  EXPECT_GT(mz.sigma, 0.0);
  EXPECT_TRUE(std::isfinite(mz.sigma));
}

// The tracker starts each round's S-scale at the previous round's: the fixed point is the same root of
// mean rho(d / sigma) = b from any start (up to the stopping tolerance), and a start near it needs fewer steps.
TEST(SScale, AnyStartReachesTheSameScale) {
  const std::uint64_t seed = 11;
  std::cout << "seed " << seed << "\n";
  const auto r = contaminated(5'000, seed);
  mm::SScaleOptions tight;
  tight.relative_tolerance = 1e-9;
  tight.max_iterations = 500;
  const mm::SScaleResult from_mad = mm::s_scale(r, tight);
  ASSERT_TRUE(from_mad.converged);
  for (const double start : {0.1, 0.5, 2.0, 10.0}) {
    mm::SScaleOptions o = tight;
    o.start = start * from_mad.sigma;
    const mm::SScaleResult s = mm::s_scale(r, o);
    EXPECT_TRUE(s.converged) << start;
    EXPECT_DOUBLE_EQ(s.sigma_start, o.start);
    EXPECT_NEAR(s.sigma / from_mad.sigma, 1.0, 1e-6) << "start " << start << " x the scale";
  }
  mm::SScaleOptions near;
  near.start = 1.01 * from_mad.sigma;
  EXPECT_LE(mm::s_scale(r, near).iterations, mm::s_scale(r).iterations);
  // Every residual 0 from a positive start: 0, not NaN (the first step lands on 0).
  mm::SScaleOptions from_one;
  from_one.start = 1.0;
  const auto zero = mm::s_scale(std::vector<double>(10, 0.0), from_one);
  EXPECT_EQ(zero.sigma, 0.0);
  EXPECT_TRUE(zero.converged);
}

TEST(MmWeights, TukeyAtTheScaleAndLopetNormalised) {
  const std::vector<double> r{0.0, 1.0, -2.0, 4.685, 5.0, -100.0};
  std::vector<double> w(r.size());
  mm::mm_weights(r, 1.0, w);
  EXPECT_DOUBLE_EQ(w[0], 1.0);
  EXPECT_NEAR(w[1], std::pow(1 - 1 / (4.685 * 4.685), 2), 1e-15);
  EXPECT_NEAR(w[2], std::pow(1 - 4 / (4.685 * 4.685), 2), 1e-15);
  EXPECT_NEAR(w[3], 0.0, 1e-15);
  EXPECT_DOUBLE_EQ(w[4], 0.0);
  EXPECT_DOUBLE_EQ(w[5], 0.0);
  mm::mm_weights(r, 2.0, w);
  EXPECT_NEAR(w[2], std::pow(1 - 1 / (4.685 * 4.685), 2), 1e-15);  // u = d / sigma

  const std::uint64_t seed = 11;
  std::cout << "seed " << seed << "\n";
  const auto c = contaminated(1'000, seed);
  std::vector<double> wl(c.size());
  const double s = mm::lopet_weights(c, wl);
  EXPECT_NEAR(std::accumulate(wl.begin(), wl.end(), 0.0), 1.0, 1e-12);
  EXPECT_DOUBLE_EQ(s, mm::lopet_scale(c));
  for (std::size_t i = 0; i < c.size(); ++i) {
    if (std::abs(c[i]) > 4.685 * s) {
      EXPECT_EQ(wl[i], 0.0);
    }
  }
}
