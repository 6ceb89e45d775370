// preview_t (issue 22): the record <-> bytes codec, both image encodings, and clear errors for bad input.
#include <gtest/gtest.h>

#include <random>

#include "evpipe/transport/codec.hpp"
#include "evpipe/transport/preview.hpp"

using namespace evpipe::transport;

namespace {

PreviewRecord sample(int width, int height) {
  PreviewRecord r;
  r.seq = 7;
  r.utime_us = 1'700'000'000'000'000;
  r.t_us = 15'000;
  r.window_t0_us = 0;
  r.window_t1_us = 30'000;
  r.status = kPreviewStatusHolding;  // 3: must travel even where pose_t does not name it
  r.pose_valid = true;
  r.raw_events = 3000;
  r.kept_events = 400;
  r.pose_events = 500;
  r.inliers = 250;
  r.sigma_px = 0.75F;
  r.latency_ms = 1.5F;
  r.latency_p99_ms = 2.5F;
  r.queue_drops = 2;
  r.previews_dropped = 1;
  r.width = width;
  r.height = height;
  r.pixels.assign(static_cast<std::size_t>(width * height), 0);
  r.segments = {{1, 2, 3, 4}, {10.5F, 20.25F, 30, 40}};
  r.note = "a note";
  return r;
}

}  // namespace

TEST(PreviewCodec, RoundTripKeepsEveryField) {
  auto r = sample(346, 260);
  r.pixels[0] = 1;
  r.pixels[1000] = 2;
  r.pixels[346 * 260 - 1] = 3;
  const auto bytes = encode(r);
  const auto d = decode_preview(bytes.data(), bytes.size());
  ASSERT_TRUE(d);
  EXPECT_EQ(d->seq, 7);
  EXPECT_EQ(d->status, kPreviewStatusHolding);
  EXPECT_EQ(preview_status_name(d->status), "holding");
  EXPECT_EQ(d->pixels, r.pixels);
  ASSERT_EQ(d->segments.size(), 2u);
  EXPECT_FLOAT_EQ(d->segments[1].y0_px, 20.25F);
  EXPECT_EQ(d->note, "a note");
  EXPECT_DOUBLE_EQ(d->inlier_share(), 0.5);
  // A nearly empty image is run-length coded: a few bytes, not 22 kB.
  EXPECT_LT(bytes.size(), 300u);
}

TEST(PreviewCodec, NoiseIsPackedAndBoundedByTwoBitsAPixel) {
  auto r = sample(346, 260);
  std::mt19937 rng(1);
  for (auto& p : r.pixels) p = static_cast<std::uint8_t>(rng() % 4);
  const auto image = encode_preview_image(r.pixels);
  EXPECT_EQ(image.encoding, 0);  // PACKED
  EXPECT_EQ(image.bytes.size(), (346u * 260u + 3) / 4);
  const auto bytes = encode(r);
  EXPECT_LT(bytes.size(), 23'000u);  // the documented worst case: ~22.5 kB of image + the rest
  const auto d = decode_preview(bytes.data(), bytes.size());
  ASSERT_TRUE(d);
  EXPECT_EQ(d->pixels, r.pixels);
}

TEST(PreviewCodec, LongRunsUseTheExtendedCount) {
  std::vector<std::uint8_t> pixels(200'000, 0);
  pixels[64] = 2;                                              // runs of 64, 1, and a long one
  std::fill(pixels.begin() + 1000, pixels.begin() + 1063, 1);  // exactly 63
  const auto image = encode_preview_image(pixels);
  EXPECT_EQ(image.encoding, 1);
  EXPECT_EQ(decode_preview_image(image.encoding, image.bytes.data(), image.bytes.size(), pixels.size()), pixels);
}

TEST(PreviewCodec, BadBytesGiveClearErrorsNotCrashes) {
  const std::vector<std::uint8_t> pixels(100, 1);
  auto image = encode_preview_image(pixels);
  // Too few pixels for the image.
  EXPECT_THROW((void)decode_preview_image(image.encoding, image.bytes.data(), image.bytes.size(), 101), DecodeError);
  // A run past the end.
  EXPECT_THROW((void)decode_preview_image(image.encoding, image.bytes.data(), image.bytes.size(), 50), DecodeError);
  // A truncated extended count.
  const std::uint8_t truncated[] = {0x3F, 0x80};
  EXPECT_THROW((void)decode_preview_image(1, truncated, sizeof truncated, 1000), DecodeError);
  EXPECT_THROW((void)decode_preview_image(5, truncated, sizeof truncated, 1000), DecodeError);
  // A pose_t is not a preview (fingerprint): nullopt, and so are truncated bytes.
  PoseRecord pose;
  const auto pose_bytes = encode(pose);
  EXPECT_FALSE(decode_preview(pose_bytes.data(), pose_bytes.size()));
  const auto bytes = encode(sample(10, 10));
  EXPECT_FALSE(decode_preview(bytes.data(), bytes.size() / 2));
  // A preview whose image does not match its size.
  auto r = sample(10, 10);
  r.pixels.resize(50);
  const auto bad = encode(r);
  try {
    (void)decode_preview(bad.data(), bad.size());
    FAIL() << "no DecodeError";
  } catch (const DecodeError& e) {
    EXPECT_NE(std::string(e.what()).find("preview_t.image"), std::string::npos) << e.what();
  }
  // A size no preview has (32767 x 32767): refused before anything is allocated for it.
  auto huge = sample(1, 1);
  huge.width = 32767;
  huge.height = 32767;
  const auto huge_bytes = encode(huge);
  try {
    (void)decode_preview(huge_bytes.data(), huge_bytes.size());
    FAIL() << "no DecodeError";
  } catch (const DecodeError& e) {
    EXPECT_NE(std::string(e.what()).find("32767x32767"), std::string::npos) << e.what();
  }
}
