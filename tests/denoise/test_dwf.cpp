// DWF: CUKE (default, windows pre-filled at (0,0)) and jAER (windows filled by the first events) variants.
#include <gtest/gtest.h>

#include <stdexcept>

#include "evpipe/denoise/dwf.hpp"

namespace evpipe::denoise {
namespace {

DwfOptions cuke(int buffer = 36, int radius = 9, int threshold = 1) {
  return {DwfOptions::Variant::cuke, buffer, radius, threshold};
}

TEST(Dwf, CukePrefillSupportsEventsNearTheOrigin) {
  Dwf f(kDavis346, cuke());
  EXPECT_TRUE(f.accept({0, 4, 5, true}));  // L1 9 from (0,0): all 72 pre-filled entries support
  EXPECT_FLOAT_EQ(f.last_score(), 72.0F);
  Dwf g(kDavis346, cuke());
  EXPECT_FALSE(g.accept({0, 5, 5, false}));  // L1 10
  EXPECT_FLOAT_EQ(g.last_score(), 0.0F);
}

TEST(Dwf, DecisionsFeedTheirWindowAndFlushIt) {
  Dwf f(kDavis346, cuke());
  EXPECT_FALSE(f.accept({0, 100, 100, true}));  // noise window: 35 × (0,0) + (100,100)
  for (int i = 0; i < 36; ++i) {                // each supported by (100,100) or the previous ones
    EXPECT_TRUE(f.accept({i + 1, 100, static_cast<std::uint16_t>(101 + i % 5), true})) << i;
  }
  // The signal window no longer holds (0,0); the noise window still holds 35 of them.
  EXPECT_TRUE(f.accept({100, 3, 3, true}));
  EXPECT_FLOAT_EQ(f.last_score(), 35.0F);
}

TEST(Dwf, InclusiveL1RadiusAndThreshold) {
  Dwf f(kDavis346, cuke(4, 3, 2));               // the (0,0) pre-fill is far from everything below
  EXPECT_FALSE(f.accept({0, 100, 200, true}));   // noise
  EXPECT_FALSE(f.accept({10, 100, 203, true}));  // only (100,200) within L1 3: 1 < 2
  EXPECT_TRUE(f.accept({11, 101, 202, true}));   // (100,200) at 3 and (100,203) at 2
  EXPECT_FLOAT_EQ(f.last_score(), 2.0F);
  EXPECT_FALSE(f.accept({12, 104, 200, true}));  // (101,202) at 5, (100,200) at 4: none
}

TEST(Dwf, JaerFillsItsWindowsWithTheFirstEvents) {
  Dwf f(kDavis346, {DwfOptions::Variant::jaer, 3, 4, 1});
  // The first 2 × 3 events are dropped; the signal window keeps the first 3, the next 3 are forgotten (jAER
  // compares only the first half of the array it filled).
  EXPECT_FALSE(f.accept({0, 100, 100, true}));
  EXPECT_FALSE(f.accept({1, 200, 100, true}));
  EXPECT_FALSE(f.accept({2, 50, 50, true}));
  EXPECT_FALSE(f.accept({3, 300, 100, true}));
  EXPECT_FALSE(f.accept({4, 300, 200, true}));
  EXPECT_FALSE(f.accept({5, 250, 50, true}));
  EXPECT_FLOAT_EQ(f.last_score(), -1.0F);
  EXPECT_FALSE(f.accept({6, 301, 101, true}));  // (300,100) was forgotten
  EXPECT_TRUE(f.accept({7, 102, 102, true}));   // (100,100) at L1 4
  EXPECT_FALSE(f.accept({8, 205, 100, true}));  // (200,100) at L1 5: jAER's disThr 5 is strict
  EXPECT_TRUE(f.accept({9, 1, 0, true}));       // the noise window started full of (-1,-1): L1 3
  EXPECT_FLOAT_EQ(f.last_score(), 1.0F);        // one (-1,-1) left, two were pushed out
}

TEST(Dwf, SpecDefaultsDependOnTheVariantAndAreValidated) {
  const auto params = describe(dwf_spec());
  ASSERT_EQ(params.size(), 4U);
  EXPECT_EQ(params[0].key, "variant");
  EXPECT_EQ(params[0].default_value, "cuke");
  EXPECT_EQ(params[1].key, "buffer");
  EXPECT_EQ(params[1].default_value, "36");
  EXPECT_EQ(params[2].key, "l1_radius");
  EXPECT_EQ(params[2].default_value, "9");
  EXPECT_EQ(params[3].key, "threshold");
  EXPECT_EQ(params[3].default_value, "1");
  EXPECT_NO_THROW((void)make_filter("dwf", {{"variant", "jaer"}}, kDavis346));
  EXPECT_THROW((void)make_filter("dwf", {}, SensorGeometry{9000, 10}), std::invalid_argument);  // int16 positions
  for (const auto& [key, value] : std::vector<std::pair<std::string, std::string>>{
           {"buffer", "0"}, {"l1_radius", "-1"}, {"threshold", "0"}, {"threshold", "73"}, {"variant", "x"}}) {
    try {
      (void)make_filter("dwf", {{key, value}}, kDavis346);
      ADD_FAILURE() << key << "=" << value << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("dwf: " + key + "=" + value), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace evpipe::denoise
