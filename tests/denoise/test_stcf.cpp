// STCF, jAER SpatioTemporalCorrelationFilter semantics (strict time test, k correlated neighbours, first event at
// a pixel dropped), with correct clipping at every border.
#include <gtest/gtest.h>

#include <map>
#include <stdexcept>

#include "evpipe/denoise/stcf.hpp"

namespace evpipe::denoise {
namespace {

StcfOptions opts(int k, std::int64_t tau_us) {
  StcfOptions o;
  o.k = k;
  o.tau_us = tau_us;
  return o;
}

TEST(Stcf, FirstEventAtAPixelIsDroppedUnlessLetThrough) {
  Stcf f(kDavis346, opts(1, 25'000));
  EXPECT_FALSE(f.accept({100'000, 50, 50, true}));
  EXPECT_FALSE(f.accept({100'100, 51, 50, true}));  // supported by (50,50), but its first event
  EXPECT_FLOAT_EQ(f.last_score(), -1.0F);
  EXPECT_TRUE(f.accept({100'200, 51, 50, true}));  // now (50,50) supports (own pixel not counted)
  EXPECT_FLOAT_EQ(f.last_score(), 1.0F);
  StcfOptions o = opts(1, 25'000);
  o.let_first_event_through = true;
  Stcf g(kDavis346, o);
  EXPECT_TRUE(g.accept({100'000, 50, 50, true}));
}

TEST(Stcf, NeedsKCorrelatedNeighboursWithAStrictTimeTest) {
  Stcf f(kDavis346, opts(2, 10'000));
  // Prime three pixels (each first event is dropped), then give them a second event.
  for (const std::uint16_t x : {49, 50, 51}) {
    EXPECT_FALSE(f.accept({100'000, x, 60, true}));
  }
  EXPECT_FALSE(f.accept({100'000, 50, 61, true}));  // first event of (50,61)
  EXPECT_TRUE(f.accept({105'000, 50, 61, true}));   // (49,60), (50,60), (51,60): 3 >= 2
  EXPECT_FLOAT_EQ(f.last_score(), 3.0F);
  EXPECT_FALSE(f.accept({110'000, 50, 61, true}));  // those are exactly 10 000 us old: strict <; own pixel excluded
  EXPECT_FLOAT_EQ(f.last_score(), 0.0F);
}

TEST(Stcf, OwnPixelAndPolarityOptions) {
  StcfOptions own = opts(1, 10'000);
  own.filter_hot_pixels = false;
  Stcf with_own(kDavis346, own);
  Stcf without_own(kDavis346, opts(1, 10'000));
  for (Stcf* f : {&with_own, &without_own}) {
    EXPECT_FALSE(f->accept({100'000, 50, 50, true}));
  }
  EXPECT_TRUE(with_own.accept({100'500, 50, 50, true}));
  EXPECT_FALSE(without_own.accept({100'500, 50, 50, true}));

  StcfOptions any = opts(1, 10'000);
  any.polarity_match = false;
  Stcf any_pol(kDavis346, any);
  Stcf same_pol(kDavis346, opts(1, 10'000));
  for (Stcf* f : {&any_pol, &same_pol}) {
    EXPECT_FALSE(f->accept({100'000, 50, 50, true}));
    EXPECT_FALSE(f->accept({100'000, 51, 50, false}));
    EXPECT_FALSE(f->accept({100'010, 52, 50, true}));  // first event of (52,50)
  }
  EXPECT_TRUE(any_pol.accept({100'100, 51, 50, true}));  // (50,50) and (52,50) ON
  EXPECT_TRUE(same_pol.accept({100'100, 51, 50, true}));
  EXPECT_TRUE(any_pol.accept({100'200, 51, 50, false}));    // any polarity
  EXPECT_FALSE(same_pol.accept({100'200, 51, 50, false}));  // its neighbours are ON
}

TEST(Stcf, BordersAreClippedNotShrunk) {
  // jAER shrinks the block at the right and bottom borders; here (345, y±1) support (345, y) as anywhere else.
  Stcf f(kDavis346, opts(2, 10'000));
  EXPECT_FALSE(f.accept({100'000, 345, 99, true}));
  EXPECT_FALSE(f.accept({100'000, 345, 101, true}));
  EXPECT_FALSE(f.accept({100'000, 345, 100, true}));  // first event
  EXPECT_TRUE(f.accept({100'100, 345, 100, true}));
  EXPECT_FALSE(f.accept({100'000, 0, 259, true}));
  EXPECT_FALSE(f.accept({100'000, 1, 259, true}));
  EXPECT_FALSE(f.accept({100'000, 0, 258, true}));
  EXPECT_TRUE(f.accept({100'100, 0, 259, true}));
  EXPECT_FALSE(f.accept({100'200, 0, 260, true}));  // outside the sensor
}

TEST(Stcf, LargerRadius) {
  StcfOptions o = opts(1, 10'000);
  o.radius = 2;
  Stcf f(kDavis346, o);
  EXPECT_FALSE(f.accept({100'000, 50, 50, true}));
  EXPECT_FALSE(f.accept({100'000, 52, 48, true}));
  EXPECT_TRUE(f.accept({100'100, 52, 48, true}));  // (50,50) is 2 px away in x and y
}

TEST(Stcf, SpecDefaultsAndValidation) {
  const auto params = describe(stcf_spec());
  std::map<std::string, std::string> defaults;
  for (const auto& p : params) {
    defaults[p.key] = p.default_value;
  }
  EXPECT_EQ(defaults["k"], "2");
  EXPECT_EQ(defaults["tau_us"], "25000");
  EXPECT_EQ(defaults["polarity_match"], "true");
  EXPECT_EQ(defaults["filter_hot_pixels"], "true");
  EXPECT_EQ(defaults["let_first_event_through"], "false");
  EXPECT_EQ(defaults["radius"], "1");
  EXPECT_NO_THROW((void)make_filter("stcf", {{"k", "9"}, {"filter_hot_pixels", "false"}}, kDavis346));
  for (const auto& [key, value] : std::vector<std::pair<std::string, std::string>>{
           {"tau_us", "-1"}, {"k", "0"}, {"k", "9"}, {"radius", "0"}, {"polarity_match", "maybe"}}) {
    try {
      (void)make_filter("stcf", {{key, value}}, kDavis346);
      ADD_FAILURE() << key << "=" << value << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("stcf: " + key + "=" + value), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace evpipe::denoise
