// BAF with dv-processing 2.0.4 semantics. Exact equality with dv-processing on the real recordings is in
// test_dv_equality.cpp.
#include <gtest/gtest.h>

#include "evpipe/denoise/baf.hpp"

namespace evpipe::denoise {
namespace {

TEST(Baf, NeighbourWithinDurationSupportsOwnPixelDoesNot) {
  Baf f(kDavis346, {2000, false});
  EXPECT_FALSE(f.accept({10'000, 50, 50, true}));  // nothing before
  EXPECT_FALSE(f.accept({10'500, 50, 50, true}));  // own pixel does not count
  EXPECT_TRUE(f.accept({11'000, 51, 51, false}));  // diagonal neighbour 500 us ago, polarity ignored
  EXPECT_FALSE(f.accept({13'000, 52, 52, true}));  // neighbour (51,51) exactly 2000 us ago: strict <
  EXPECT_TRUE(f.accept({13'001, 51, 51, true}));   // (52,52) 1 us ago
  EXPECT_FALSE(f.accept({13'002, 60, 60, true}));  // far away
}

TEST(Baf, ZeroInitLetsEarlyEventsThrough) {
  Baf dv(kDavis346, {2000, true});
  EXPECT_TRUE(dv.accept({1999, 0, 0, true}));  // corner pixel: outside neighbours are skipped, inside ones are 0
  EXPECT_FALSE(dv.accept({2000, 200, 200, true}));
  Baf never(kDavis346, {2000, false});
  EXPECT_FALSE(never.accept({1999, 0, 0, true}));
}

}  // namespace
}  // namespace evpipe::denoise
