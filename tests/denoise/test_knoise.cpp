// KNoise: dv-processing 2.0.4 semantics (default) and the CUKE variant. Exact equality with dv-processing on the
// real recordings is in test_dv_equality.cpp; per-event equality in tools/check_denoise_dv.py.
#include <gtest/gtest.h>

#include <stdexcept>

#include "evpipe/denoise/knoise.hpp"

namespace evpipe::denoise {
namespace {

constexpr KnoiseOptions kDv{1000, 1, KnoiseOptions::Variant::dv};
constexpr KnoiseOptions kCuke{1000, 1, KnoiseOptions::Variant::cuke};

TEST(Knoise, NeighbourSupportIsInclusiveAndNeedsTheSamePolarity) {
  for (const auto& o : {kDv, kCuke}) {
    Knoise f(kDavis346, o);
    EXPECT_FALSE(f.accept({10'000, 50, 50, true}));   // nothing before
    EXPECT_TRUE(f.accept({11'000, 51, 51, true}));    // diagonal neighbour exactly 1000 us ago: t - c.t <= d
    EXPECT_FALSE(f.accept({12'001, 52, 52, true}));   // (51,51) 1001 us ago
    EXPECT_FALSE(f.accept({12'100, 53, 53, false}));  // (52,52) ON, we are OFF
    EXPECT_TRUE(f.accept({12'200, 53, 52, true}));    // (52,52) ON 199 us ago (column 52 and row 52 both support)
    EXPECT_FLOAT_EQ(f.last_score(), 2.0F);
  }
}

TEST(Knoise, OwnPixelSupportsInDvNotInCuke) {
  Knoise dv(kDavis346, kDv);
  Knoise cuke(kDavis346, kCuke);
  for (Knoise* f : {&dv, &cuke}) {
    EXPECT_FALSE(f->accept({10'000, 50, 50, true}));
  }
  EXPECT_TRUE(dv.accept({10'500, 50, 50, true}));  // col[50] and row[50] hold this very pixel
  EXPECT_FLOAT_EQ(dv.last_score(), 2.0F);
  EXPECT_FALSE(cuke.accept({10'500, 50, 50, true}));
  EXPECT_FLOAT_EQ(cuke.last_score(), 0.0F);
  // Same column one row away supports in both (col[x] with |dy| = 1).
  EXPECT_TRUE(dv.accept({10'600, 50, 51, true}));
  EXPECT_TRUE(cuke.accept({10'600, 50, 51, true}));
}

TEST(Knoise, OnlyTheLastEventOfEachColumnAndRowIsRemembered) {
  Knoise f(kDavis346, kDv);
  EXPECT_FALSE(f.accept({10'000, 50, 50, true}));
  EXPECT_FALSE(f.accept({10'010, 50, 100, true}));  // overwrites column 50
  EXPECT_FALSE(f.accept({10'020, 200, 50, true}));  // overwrites row 50
  // (50,50) fired 30 us ago and is a neighbour, but neither its column nor its row cell remembers it.
  EXPECT_FALSE(f.accept({10'030, 51, 51, true}));
}

TEST(Knoise, SupportersCountsCells) {
  Knoise f(kDavis346, {1000, 2, KnoiseOptions::Variant::dv});
  EXPECT_FALSE(f.accept({10'000, 50, 50, true}));
  EXPECT_FALSE(f.accept({10'100, 60, 60, true}));
  EXPECT_FALSE(f.accept({10'200, 51, 70, true}));  // column 51 supported by nothing, row 70 nothing
  // (52, 49): column 51's cell is (51,70) (far), row 50's cell is (50,50) but |50 - 52| = 2: no support.
  EXPECT_FALSE(f.accept({10'300, 52, 49, true}));
  // (51, 51): column 50 holds (50,50) and row 50 holds (50,50): two cells, one event.
  EXPECT_TRUE(f.accept({10'400, 51, 51, true}));
  EXPECT_FLOAT_EQ(f.last_score(), 2.0F);
}

TEST(Knoise, BordersNeedNoClippingAndOutsideEventsAreDropped) {
  Knoise f(kDavis346, kDv);
  EXPECT_FALSE(f.accept({10'000, 0, 0, true}));
  EXPECT_TRUE(f.accept({10'001, 1, 1, true}));
  EXPECT_FALSE(f.accept({10'002, 345, 259, true}));
  EXPECT_TRUE(f.accept({10'003, 344, 259, true}));
  EXPECT_FALSE(f.accept({10'004, 346, 100, true}));  // outside: dropped, state untouched
  EXPECT_FALSE(f.accept({10'005, 345, 100, true}));  // so (346,100) did not support (345,100)
}

TEST(Knoise, StartUpArtefactOfZeroInitialisedCells) {
  // Cells start at (t = 0, coordinate 0, OFF): an OFF event within 1 ms of t = 0 is supported by them when it is
  // within 1 of row 0 (column cells) or column 0 (row cells).
  Knoise f(kDavis346, kDv);
  EXPECT_TRUE(f.accept({500, 100, 1, false}));    // column cells (t 0, y 0)
  EXPECT_FALSE(f.accept({600, 200, 2, false}));   // y 2: not within 1 of row 0; rows 1..3 hold x = 0 (except 1)
  EXPECT_TRUE(f.accept({700, 1, 150, false}));    // row cells (t 0, x 0)
  EXPECT_FALSE(f.accept({800, 300, 0, true}));    // ON: polarity differs
  EXPECT_TRUE(f.accept({1000, 300, 0, false}));   // t - 0 = 1000 <= 1000
  EXPECT_FALSE(f.accept({1001, 250, 0, false}));  // 1001 us after the cells' t = 0
  Knoise cuke(kDavis346, kCuke);
  EXPECT_TRUE(cuke.accept({500, 100, 1, false}));  // CUKE's cells start the same way
}

TEST(Knoise, ResetForgets) {
  Knoise f(kDavis346, kDv);
  EXPECT_FALSE(f.accept({10'000, 50, 50, true}));
  f.reset();
  EXPECT_FALSE(f.accept({10'100, 51, 51, true}));
}

TEST(Knoise, SpecDefaultsAndValidation) {
  const FilterSpec spec = knoise_spec();
  const auto params = describe(spec);
  ASSERT_EQ(params.size(), 3U);
  EXPECT_EQ(params[0].key, "duration_us");
  EXPECT_EQ(params[0].default_value, "1000");
  EXPECT_EQ(params[1].key, "supporters");
  EXPECT_EQ(params[1].default_value, "1");
  EXPECT_EQ(params[2].key, "variant");
  EXPECT_EQ(params[2].default_value, "dv");
  EXPECT_NO_THROW((void)make_filter("knoise", {{"variant", "cuke"}, {"supporters", "3"}}, kDavis346));
  for (const auto& [key, value] : std::vector<std::pair<std::string, std::string>>{{"duration_us", "-1"},
                                                                                   {"duration_us", "0"},
                                                                                   {"supporters", "0"},
                                                                                   {"supporters", "7"},
                                                                                   {"variant", "jaer"},
                                                                                   {"duration_us", "1ms"}}) {
    try {
      (void)make_filter("knoise", {{key, value}}, kDavis346);
      ADD_FAILURE() << key << "=" << value << " accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("knoise: " + key + "=" + value), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace evpipe::denoise
