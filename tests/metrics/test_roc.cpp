// ROC AUC: hand-computed cases, ties, degenerate inputs, and a brute-force pair count on random scores.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <vector>

#include "evpipe/metrics/roc.hpp"

namespace evpipe::metrics {
namespace {

constexpr Label S = Label::signal;
constexpr Label N = Label::noise;

// Mann–Whitney by definition: every (signal, noise) pair, ties one half.
double brute_force_auc(const std::vector<float>& scores, const std::vector<Label>& labels) {
  double wins = 0;
  double pairs = 0;
  for (std::size_t i = 0; i < scores.size(); ++i) {
    if (labels[i] != S) continue;
    for (std::size_t j = 0; j < scores.size(); ++j) {
      if (labels[j] != N) continue;
      pairs += 1;
      wins += scores[i] > scores[j] ? 1.0 : scores[i] == scores[j] ? 0.5 : 0.0;
    }
  }
  return wins / pairs;
}

TEST(RocAuc, PerfectInvertedAndHandComputed) {
  EXPECT_DOUBLE_EQ(*roc_auc(std::vector<float>{3, 4, 1, 2}, std::vector<Label>{S, S, N, N}), 1.0);
  EXPECT_DOUBLE_EQ(*roc_auc(std::vector<float>{1, 2, 3, 4}, std::vector<Label>{S, S, N, N}), 0.0);
  // Signal {0.9, 0.4}, noise {0.5, 0.1, 0.3}: pairs won 3 + 2 = 5 of 6.
  EXPECT_DOUBLE_EQ(*roc_auc(std::vector<float>{0.9F, 0.5F, 0.4F, 0.1F, 0.3F}, std::vector<Label>{S, N, S, N, N}),
                   5.0 / 6.0);
}

TEST(RocAuc, TiesCountOneHalf) {
  // All scores equal: 0.5. Signal {2, 1}, noise {1, 0}: pairs (2,1) 1, (2,0) 1, (1,1) 0.5, (1,0) 1 → 3.5 / 4.
  EXPECT_DOUBLE_EQ(*roc_auc(std::vector<float>{7, 7, 7}, std::vector<Label>{S, N, N}), 0.5);
  EXPECT_DOUBLE_EQ(*roc_auc(std::vector<float>{2, 1, 1, 0}, std::vector<Label>{S, S, N, N}), 3.5 / 4.0);
  // -0 and +0 are one score; NaN is the lowest score, tied with -infinity.
  EXPECT_DOUBLE_EQ(*roc_auc(std::vector<float>{-0.0F, 0.0F}, std::vector<Label>{S, N}), 0.5);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  EXPECT_DOUBLE_EQ(*roc_auc(std::vector<float>{nan, -inf, -1e30F}, std::vector<Label>{S, N, S}), 0.75);
}

TEST(RocAuc, OneClassIsNotAvailable) {
  EXPECT_FALSE(roc_auc(std::vector<float>{1, 2}, std::vector<Label>{S, S}).has_value());
  EXPECT_FALSE(roc_auc(std::vector<float>{1, 2}, std::vector<Label>{N, N}).has_value());
  EXPECT_FALSE(roc_auc({}, {}).has_value());
  EXPECT_THROW((void)roc_auc(std::vector<float>{1}, std::vector<Label>{}), std::invalid_argument);
}

TEST(RocAuc, MatchesBruteForceOnRandomScores) {
  const std::uint64_t seed = 99;
  std::mt19937_64 rng(seed);
  std::vector<float> scores;
  std::vector<Label> labels;
  for (int i = 0; i < 3000; ++i) {
    const bool signal = rng() % 3 == 0;
    // Integer-valued scores: many ties; signal shifted up.
    scores.push_back(static_cast<float>(rng() % 40 + (signal ? 8 : 0)));
    labels.push_back(signal ? S : N);
  }
  const auto auc = roc_auc(scores, labels);
  ASSERT_TRUE(auc) << "seed " << seed;
  EXPECT_NEAR(*auc, brute_force_auc(scores, labels), 1e-12) << "seed " << seed;
}

TEST(RocAuc, LargeStreamsMergeExactly) {
  // Enough events to merge the buffer several times, fed in pieces: the result equals a rank-based count.
  const std::uint64_t seed = 5;
  std::mt19937_64 rng(seed);
  AucAccumulator acc;
  std::vector<std::uint64_t> signal_at(1000, 0);
  std::vector<std::uint64_t> noise_at(1000, 0);
  for (int i = 0; i < 300'000; ++i) {
    const bool signal = rng() % 2 == 0;
    const unsigned v = static_cast<unsigned>(rng() % 700 + (signal ? 300 : 0));
    acc.add(static_cast<float>(v), signal ? S : N);
    (signal ? signal_at : noise_at)[v]++;
  }
  double wins = 0;
  double noise_below = 0;
  double p = 0;
  double n = 0;
  for (std::size_t v = 0; v < 1000; ++v) {
    wins += static_cast<double>(signal_at[v]) * (noise_below + 0.5 * static_cast<double>(noise_at[v]));
    noise_below += static_cast<double>(noise_at[v]);
    p += static_cast<double>(signal_at[v]);
    n += static_cast<double>(noise_at[v]);
  }
  EXPECT_EQ(acc.signal() + acc.noise(), 300'000U);
  EXPECT_EQ(acc.distinct_scores(), 1000U) << "seed " << seed;
  EXPECT_NEAR(*acc.auc(), wins / (p * n), 1e-12) << "seed " << seed;
  acc.reset();
  EXPECT_FALSE(acc.auc().has_value());
}

}  // namespace
}  // namespace evpipe::metrics
