// AEDAT 2.0 reader: real jAER recordings (formats.md §10.1) and synthetic files for every edge case.

#include <gtest/gtest.h>

#include <cstdint>
#include <string>

#include "evpipe/io/reader.hpp"
#include "evpipe_test_data.hpp"
#include "io_test_util.hpp"
#include "sha1.hpp"

namespace evpipe::testing {
namespace {

using io::make_aedat2_reader;
using io::ReaderOptions;

constexpr const char* kRotDisk = "davis240c-rotdisk/IMU_rotDisk.aedat";
constexpr const char* kTranslBoxes = "davis240c-translboxes/IMU_translBoxes.aedat";
constexpr const char* kHeaderOnly = "davis346red-aedat2-header/sample_aedat_header.aedat";

std::uint32_t dvs(std::uint32_t x, std::uint32_t y, bool on) {
  return (y << 22) | (x << 12) | (on ? 0x800u : 0u);
}
constexpr std::uint32_t kImuWord = 0x80000C00u;  // bit 31 and bits 11-10 = 3
constexpr std::uint32_t kApsWord = 0x80000400u;
constexpr std::uint32_t kSpecialWord = 0x00000400u;

std::string header(const std::string& chip = "eu.seebetter.ini.chips.davis.DAVIS240C", const char* eol = "\r\n") {
  std::string h = std::string("#!AER-DAT2.0") + eol + "# This is a raw AE data file" + eol;
  if (!chip.empty()) h += "# AEChip: " + chip + eol;
  h += std::string("#End Of ASCII Header") + eol;
  return h;
}

struct Rec {
  std::uint32_t addr;
  std::int32_t ts;
};

Bytes file(const std::string& hdr, const std::vector<Rec>& recs) {
  Bytes out = bytes_of(hdr);
  for (const auto& r : recs) {
    put_be32(out, r.addr);
    put_be32(out, static_cast<std::uint32_t>(r.ts));
  }
  return out;
}

Drained read(const Bytes& data, ReaderOptions o = {}) {
  auto r = make_aedat2_reader(io::memory_source(data), std::move(o));
  return drain(*r);
}

// ---- real recordings ----------------------------------------------------------------------------

struct RealCase {
  const char* rel;
  std::size_t events;
  std::int64_t t_first;
  std::int64_t t_last;
  const char* fingerprint;
  std::uint64_t imu_words;
};

void check_real(const std::string& path, const RealCase& c) {
  ReaderOptions raw_opts;
  raw_opts.aedat2_flip_y = false;
  auto raw_reader = io::open_reader(path, raw_opts);
  EXPECT_EQ(raw_reader->info().format, "aedat2");
  EXPECT_EQ(raw_reader->info().geometry, kDavis240);
  EXPECT_TRUE(raw_reader->info().geometry_known);
  const auto raw = drain(*raw_reader);
  ASSERT_EQ(raw.events.size(), c.events);
  EXPECT_EQ(raw.events.front().t_us, c.t_first);
  EXPECT_EQ(raw.events.back().t_us, c.t_last);
  EXPECT_EQ(fingerprint(raw.events), c.fingerprint);
  const auto& st = raw_reader->stats();
  EXPECT_EQ(st.events, c.events);
  EXPECT_EQ(st.skipped_non_dvs, c.imu_words);
  EXPECT_EQ(st.out_of_order, 0u);
  EXPECT_EQ(st.discontinuities, 0u);
  EXPECT_EQ(st.truncated_bytes, 0u);
  EXPECT_EQ(st.bytes_read, std::filesystem::file_size(path));
  EXPECT_TRUE(raw_reader->finished());
  EXPECT_DOUBLE_EQ(raw_reader->progress().value_or(0.0), 1.0);

  // Default orientation: y flipped to the top-left origin, x and t untouched.
  auto flipped = drain(*io::open_reader(path));
  ASSERT_EQ(flipped.events.size(), raw.events.size());
  for (std::size_t i = 0; i < raw.events.size(); ++i) {
    ASSERT_EQ(flipped.events[i].y, 179 - raw.events[i].y) << "event " << i;
    ASSERT_EQ(flipped.events[i].x, raw.events[i].x) << "event " << i;
    ASSERT_EQ(flipped.events[i].t_us, raw.events[i].t_us) << "event " << i;
    ASSERT_EQ(flipped.events[i].polarity, raw.events[i].polarity) << "event " << i;
  }
}

TEST(Aedat2Real, RotDiskDecodesToGoldenCountsAndFingerprint) {
  EVPIPE_REQUIRE_REAL(path, kRotDisk);
  check_real(path, {kRotDisk, 374'296, 341'678, 3'508'437, "f918fc660cc4", 51'688});
}

TEST(Aedat2Real, TranslBoxesWithCutImuSampleDecodesToGoldenCounts) {
  EVPIPE_REQUIRE_REAL(path, kTranslBoxes);
  check_real(path, {kTranslBoxes, 162'771, 294'976'755, 297'049'406, "3bf0bf5bc9f7", 33'837});
}

TEST(Aedat2Real, HeaderOnlyFileGivesNoEventsAndDavis346Geometry) {
  EVPIPE_REQUIRE_REAL(path, kHeaderOnly);
  WarningLog log;
  auto r = io::open_reader(path, log.attach());
  EXPECT_EQ(r->info().format, "aedat2");
  EXPECT_EQ(r->info().geometry, kDavis346);
  EXPECT_TRUE(r->info().geometry_known);
  EXPECT_EQ(r->next(), nullptr);
  EXPECT_TRUE(r->finished());
  EXPECT_EQ(r->next(), nullptr);
  EXPECT_EQ(r->stats().events, 0u);
  EXPECT_EQ(r->stats().bytes_read, 599u);
  EXPECT_EQ(r->stats().truncated_bytes, 0u);
  EXPECT_TRUE(log.items->empty());
}

TEST(Aedat2Real, CutsOfARealFileNeverCrash) {
  EVPIPE_REQUIRE_REAL(path, kTranslBoxes);
  const Bytes all = read_bytes(path);
  ASSERT_EQ(all.size(), 1'748'132u);
  const std::size_t header_bytes = all.size() - 1'572'864;  // exactly 1.5 MiB of words after the header
  std::vector<std::size_t> cuts = {0,
                                   1,
                                   5,
                                   11,
                                   12,
                                   13,
                                   14,
                                   100,
                                   4095,
                                   4096,
                                   4097,
                                   65535,
                                   65536,
                                   65537,
                                   header_bytes - 1,
                                   header_bytes,
                                   header_bytes + 1,
                                   header_bytes + 7,
                                   header_bytes + 8,
                                   header_bytes + 8'003,
                                   all.size() - 1};
  for (std::size_t cut = 0; cut < header_bytes; cut += 9973) cuts.push_back(cut);
  for (const std::size_t cut : cuts) {
    SCOPED_TRACE("cut at " + std::to_string(cut));
    const Bytes prefix(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(cut));
    try {
      auto r = make_aedat2_reader(io::memory_source(prefix, "cut.aedat"), {});
      const auto d = drain(*r);
      if (cut >= header_bytes) {
        EXPECT_EQ(r->stats().truncated_bytes, (cut - header_bytes) % 8);
        EXPECT_EQ(d.events.size() + r->stats().skipped_non_dvs, (cut - header_bytes) / 8);
      } else {
        EXPECT_TRUE(d.events.empty());
      }
    } catch (const FormatError& e) {
      // Only a cut inside the magic line may be rejected.
      EXPECT_LT(cut, 14u) << e.what();
      EXPECT_NE(std::string(e.what()).find("cut.aedat"), std::string::npos);
    }
  }
}

// ---- synthetic files ------------------------------------------------------------------------------

TEST(Aedat2, DecodesDvsSkipsApsImuSpecialAndFlipsY) {
  const Bytes data = file(header(), {{dvs(0, 0, true), 10},
                                     {kImuWord, 11},
                                     {kApsWord, 12},
                                     {dvs(239, 179, false), 13},
                                     {kSpecialWord, 14},
                                     {dvs(5, 7, true), 15}});
  ReaderOptions raw;
  raw.aedat2_flip_y = false;
  auto r = make_aedat2_reader(io::memory_source(data), raw);
  EXPECT_EQ(r->info().geometry, kDavis240);
  const auto d = drain(*r);
  ASSERT_EQ(d.events.size(), 3u);
  EXPECT_EQ(d.events[0], (Event{10, 0, 0, true}));
  EXPECT_EQ(d.events[1], (Event{13, 239, 179, false}));
  EXPECT_EQ(d.events[2], (Event{15, 5, 7, true}));
  EXPECT_EQ(r->stats().skipped_non_dvs, 3u);
  EXPECT_FALSE(d.batches[0]->labelled());

  const auto flipped = read(data);
  ASSERT_EQ(flipped.events.size(), 3u);
  EXPECT_EQ(flipped.events[0], (Event{10, 0, 179, true}));
  EXPECT_EQ(flipped.events[1], (Event{13, 239, 0, false}));
  EXPECT_EQ(flipped.events[2], (Event{15, 5, 172, true}));

  ReaderOptions both;
  both.aedat2_flip_x = true;
  const auto xy = read(data, both);
  EXPECT_EQ(xy.events[0], (Event{10, 239, 179, true}));
  EXPECT_EQ(xy.events[2], (Event{15, 234, 172, true}));
}

TEST(Aedat2, LfHeaderAndDavis346ChipClass) {
  const Bytes data = file(header("eu.seebetter.ini.chips.davis.Davis346red", "\n"), {{dvs(345, 259, true), 1}});
  ReaderOptions raw;
  raw.aedat2_flip_y = false;
  auto r = make_aedat2_reader(io::memory_source(data), raw);
  EXPECT_EQ(r->info().geometry, kDavis346);
  EXPECT_TRUE(r->info().geometry_known);
  const auto d = drain(*r);
  ASSERT_EQ(d.events.size(), 1u);
  EXPECT_EQ(d.events[0], (Event{1, 345, 259, true}));
}

TEST(Aedat2, UnknownChipUsesTheDefaultGeometryAndWarns) {
  WarningLog log;
  ReaderOptions o = log.attach();
  o.default_geometry = {640, 480};
  const Bytes data = file(header("ch.unizh.ini.jaer.chip.retina.DVS128"), {{dvs(600, 400, true), 1}});
  auto r = make_aedat2_reader(io::memory_source(data), o);
  EXPECT_EQ(r->info().geometry, (SensorGeometry{640, 480}));
  EXPECT_FALSE(r->info().geometry_known);
  EXPECT_TRUE(log.any_contains("DVS128"));
  EXPECT_EQ(drain(*r).events.size(), 1u);

  auto no_chip = make_aedat2_reader(io::memory_source(file(header(""), {})), {});
  EXPECT_EQ(no_chip->info().geometry, kDavis346);
  EXPECT_FALSE(no_chip->info().geometry_known);
}

TEST(Aedat2, FirstRecordStartingWithHashIsDataNotHeader) {
  // Address 0x23...: its top byte is '#', but the record holds binary bytes: it is the first event.
  const std::uint32_t addr = dvs(3, 140, false);
  ASSERT_EQ(addr >> 24, 0x23u);
  ReaderOptions raw;
  raw.aedat2_flip_y = false;
  const auto d = read(file(header(), {{addr, 5}, {dvs(4, 4, true), 6}}), raw);
  ASSERT_EQ(d.events.size(), 2u);
  EXPECT_EQ(d.events[0], (Event{5, 3, 140, false}));
}

TEST(Aedat2, BatchesHoldAtMostBatchEvents) {
  std::vector<Rec> recs(10);
  for (int i = 0; i < 10; ++i) recs[static_cast<std::size_t>(i)] = {dvs(1, 1, true), i};
  ReaderOptions o;
  o.batch_events = 3;
  auto r = make_aedat2_reader(io::memory_source(file(header(), recs)), o);
  const auto d = drain(*r);
  ASSERT_EQ(d.batches.size(), 4u);
  EXPECT_EQ(d.batches[0]->size(), 3u);
  EXPECT_EQ(d.batches[3]->size(), 1u);
  EXPECT_EQ(r->stats().batches, 4u);
  EXPECT_EQ(r->stats().events, 10u);
}

TEST(Aedat2, TruncatedAtEveryCutPointKeepsCompleteRecords) {
  const std::string hdr = header();
  const Bytes data = file(hdr, {{dvs(1, 2, true), 1}, {kImuWord, 2}, {dvs(3, 4, false), 3}, {dvs(5, 6, true), 4}});
  for (std::size_t cut = 0; cut <= data.size(); ++cut) {
    SCOPED_TRACE("cut at " + std::to_string(cut));
    const Bytes prefix(data.begin(), data.begin() + static_cast<std::ptrdiff_t>(cut));
    WarningLog log;
    try {
      auto r = make_aedat2_reader(io::memory_source(prefix), log.attach());
      const auto d = drain(*r);
      ASSERT_GE(cut, 12u);
      if (cut < hdr.size()) {
        EXPECT_TRUE(d.events.empty());
        continue;
      }
      const std::size_t body = cut - hdr.size();
      const std::size_t records = body / 8;
      EXPECT_EQ(d.events.size(), records - (records >= 2 ? 1 : 0));
      EXPECT_EQ(r->stats().truncated_bytes, body % 8);
      EXPECT_EQ(log.any_contains("truncated last record"), body % 8 != 0);
      if (body % 8 != 0) {
        EXPECT_EQ(log.items->back().offset, hdr.size() + records * 8);
      }
    } catch (const FormatError& e) {
      EXPECT_LT(cut, 12u) << e.what();
    }
  }
}

TEST(Aedat2, GarbageHeaderIsAFormatErrorNamingTheFile) {
  auto err = read_error(make_aedat2_reader, bytes_of("#!AER-DAT3.1\r\n#!END-HEADER\r\n"), {}, "bad.aedat");
  ASSERT_TRUE(err);
  EXPECT_EQ(err->offset(), 0u);
  EXPECT_NE(std::string(err->what()).find("bad.aedat: byte 0:"), std::string::npos) << err->what();

  err = read_error(make_aedat2_reader, bytes_of("garbage"), {}, "bad.aedat");
  ASSERT_TRUE(err);

  // A header line longer than 1 MiB is rejected instead of buffered without bound.
  std::string huge = "#!AER-DAT2.0\r\n#" + std::string((1u << 20) + 10, 'a') + "\r\n";
  err = read_error(make_aedat2_reader, bytes_of(huge), {}, "huge.aedat");
  ASSERT_TRUE(err);
  EXPECT_EQ(err->offset(), 14u);
  EXPECT_NE(std::string(err->what()).find("longer than"), std::string::npos);
}

TEST(Aedat2, EventOutsideTheSensorNamesItsByteOffset) {
  const std::string hdr = header();
  const Bytes data = file(hdr, {{dvs(1, 1, true), 1}, {kImuWord, 2}, {dvs(240, 3, true), 3}});
  auto err = read_error(make_aedat2_reader, data, {}, "out.aedat");
  ASSERT_TRUE(err);
  EXPECT_EQ(err->offset(), hdr.size() + 16);
  EXPECT_NE(std::string(err->what()).find("byte " + std::to_string(hdr.size() + 16) + ":"), std::string::npos)
      << err->what();
  EXPECT_NE(std::string(err->what()).find("x=240"), std::string::npos) << err->what();
  EXPECT_NE(std::string(err->what()).find("out.aedat"), std::string::npos);

  // y beyond 180 (raw field up to 511).
  err = read_error(make_aedat2_reader, file(hdr, {{dvs(1, 180, true), 1}}));
  ASSERT_TRUE(err);
  EXPECT_EQ(err->offset(), hdr.size());
}

TEST(Aedat2, OutOfOrderTimestampsAreDroppedOrKeptAndCounted) {
  const Bytes data =
      file(header(), {{dvs(1, 1, true), 100}, {dvs(1, 1, true), 200}, {dvs(2, 2, true), 150}, {dvs(3, 3, true), 300}});
  WarningLog log;
  auto dropped = make_aedat2_reader(io::memory_source(data), log.attach());
  const auto d = drain(*dropped);
  ASSERT_EQ(d.events.size(), 3u);
  EXPECT_EQ(d.events[2].t_us, 300);
  EXPECT_EQ(dropped->stats().out_of_order, 1u);
  EXPECT_EQ(dropped->stats().discontinuities, 0u);
  ASSERT_EQ(log.items->size(), 1u);
  EXPECT_EQ(log.items->front().offset, header().size() + 16);

  ReaderOptions keep;
  keep.out_of_order = io::OutOfOrderPolicy::keep;
  auto kept = make_aedat2_reader(io::memory_source(data), keep);
  const auto k = drain(*kept);
  ASSERT_EQ(k.events.size(), 4u);
  EXPECT_EQ(k.events[2].t_us, 150);
  EXPECT_EQ(kept->stats().out_of_order, 1u);
}

TEST(Aedat2, BackwardJumpStartsANewBatchFlaggedAsDiscontinuity) {
  const Bytes data = file(header(), {{dvs(1, 1, true), 5'000'000},
                                     {dvs(1, 1, true), 5'100'000},
                                     {dvs(2, 2, true), 1'000},
                                     {dvs(3, 3, true), 2'000},
                                     {dvs(3, 3, true), 3'000}});
  auto r = make_aedat2_reader(io::memory_source(data), {});
  const auto d = drain(*r);
  ASSERT_EQ(d.batches.size(), 2u);
  EXPECT_FALSE(d.batches[0]->discontinuity_before);
  EXPECT_EQ(d.batches[0]->size(), 2u);
  EXPECT_TRUE(d.batches[1]->discontinuity_before);
  ASSERT_EQ(d.batches[1]->size(), 3u);
  EXPECT_EQ(d.batches[1]->events[0].t_us, 1'000);
  EXPECT_EQ(r->stats().discontinuities, 1u);
  EXPECT_EQ(r->stats().out_of_order, 0u);

  // A smaller threshold turns a 0.5 s step back into a discontinuity too, even at a batch boundary.
  ReaderOptions o;
  o.discontinuity_us = 100;
  o.batch_events = 2;
  auto small = make_aedat2_reader(
      io::memory_source(file(header(), {{dvs(1, 1, true), 1'000}, {dvs(1, 1, true), 1'100}, {dvs(1, 1, true), 500}})),
      o);
  const auto s = drain(*small);
  ASSERT_EQ(s.batches.size(), 2u);
  EXPECT_TRUE(s.batches[1]->discontinuity_before);
  EXPECT_EQ(s.batches[1]->events[0].t_us, 500);
}

TEST(Aedat2, ThirtyTwoBitTimestampWrapIsUnwrapped) {
  constexpr std::int64_t k31 = std::int64_t{1} << 31;
  const Bytes data = file(header(), {{dvs(1, 1, true), static_cast<std::int32_t>(k31 - 10)},
                                     {dvs(1, 1, true), INT32_MAX},
                                     {dvs(1, 1, true), INT32_MIN},
                                     {dvs(1, 1, true), INT32_MIN + 5},
                                     {dvs(1, 1, true), -1},
                                     {dvs(1, 1, true), 0},
                                     {dvs(1, 1, true), INT32_MAX},
                                     {dvs(1, 1, true), INT32_MIN}});
  auto r = make_aedat2_reader(io::memory_source(data), {});
  const auto d = drain(*r);
  ASSERT_EQ(d.events.size(), 8u);
  const std::vector<std::int64_t> expected = {k31 - 10,    k31 - 1, k31,         k31 + 5,
                                              2 * k31 - 1, 2 * k31, 3 * k31 - 1, 3 * k31};
  for (std::size_t i = 0; i < expected.size(); ++i) EXPECT_EQ(d.events[i].t_us, expected[i]) << i;
  EXPECT_EQ(r->stats().discontinuities, 0u);
  EXPECT_EQ(r->stats().out_of_order, 0u);
  EXPECT_EQ(d.batches.size(), 1u);

  // A reset to near zero from below 2^31 is a clock reset (discontinuity), not a wrap.
  auto reset = make_aedat2_reader(
      io::memory_source(file(header(), {{dvs(1, 1, true), 2'000'000'000}, {dvs(1, 1, true), 10}})), {});
  const auto rd = drain(*reset);
  ASSERT_EQ(rd.events.size(), 2u);
  EXPECT_EQ(rd.events[1].t_us, 10);
  EXPECT_EQ(reset->stats().discontinuities, 1u);
}

}  // namespace
}  // namespace evpipe::testing
