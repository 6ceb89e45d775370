// YNoise, CUKE semantics: density over the L×L window including the own pixel, same polarity, inclusive time.
#include <gtest/gtest.h>

#include <stdexcept>

#include "evpipe/denoise/ynoise.hpp"

namespace evpipe::denoise {
namespace {

constexpr YnoiseOptions kNever{10'000, 3, 1, false};

TEST(Ynoise, OwnPixelCountsAndTheTimeTestIsInclusive) {
  Ynoise f(kDavis346, kNever);
  EXPECT_FALSE(f.accept({100'000, 50, 50, true}));
  EXPECT_TRUE(f.accept({110'000, 50, 50, true}));  // its own previous event, exactly 10 ms ago
  EXPECT_FLOAT_EQ(f.last_score(), 1.0F);
  EXPECT_FALSE(f.accept({120'001, 50, 50, true}));  // 10 001 us
}

TEST(Ynoise, PolarityMustMatchAndOnlyTheLastEventOfAPixelCounts) {
  Ynoise f(kDavis346, kNever);
  EXPECT_FALSE(f.accept({100'000, 50, 50, true}));
  EXPECT_FALSE(f.accept({100'100, 51, 50, false}));  // (50,50) is ON
  EXPECT_TRUE(f.accept({100'200, 50, 50, false}));   // (51,50) OFF supports; (50,50) becomes OFF
  EXPECT_FALSE(f.accept({100'300, 49, 50, true}));   // the ON event of (50,50) was overwritten
}

TEST(Ynoise, WindowSideAndThreshold) {
  Ynoise l3(kDavis346, kNever);
  Ynoise l5(kDavis346, {10'000, 5, 1, false});
  Ynoise thr2(kDavis346, {10'000, 3, 2, false});
  for (Ynoise* f : {&l3, &l5, &thr2}) {
    EXPECT_FALSE(f->accept({100'000, 50, 50, true}));
  }
  EXPECT_FALSE(l3.accept({100'100, 52, 52, true}));    // 2 px away: outside 3×3
  EXPECT_TRUE(l5.accept({100'100, 52, 52, true}));     // inside 5×5
  EXPECT_FALSE(thr2.accept({100'100, 51, 51, true}));  // density 1 < 2
  EXPECT_TRUE(thr2.accept({100'200, 51, 50, true}));   // (50,50) and (51,51)
  EXPECT_FLOAT_EQ(thr2.last_score(), 2.0F);
}

TEST(Ynoise, StartUpArtefactAndClippedWindowAtTheBorders) {
  // init zero (CUKE): every pixel starts as an OFF event at t = 0.
  Ynoise zero(kDavis346, {10'000, 3, 1, true});
  EXPECT_TRUE(zero.accept({10'000, 100, 100, false}));  // 9 untouched pixels, t - 0 <= 10 000
  EXPECT_FLOAT_EQ(zero.last_score(), 9.0F);
  EXPECT_FALSE(zero.accept({10'000, 200, 200, true}));   // ON: no support from the OFF start state
  EXPECT_FALSE(zero.accept({10'001, 300, 100, false}));  // too late for the start state
  // At a corner only the 4 pixels inside the sensor count, at an edge 6.
  Ynoise corner(kDavis346, {10'000, 3, 5, true});
  EXPECT_FALSE(corner.accept({100, 0, 0, false}));
  EXPECT_FLOAT_EQ(corner.last_score(), 4.0F);
  EXPECT_FALSE(corner.accept({100, 345, 259, false}));
  EXPECT_FLOAT_EQ(corner.last_score(), 4.0F);
  EXPECT_TRUE(corner.accept({100, 345, 100, false}));
  EXPECT_FLOAT_EQ(corner.last_score(), 6.0F);
  // init never: no start-up artefact.
  Ynoise never(kDavis346, kNever);
  EXPECT_FALSE(never.accept({10'000, 100, 100, false}));
  EXPECT_FALSE(never.accept({10'000, 346, 0, false}));  // outside the sensor
}

TEST(Ynoise, SpecDefaultsAndValidation) {
  const auto params = describe(ynoise_spec());
  ASSERT_EQ(params.size(), 4U);
  EXPECT_EQ(params[0].key, "duration_us");
  EXPECT_EQ(params[0].default_value, "10000");
  EXPECT_EQ(params[1].key, "L");
  EXPECT_EQ(params[1].default_value, "3");
  EXPECT_EQ(params[2].key, "threshold");
  EXPECT_EQ(params[2].default_value, "1");
  EXPECT_EQ(params[3].key, "init");
  EXPECT_EQ(params[3].default_value, "zero");
  EXPECT_NO_THROW((void)make_filter("ynoise", {{"L", "5"}, {"threshold", "25"}, {"init", "never"}}, kDavis346));
  for (const auto& [key, value] : std::vector<std::pair<std::string, std::string>>{{"duration_us", "-5"},
                                                                                   {"L", "4"},
                                                                                   {"L", "0"},
                                                                                   {"L", "33"},
                                                                                   {"threshold", "0"},
                                                                                   {"threshold", "10"},
                                                                                   {"init", "one"}}) {
    try {
      (void)make_filter("ynoise", {{key, value}}, kDavis346);
      ADD_FAILURE() << key << "=" << value << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("ynoise: " + key + "=" + value), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace evpipe::denoise
