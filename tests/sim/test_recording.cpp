#include <gtest/gtest.h>

#include "evpipe/sim/recording.hpp"

using namespace evpipe;

TEST(MergeLabelled, TimeOrderSignalFirstAtEqualTimes) {
  const std::vector<Event> signal = {{10, 1, 1, true}, {20, 2, 2, false}, {30, 3, 3, true}};
  const std::vector<Event> noise = {{5, 9, 9, false}, {20, 8, 8, true}, {40, 7, 7, true}};
  const auto rec = sim::merge_labelled(signal, noise);
  ASSERT_EQ(rec.events.size(), 6U);
  ASSERT_EQ(rec.labels.size(), 6U);
  const std::vector<std::int64_t> t = {5, 10, 20, 20, 30, 40};
  const std::vector<Label> l = {Label::noise, Label::signal, Label::signal, Label::noise, Label::signal, Label::noise};
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_EQ(rec.events[i].t_us, t[i]) << i;
    EXPECT_EQ(rec.labels[i], l[i]) << i;
  }
  EXPECT_EQ(rec.events[2].x, 2);  // the signal event of t = 20
}

TEST(EventFrame, LastPolarityInTheWindowWins) {
  const SensorGeometry g{4, 3};
  const std::vector<Event> ev = {{0, 0, 0, true},  {10, 1, 1, true},  {15, 1, 1, false},
                                 {19, 3, 2, true}, {20, 2, 2, false}, {25, 9, 9, true}};
  const auto f = sim::event_frame(ev, g, 10, 20);  // [10, 20): not t = 0, not t = 20; (9, 9) is outside
  ASSERT_EQ(f.size(), 12U);
  std::vector<std::int8_t> expected(12, 0);
  expected[1 * 4 + 1] = -1;
  expected[2 * 4 + 3] = 1;
  EXPECT_EQ(f, expected);
}
