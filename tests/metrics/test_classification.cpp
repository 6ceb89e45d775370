// Confusion counts and the ratios derived from them, on hand-made decisions.
#include <gtest/gtest.h>

#include <stdexcept>
#include <vector>

#include "evpipe/metrics/classification.hpp"

namespace evpipe::metrics {
namespace {

constexpr Label S = Label::signal;
constexpr Label N = Label::noise;

TEST(Classification, CountsAndRatiosByHand) {
  // 4 signal: 3 kept, 1 removed; 6 noise: 2 kept, 4 removed.
  const std::vector<std::uint8_t> keep = {1, 1, 1, 0, 1, 1, 0, 0, 0, 0};
  const std::vector<Label> labels = {S, S, S, S, N, N, N, N, N, N};
  const Classification c = classify(keep, labels);
  EXPECT_EQ(c.events_in, 10U);
  EXPECT_EQ(c.events_kept, 5U);
  EXPECT_EQ(c.events_removed(), 5U);
  ASSERT_TRUE(c.confusion);
  EXPECT_EQ(*c.confusion, (Confusion{3, 2, 4, 1}));
  EXPECT_EQ(c.confusion->signal(), 4U);
  EXPECT_EQ(c.confusion->noise(), 6U);
  EXPECT_DOUBLE_EQ(*signal_retention(*c.confusion), 3.0 / 4.0);
  EXPECT_DOUBLE_EQ(*noise_removal(*c.confusion), 4.0 / 6.0);
  EXPECT_DOUBLE_EQ(*precision(*c.confusion), 3.0 / 5.0);
  EXPECT_DOUBLE_EQ(*f1(*c.confusion), 6.0 / (6.0 + 2.0 + 1.0));  // = 2PR/(P+R) with P = 0.6, R = 0.75
  EXPECT_DOUBLE_EQ(*c.nrr(), 0.5);
  EXPECT_DOUBLE_EQ(*c.kept_fraction(), 0.5);
}

TEST(Classification, StreamingEqualsOneShot) {
  const std::vector<std::uint8_t> keep = {1, 0, 0, 1, 1, 0, 1};
  const std::vector<Label> labels = {S, N, S, N, S, N, N};
  ClassificationCounter counter;
  counter.add(std::span(keep).first(3), std::span(labels).first(3));
  counter.add(std::span(keep).subspan(3, 0), std::span(labels).subspan(3, 0));
  counter.add(std::span(keep).subspan(3), std::span(labels).subspan(3));
  const Classification whole = classify(keep, labels);
  EXPECT_EQ(counter.result().events_in, whole.events_in);
  EXPECT_EQ(counter.result().events_kept, whole.events_kept);
  EXPECT_EQ(counter.result().confusion, whole.confusion);
  EXPECT_EQ(*whole.confusion, (Confusion{2, 2, 2, 1}));
}

TEST(Classification, UnlabelledHasOnlyKeptAndNrr) {
  const std::vector<std::uint8_t> keep = {1, 0, 0, 0};
  const Classification c = classify(keep);
  EXPECT_FALSE(c.confusion.has_value());
  EXPECT_DOUBLE_EQ(*c.nrr(), 0.75);
  // Labelled then unlabelled: the confusion matrix would cover part of the stream only, so none.
  ClassificationCounter counter;
  const std::vector<Label> labels = {S, S, N, N};
  counter.add(keep, labels);
  ASSERT_TRUE(counter.result().confusion);
  counter.add(keep);
  EXPECT_FALSE(counter.result().confusion.has_value());
  EXPECT_EQ(counter.result().events_in, 8U);
  counter.reset();
  EXPECT_EQ(counter.result().events_in, 0U);
  EXPECT_TRUE(counter.result().confusion.has_value());
}

TEST(Classification, UndefinedRatiosAreNotAvailable) {
  EXPECT_FALSE(classify({}).nrr().has_value());
  // Pure noise, everything removed: SR, precision and F1 undefined, NR = 1.
  const std::vector<std::uint8_t> keep = {0, 0, 0};
  const std::vector<Label> labels = {N, N, N};
  const Classification c = classify(keep, labels);
  EXPECT_FALSE(signal_retention(*c.confusion));
  EXPECT_FALSE(precision(*c.confusion));
  EXPECT_FALSE(f1(*c.confusion));
  EXPECT_DOUBLE_EQ(*noise_removal(*c.confusion), 1.0);
  EXPECT_DOUBLE_EQ(*c.nrr(), 1.0);
  // Pure signal, all removed: precision undefined, F1 = 0 (FN > 0).
  const std::vector<Label> sig = {S, S, S};
  const Classification d = classify(keep, sig);
  EXPECT_DOUBLE_EQ(*signal_retention(*d.confusion), 0.0);
  EXPECT_FALSE(precision(*d.confusion));
  EXPECT_DOUBLE_EQ(*f1(*d.confusion), 0.0);
  EXPECT_FALSE(noise_removal(*d.confusion));
}

TEST(Classification, RejectsMismatchedLabels) {
  const std::vector<std::uint8_t> keep = {1, 0};
  const std::vector<Label> labels = {S};
  ClassificationCounter counter;
  EXPECT_THROW(counter.add(keep, labels), std::invalid_argument);
}

}  // namespace
}  // namespace evpipe::metrics
