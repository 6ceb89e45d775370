// ESR against the reference values of denoise.md §6.4 / §8.3 and its closed-form properties (§6.5).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <vector>

#include "evpipe/io/reader.hpp"
#include "evpipe/metrics/esr.hpp"
#include "evpipe/sim/noise.hpp"
#include "evpipe_test_data.hpp"

namespace evpipe::metrics {
namespace {

constexpr std::int64_t kN = 30'000;

// The golden patterns of denoise.md §6.4 (integer arithmetic in int64, t = i).
std::vector<Event> pattern(char which) {
  std::vector<Event> ev;
  ev.reserve(kN);
  for (std::int64_t i = 0; i < kN; ++i) {
    std::int64_t x = 0;
    std::int64_t y = 0;
    switch (which) {
      case 'A':
      case 'C':
        x = (i * i + 3 * i) % 346;
        y = (i * i * i + 7 * i) % 260;
        if (which == 'C' && i % 10 == 0) {
          x = 100;
          y = 100;
        }
        break;
      case 'B':
        x = i % 100;
        y = (i / 100) % 50;
        break;
      case 'D':
        x = i % 346;
        y = (i / 346) % 260;
        break;
      default:  // 'E'
        x = 5;
        y = 7;
        break;
    }
    ev.push_back({i, static_cast<std::uint16_t>(x), static_cast<std::uint16_t>(y), i % 2 == 0});
  }
  return ev;
}

TEST(Esr, GoldenVectorsOfTheReference) {
  struct Golden {
    char pattern;
    double reference;  // CUKE / dv-processing path, float32 (denoise.md §6.4)
  };
  for (const Golden g : {Golden{'A', 1.248745862}, Golden{'B', 0.912259746}, Golden{'C', 6.254750699}, Golden{'D', 0.0},
                         Golden{'E', 0.999999991}}) {
    const auto r = esr(pattern(g.pattern), kDavis346);
    ASSERT_TRUE(r.mean.has_value()) << g.pattern;
    ASSERT_EQ(r.chunks.size(), 1U) << g.pattern;
    EXPECT_NEAR(*r.mean, g.reference, 1e-5) << "pattern " << g.pattern;
    std::printf("ESR golden %c: %.9f (reference %.9f, diff %.2e)\n", g.pattern, *r.mean, g.reference,
                *r.mean - g.reference);
  }
}

TEST(Esr, Float64ColumnOfTheGoldenTable) {
  // The float64 re-implementation's column of §6.4: the same formula in double agrees to rounding.
  EXPECT_NEAR(*esr(pattern('A'), kDavis346).mean, 1.248746290, 1e-9);
  EXPECT_NEAR(*esr(pattern('B'), kDavis346).mean, 0.912259807, 1e-9);
  EXPECT_NEAR(*esr(pattern('C'), kDavis346).mean, 6.254754516, 1e-9);
  EXPECT_EQ(*esr(pattern('D'), kDavis346).mean, 0.0);
  EXPECT_NEAR(*esr(pattern('E'), kDavis346).mean, 1.0, 1e-12);
}

TEST(Esr, SinglePixelIsOneAllDistinctIsZero) {
  // One pixel: NTSS = 1, L = 1 − (1/3)^N = 1. Distinct pixels: NTSS = 0.
  EXPECT_NEAR(*esr(pattern('E'), kDavis346).mean, 1.0, 1e-12);
  EXPECT_EQ(*esr(pattern('D'), kDavis346).mean, 0.0);
}

TEST(Esr, HandComputedSmallBlock) {
  // N = 6 on a 4x1 sensor: counts {3, 2, 1, 0}; M = 4, q = 1/3.
  // NTSS = (6 + 2) / 30, L = (1 − q^3) + (1 − q^2) + (1 − q).
  const std::vector<Event> ev = {{0, 0, 0, true}, {1, 0, 0, true}, {2, 0, 0, false},
                                 {3, 1, 0, true}, {4, 1, 0, true}, {5, 2, 0, true}};
  const double q = 1.0 - 4.0 / 6.0;
  const double expected = std::sqrt(8.0 / 30.0 * ((1 - q * q * q) + (1 - q * q) + (1 - q)));
  const auto r = esr(ev, SensorGeometry{4, 1}, 6);
  ASSERT_TRUE(r.mean);
  EXPECT_NEAR(*r.mean, expected, 1e-15);
}

TEST(Esr, FewerThanOneBlockIsNotAvailable) {
  auto ev = pattern('E');
  ev.pop_back();  // 29 999 events
  const auto r = esr(ev, kDavis346);
  EXPECT_FALSE(r.mean.has_value());
  EXPECT_TRUE(r.chunks.empty());
  EXPECT_FALSE(esr({}, kDavis346).mean.has_value());
  EsrAccumulator acc(kDavis346);
  acc.add(ev);
  EXPECT_EQ(acc.remainder(), 29'999U);
  EXPECT_FALSE(acc.mean().has_value());
  acc.add(Event{kN, 5, 7, true});
  ASSERT_TRUE(acc.mean().has_value());
  EXPECT_NEAR(*acc.mean(), 1.0, 1e-12);
}

TEST(Esr, ChunksAreConsecutiveRemainderDroppedMeanOverChunks) {
  // Block 1 = one pixel (ESR 1), block 2 = all distinct (ESR 0), then 29 999 events of pattern C (dropped).
  std::vector<Event> ev = pattern('E');
  const auto d = pattern('D');
  ev.insert(ev.end(), d.begin(), d.end());
  auto c = pattern('C');
  c.pop_back();
  ev.insert(ev.end(), c.begin(), c.end());
  const auto r = esr(ev, kDavis346);
  ASSERT_EQ(r.chunks.size(), 2U);
  EXPECT_NEAR(r.chunks[0], 1.0, 1e-12);
  EXPECT_EQ(r.chunks[1], 0.0);
  EXPECT_NEAR(*r.mean, 0.5, 1e-12);
  // Same stream, blocks in the other order and shifted by one event: the counts must be reset between blocks.
  // One event in front (and one fewer at the end): block 1 = (9,9) once + 29 999 at (5,7); block 2 = the last
  // (5,7) event + the first 29 999 events of pattern D, which include (5,7) (its index 7·346 + 5 = 2 427), so
  // (5,7) holds 2 events and 29 998 pixels hold 1. Wrong if counts leaked between blocks.
  std::vector<Event> shifted = {Event{0, 9, 9, true}};
  shifted.insert(shifted.end(), ev.begin(), ev.end() - 1);
  const auto s = esr(shifted, kDavis346);
  ASSERT_EQ(s.chunks.size(), 2U);
  const double n = 30'000.0;
  const double q = 1.0 - 20'000.0 / n;
  const double b1 = std::sqrt(29'999.0 * 29'998.0 / (n * (n - 1)) * ((1 - std::pow(q, 29'999)) + (1 - q)));
  const double b2 = std::sqrt(2.0 / (n * (n - 1)) * ((1 - q * q) + 29'998 * (1 - q)));
  EXPECT_NEAR(s.chunks[0], b1, 1e-12);
  EXPECT_NEAR(s.chunks[1], b2, 1e-12);
}

TEST(Esr, StreamingInPiecesEqualsOneShot) {
  const std::uint64_t seed = 20240611;
  std::mt19937_64 rng(seed);
  std::vector<Event> ev = pattern('A');
  const auto c = pattern('C');
  ev.insert(ev.end(), c.begin(), c.end());
  ev.insert(ev.end(), c.begin(), c.begin() + 12'345);
  const auto whole = esr(ev, kDavis346);
  EsrAccumulator acc(kDavis346);
  std::size_t at = 0;
  while (at < ev.size()) {
    const std::size_t piece = std::min<std::size_t>(ev.size() - at, rng() % 7000);
    acc.add(EventSpan(ev).subspan(at, piece));
    at += piece;
  }
  ASSERT_EQ(acc.chunks(), 2U) << "seed " << seed;
  EXPECT_EQ(acc.chunk_values(), whole.chunks) << "seed " << seed;
  EXPECT_EQ(acc.remainder(), 12'345U);
  EXPECT_EQ(acc.events(), ev.size());
  acc.reset();
  EXPECT_EQ(acc.chunks(), 0U);
  acc.add(pattern('E'));
  EXPECT_NEAR(*acc.mean(), 1.0, 1e-12) << "reset clears the count map";
}

TEST(Esr, UniformPoissonNoiseIsAboutPointFourFour) {
  // E[ESR] ≈ sqrt(1 − exp(−M/K)) = 0.4465 for DAVIS346 (denoise.md §6.5), whatever the rate.
  const std::uint64_t seed = 7;
  std::mt19937_64 rng(seed);
  sim::NoiseOptions o;
  o.rate_hz_per_pixel = 5.0;
  const auto ev = sim::background_activity(kDavis346, 0, 2'000'000, o, rng);  // ~900 000 events, ~30 blocks
  const auto r = esr(ev, kDavis346);
  ASSERT_TRUE(r.mean) << "seed " << seed;
  EXPECT_GE(r.chunks.size(), 28U) << "seed " << seed;
  EXPECT_NEAR(*r.mean, std::sqrt(1.0 - std::exp(-20'000.0 / 89'960.0)), 0.002) << "seed " << seed;
  EXPECT_NEAR(*r.mean, 0.4465, 0.002) << "seed " << seed;
}

TEST(Esr, EventsOutsideTheSensorAreNotCounted) {
  EsrAccumulator acc(SensorGeometry{4, 4}, 3);
  acc.add(std::vector<Event>{{0, 4, 0, true}, {1, 0, 4, true}, {2, 1, 1, true}});
  EXPECT_EQ(acc.outside(), 2U);
  EXPECT_EQ(acc.events(), 1U);
  EXPECT_EQ(acc.chunks(), 0U);
}

TEST(Esr, RejectsDegenerateSetups) {
  EXPECT_THROW(EsrAccumulator(kDavis346, 2), std::invalid_argument);
  EXPECT_THROW(EsrAccumulator(SensorGeometry{0, 10}), std::invalid_argument);
  const std::vector<std::uint32_t> counts = {1, 2};
  EXPECT_THROW((void)esr_of_counts(counts, 4, 10), std::invalid_argument);  // counts sum to 3
  EXPECT_THROW((void)esr_of_counts(counts, 1, 10), std::invalid_argument);
}

TEST(Esr, RealEmlbDemoMatchesTheReferencePerChunk) {
  EVPIPE_REQUIRE_REAL(path, "emlb-demo-01/demo-01.aedat4");
  const auto batch = io::read_all(path);
  ASSERT_EQ(batch.events.size(), 319'512U);
  const auto r = esr(batch.events, kDavis346);
  // denoise.md §8.3: the reference's per-chunk values, printed to 4 decimals (hence 5e-5 of rounding) plus
  // the float32-vs-double difference (< 1e-5).
  const std::vector<double> reference = {1.0614, 1.0143, 0.9798, 0.9516, 1.0180,
                                         1.1340, 1.0561, 0.9926, 0.9556, 0.9699};
  // The same chunks to 9 decimals from a float32 replica of CUKE's _calc_esr (NumPy 2.4.6 pairwise sums over
  // float32 counts, events read with dv-processing 2.0.4; it reproduces the values above): within 1e-5.
  const std::vector<double> float32_replica = {1.061386231, 1.014295819, 0.979755603, 0.951619254, 1.018021583,
                                               1.134007840, 1.056065213, 0.992623704, 0.955641861, 0.969857338};
  ASSERT_EQ(r.chunks.size(), reference.size());
  for (std::size_t i = 0; i < reference.size(); ++i) {
    EXPECT_NEAR(r.chunks[i], reference[i], 6e-5) << "chunk " << i;
    EXPECT_NEAR(r.chunks[i], float32_replica[i], 1e-5) << "chunk " << i;
    std::printf("demo-01 chunk %zu: %.9f (reference %.4f, float32 replica %.9f, diff %.1e)\n", i, r.chunks[i],
                reference[i], float32_replica[i], r.chunks[i] - float32_replica[i]);
  }
  ASSERT_TRUE(r.mean);
  EXPECT_NEAR(*r.mean, 1.0133, 6e-5);
  EXPECT_NEAR(*r.mean, 1.0133274447, 1e-5);
}

}  // namespace
}  // namespace evpipe::metrics
