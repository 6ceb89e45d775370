#include <gtest/gtest.h>

#include "evpipe/core/error.hpp"

TEST(FormatError, NamesFileOffsetAndReason) {
  const evpipe::FormatError e("rec.aedat4", 1234, "packet size 99999 runs past the end of the file");
  EXPECT_STREQ(e.what(), "rec.aedat4: byte 1234: packet size 99999 runs past the end of the file");
  EXPECT_EQ(e.file(), "rec.aedat4");
  EXPECT_EQ(e.offset(), 1234U);
}

TEST(FormatError, WithoutOffset) {
  const evpipe::FormatError e("x.txt", std::nullopt, "empty file");
  EXPECT_STREQ(e.what(), "x.txt: empty file");
}

TEST(Warning, Message) {
  const evpipe::Warning w{"f.aedat", 8, "truncated record"};
  EXPECT_EQ(w.message(), "f.aedat: byte 8: truncated record");
}
