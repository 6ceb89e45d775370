#include <gtest/gtest.h>

#include <cmath>
#include <set>

#include "evpipe/sim/noise.hpp"

using namespace evpipe;

TEST(BackgroundActivity, RateWithinPoissonBounds) {
  for (const double lambda : {0.1, 1.0, 5.0}) {
    const std::uint64_t seed = 100 + static_cast<std::uint64_t>(lambda * 10);
    SCOPED_TRACE(testing::Message() << "lambda=" << lambda << " seed=" << seed);
    std::mt19937_64 rng(seed);
    sim::NoiseOptions o;
    o.rate_hz_per_pixel = lambda;
    const auto ev = sim::background_activity(kDavis346, 0, 2'000'000, o, rng);
    const double expected = lambda * static_cast<double>(kDavis346.pixels()) * 2.0;
    // 5 sigma of a Poisson count.
    EXPECT_NEAR(static_cast<double>(ev.size()), expected, 5.0 * std::sqrt(expected));
    std::size_t on = 0;
    for (std::size_t i = 0; i < ev.size(); ++i) {
      ASSERT_TRUE(kDavis346.contains(ev[i].x, ev[i].y));
      ASSERT_GE(ev[i].t_us, 0);
      ASSERT_LT(ev[i].t_us, 2'000'000);
      if (i) {
        ASSERT_LE(ev[i - 1].t_us, ev[i].t_us);
      }
      on += ev[i].polarity;
    }
    EXPECT_NEAR(static_cast<double>(on) / static_cast<double>(ev.size()), 0.5,
                5.0 * 0.5 / std::sqrt(static_cast<double>(ev.size())));
  }
}

TEST(BackgroundActivity, PerPixelCountsAreUniform) {
  // Chi-square over 16 coarse blocks of the sensor.
  std::mt19937_64 rng(7);
  sim::NoiseOptions o;
  o.rate_hz_per_pixel = 2.0;
  const auto ev = sim::background_activity(kDavis346, 0, 1'000'000, o, rng);
  std::vector<double> blocks(16, 0);
  for (const auto& e : ev) blocks[static_cast<std::size_t>((e.x * 4 / 346) * 4 + e.y * 4 / 260)] += 1;
  // Block sizes differ slightly (346 and 260 are not multiples of 4): expected counts by block area.
  double chi2 = 0;
  for (int bx = 0; bx < 4; ++bx)
    for (int by = 0; by < 4; ++by) {
      int w = 0, h = 0;
      for (int x = 0; x < 346; ++x) w += (x * 4 / 346) == bx;
      for (int y = 0; y < 260; ++y) h += (y * 4 / 260) == by;
      const double exp = static_cast<double>(ev.size()) * w * h / (346.0 * 260.0);
      const double d = blocks[static_cast<std::size_t>(bx * 4 + by)] - exp;
      chi2 += d * d / exp;
    }
  EXPECT_LT(chi2, 37.7);  // chi-square, 15 degrees of freedom, p = 0.001
}

TEST(BackgroundActivity, HotPixelsFireAtTheirRate) {
  std::mt19937_64 rng(11);
  sim::NoiseOptions o;
  o.rate_hz_per_pixel = 0;
  o.hot_pixels = 3;
  o.hot_rate_hz = 500;
  const auto ev = sim::background_activity(kDavis346, 0, 2'000'000, o, rng);
  EXPECT_NEAR(static_cast<double>(ev.size()), 3000.0, 5.0 * std::sqrt(3000.0));
  std::set<std::pair<int, int>> pixels;
  for (const auto& e : ev) pixels.insert({e.x, e.y});
  EXPECT_LE(pixels.size(), 3U);
}

TEST(UniformNoise, PaperProtocolExactCountWithin30ms) {
  for (const std::size_t n : {500U, 3000U, 6000U, 9000U}) {
    std::mt19937_64 rng(n);
    const auto ev = sim::uniform_noise(kDavis346, 1000, 30'000, n, rng);
    ASSERT_EQ(ev.size(), n);
    for (std::size_t i = 0; i < n; ++i) {
      ASSERT_GE(ev[i].t_us, 1000);
      ASSERT_LT(ev[i].t_us, 31'000);
      if (i) {
        ASSERT_LE(ev[i - 1].t_us, ev[i].t_us);
      }
    }
  }
}

TEST(BackgroundActivity, SameSeedSameEvents) {
  sim::NoiseOptions o;
  std::mt19937_64 a(5), b(5), c(6);
  const auto ea = sim::background_activity(kDavis346, 0, 100'000, o, a);
  EXPECT_EQ(ea, sim::background_activity(kDavis346, 0, 100'000, o, b));
  EXPECT_NE(ea, sim::background_activity(kDavis346, 0, 100'000, o, c));
}

TEST(BackgroundActivity, LeakEventsAreOnAtTheirRate) {
  std::mt19937_64 rng(21);
  sim::NoiseOptions o;
  o.rate_hz_per_pixel = 0;
  o.leak_rate_hz_per_pixel = 0.5;
  const auto ev = sim::background_activity(kDavis346, 0, 2'000'000, o, rng);
  const double expected = 0.5 * static_cast<double>(kDavis346.pixels()) * 2.0;
  EXPECT_NEAR(static_cast<double>(ev.size()), expected, 5.0 * std::sqrt(expected));
  for (const auto& e : ev) ASSERT_TRUE(e.polarity);
}
