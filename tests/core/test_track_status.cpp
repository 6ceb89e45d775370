// The one tracking-status type: names, values in order, and the value -> status lookup the codec decodes with.
#include "evpipe/core/track_status.hpp"

#include <gtest/gtest.h>

namespace evpipe {
namespace {

static_assert(to_string(TrackStatus::tracking) == "tracking");
static_assert(track_status_from_value(3) == TrackStatus::holding);

TEST(TrackStatus, NamesAndValues) {
  EXPECT_EQ(to_string(TrackStatus::initialising), "initialising");
  EXPECT_EQ(to_string(TrackStatus::tracking), "tracking");
  EXPECT_EQ(to_string(TrackStatus::lost), "lost");
  EXPECT_EQ(to_string(TrackStatus::holding), "holding");
  for (std::size_t i = 0; i < kTrackStatuses.size(); ++i) {
    EXPECT_EQ(static_cast<std::size_t>(kTrackStatuses[i]), i);
    EXPECT_EQ(track_status_from_value(static_cast<int>(i)), kTrackStatuses[i]);
    EXPECT_NE(to_string(kTrackStatuses[i]), "?");
  }
}

TEST(TrackStatus, OtherValuesAreNoStatus) {
  for (const int v : {-128, -1, 4, 7, 127, 255}) {
    EXPECT_FALSE(track_status_from_value(v).has_value()) << v;
  }
}

}  // namespace
}  // namespace evpipe
