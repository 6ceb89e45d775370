// The baselines on seeded uniform Poisson noise (346×260) against denoise.md §8.3's measured NRRs, plus checks
// shared by every baseline (registry, push-size independence, scores).
//
// Protocol: timestamps start at t = 1 µs; 1 Hz/px over 3 s and 5 Hz/px over 1 s. §8.3 does not state its stream
// lengths; these are the ones that reproduce every row with NumPy replicas of its generator (default_rng, t uniform
// in [1, T]): the length matters through start-up effects (BAF passes the first 2 ms; STCF drops the first event of
// every pixel, ~20 % of a 1 s stream at 5 Hz/px; at 1 Hz/px STCF 25 ms gives 99.86 / 99.78 / 99.73 % for
// T = 1 / 2 / 3 s against §8.3's 99.72 %). §8.3's YNoise rows have no start-up artefact, so YNoise runs with
// init=never here (with the default init=zero the 5 Hz/px stream loses ~0.45 % NRR: every OFF event of the first
// 10 ms passes).
// Tolerance ±0.3 % absolute: each NRR is a proportion over 0.27–0.45 M events with σ ≤ 0.06 %, the reference is one
// measurement with the same σ, so the difference has σ ≤ 0.09 %: 0.3 % is > 3σ. It is a sanity check of the
// statistics (window sizes, thresholds, start-up handling move these numbers by 0.4–15 %); the finer rules
// (strict vs inclusive, KNoise's own pixel: < 0.2 % here) are pinned exactly by the hand-made tests and by the
// dv-processing equality tests.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "evpipe/denoise/registry.hpp"
#include "evpipe/sim/noise.hpp"

namespace evpipe::denoise {
namespace {

using Settings = std::vector<std::pair<std::string, std::string>>;

std::vector<Event> poisson_noise(double rate_hz, std::int64_t span_us, std::uint64_t seed, int hot_pixels = 0) {
  std::mt19937_64 rng(seed);
  sim::NoiseOptions o;
  o.rate_hz_per_pixel = rate_hz;
  o.hot_pixels = hot_pixels;
  o.hot_rate_hz = 2000.0;
  return sim::background_activity(kDavis346, 1, 1 + span_us, o, rng);
}

double nrr_percent(const std::string& filter, const Settings& settings, const std::vector<Event>& events) {
  auto f = make_filter(filter, settings, kDavis346);
  const Decisions d = run_filter(*f, events, 10'000);
  return 100.0 * (1.0 - static_cast<double>(count_kept(d)) / static_cast<double>(events.size()));
}

TEST(BaselinesNrr, MatchTheReferenceOnSeededPoissonNoise) {
  struct Row {
    const char* label;
    const char* filter;
    Settings settings;
    double ref_1hz, ref_5hz;  // denoise.md §8.3
  };
  const Row rows[] = {
      {"dv BAF 2000 us", "baf", {}, 98.36, 92.12},
      {"dv KNoise 1000 us", "knoise", {}, 99.56, 98.40},
      {"CUKE KNoise 1000 us", "knoise", {{"variant", "cuke"}}, 99.61, 98.58},
      {"CUKE YNoise 10 ms thr 1", "ynoise", {{"init", "never"}}, 95.64, 80.26},
      {"CUKE YNoise 10 ms thr 2", "ynoise", {{"init", "never"}, {"threshold", "2"}}, 99.91, 98.14},
      {"jAER STCF tau 10 ms", "stcf", {{"tau_us", "10000"}}, 99.95, 98.81},
      {"jAER STCF tau 25 ms", "stcf", {}, 99.72, 94.00},
      {"CUKE DWF 36/9/1", "dwf", {}, 87.46, 87.41},
  };
  const std::uint64_t seed = 20250401;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const auto noise_1hz = poisson_noise(1.0, 3'000'000, seed);
  const auto noise_5hz = poisson_noise(5.0, 1'000'000, seed + 1);
  std::printf("NRR on Poisson noise, seed %llu (1 Hz/px 3 s: %zu events; 5 Hz/px 1 s: %zu events)\n",
              static_cast<unsigned long long>(seed), noise_1hz.size(), noise_5hz.size());
  for (const Row& r : rows) {
    const double at1 = nrr_percent(r.filter, r.settings, noise_1hz);
    const double at5 = nrr_percent(r.filter, r.settings, noise_5hz);
    std::printf("  %-26s 1 Hz %6.2f %% (ref %6.2f)   5 Hz %6.2f %% (ref %6.2f)\n", r.label, at1, r.ref_1hz, at5,
                r.ref_5hz);
    EXPECT_NEAR(at1, r.ref_1hz, 0.3) << r.label << " at 1 Hz/px";
    EXPECT_NEAR(at5, r.ref_5hz, 0.3) << r.label << " at 5 Hz/px";
  }
}

TEST(Baselines, AllRegisteredWithScoresAndPushSizeIndependent) {
  const std::uint64_t seed = 7;
  SCOPED_TRACE("seed " + std::to_string(seed));
  auto events = poisson_noise(20.0, 200'000, seed, 3);  // (hot pixels for `hotpixel`)
  for (const char* name : {"baf", "knoise", "ynoise", "stcf", "dwf", "hotpixel"}) {
    SCOPED_TRACE(name);
    ASSERT_NE(find_filter(name), nullptr);
    auto whole = make_filter(name, {}, kDavis346);
    EXPECT_TRUE(whole->has_score());
    const Decisions a = run_filter(*whole, events, 0);
    auto small = make_filter(name, {}, kDavis346);
    const Decisions b = run_filter(*small, events, 7);
    ASSERT_EQ(a.size(), events.size());
    EXPECT_EQ(a.keep, b.keep);
    EXPECT_EQ(a.score, b.score);
    // reset() gives a fresh filter.
    small->reset();
    const Decisions c = run_filter(*small, events, 1000);
    EXPECT_EQ(a.keep, c.keep);
    const std::size_t kept = count_kept(a);
    EXPECT_GT(kept, 0U);
    EXPECT_LT(kept, events.size());
  }
}

}  // namespace
}  // namespace evpipe::denoise
