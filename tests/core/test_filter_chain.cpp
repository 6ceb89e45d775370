#include <gtest/gtest.h>

#include <string_view>
#include <vector>

#include "evpipe/core/filter_chain.hpp"

TEST(FilterChainNames, SplitsOnCommasKeepingEmptyParts) {
  using V = std::vector<std::string_view>;
  EXPECT_EQ(evpipe::filter_chain_names("curvature"), V{"curvature"});
  EXPECT_EQ(evpipe::filter_chain_names("hotpixel,curvature"), (V{"hotpixel", "curvature"}));
  EXPECT_EQ(evpipe::filter_chain_names("a,,b"), (V{"a", "", "b"}));
  EXPECT_EQ(evpipe::filter_chain_names(""), V{""});
  EXPECT_EQ(evpipe::filter_chain_names("a,"), (V{"a", ""}));
}
