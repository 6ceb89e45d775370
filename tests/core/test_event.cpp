#include <gtest/gtest.h>

#include <vector>

#include "evpipe/core/event.hpp"

using evpipe::Event;
using evpipe::EventSpan;

namespace {

std::vector<Event> at_times(std::initializer_list<std::int64_t> times) {
  std::vector<Event> ev;
  for (const std::int64_t t : times) ev.push_back({t, static_cast<std::uint16_t>(t % 7), 3, true});
  return ev;
}

std::vector<std::int64_t> times_of(EventSpan ev) {
  std::vector<std::int64_t> t;
  for (const Event& e : ev) t.push_back(e.t_us);
  return t;
}

}  // namespace

TEST(EventsAfter, TimeOrderedGivesTheSuffixWithoutCopying) {
  const auto ev = at_times({5, 10, 10, 10, 12, 20});
  std::vector<Event> scratch;
  const EventSpan later = evpipe::events_after(ev, 10, scratch);  // strictly later: the 10s are not
  EXPECT_EQ(times_of(later), (std::vector<std::int64_t>{12, 20}));
  EXPECT_EQ(later.data(), ev.data() + 4);
  EXPECT_TRUE(scratch.empty());
  EXPECT_EQ(evpipe::events_after(ev, 4, scratch).size(), ev.size());
  EXPECT_TRUE(evpipe::events_after(ev, 20, scratch).empty());
  EXPECT_TRUE(evpipe::events_after({}, 0, scratch).empty());
}

TEST(EventsAfter, AnEarlierEventAfterALaterOneIsLeftOutAndTheRestCopiedInOrder) {
  // A source that keeps small backward jumps (source.drop_out_of_order: false).
  const auto ev = at_times({5, 12, 9, 15, 11, 8});
  std::vector<Event> scratch;
  const EventSpan later = evpipe::events_after(ev, 10, scratch);
  EXPECT_EQ(times_of(later), (std::vector<std::int64_t>{12, 15, 11}));
  EXPECT_EQ(later.data(), scratch.data());
}

TEST(AppendBounded, DropsTheOldestBeyondTheCapOrTooOldBeforeAppending) {
  std::vector<Event> held = at_times({1, 2, 3});
  evpipe::append_bounded(held, at_times({4, 5}), 10, 0);  // within both bounds: everything stays
  EXPECT_EQ(times_of(held), (std::vector<std::int64_t>{1, 2, 3, 4, 5}));
  evpipe::append_bounded(held, at_times({6, 7}), 4, 0);  // the cap drops held's oldest
  EXPECT_EQ(times_of(held), (std::vector<std::int64_t>{4, 5, 6, 7}));
  evpipe::append_bounded(held, at_times({8}), 10, 6);  // too old: 4 and 5
  EXPECT_EQ(times_of(held), (std::vector<std::int64_t>{6, 7, 8}));
  evpipe::append_bounded(held, at_times({9, 10, 11, 12}), 2, 0);  // fresh alone exceeds the cap: its newest
  EXPECT_EQ(times_of(held), (std::vector<std::int64_t>{11, 12}));
  evpipe::append_bounded(held, {}, 10, 100);  // all too old
  EXPECT_TRUE(held.empty());
  held = at_times({1, 2, 3, 4});
  const std::size_t cap4 = held.capacity();
  evpipe::append_bounded(held, at_times({5, 6}), 4, 0);  // trimmed first: no growth past what is kept
  EXPECT_EQ(times_of(held), (std::vector<std::int64_t>{3, 4, 5, 6}));
  EXPECT_EQ(held.capacity(), cap4);
}
