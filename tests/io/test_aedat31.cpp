// AEDAT 3.1: writer -> reader round trips (no public 3.1 recording exists, formats.md §10.4) and
// hand-built packets for every edge case of the reader.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <string_view>

#include "evpipe/io/reader.hpp"
#include "evpipe/io/writer.hpp"
#include "evpipe_test_data.hpp"
#include "io_test_util.hpp"

namespace evpipe::testing {
namespace {

using io::make_aedat31_reader;
using io::ReaderOptions;

constexpr std::int64_t k31 = std::int64_t{1} << 31;

constexpr std::string_view kHeader =
    "#!AER-DAT3.1\r\n#Format: RAW\r\n#Source 1: DAVIS346\r\n#Start-Time: 2024-01-01 00:00:00 (TZ+0000)\r\n"
    "#!END-HEADER\r\n";

struct Packet {
  std::int16_t type = 1;
  std::int32_t event_size = 8;
  std::int32_t ts_offset = 4;
  std::int32_t overflow = 0;
  std::int32_t capacity = -1;        // -1: = number
  std::int32_t number = -1;          // -1: = words.size() / 2
  std::vector<std::uint32_t> words;  // payload as LE uint32 words
};

std::uint32_t pol(std::uint32_t x, std::uint32_t y, bool on, bool valid = true) {
  return (valid ? 1u : 0u) | (on ? 2u : 0u) | (y << 2) | (x << 17);
}
std::uint32_t special(std::uint32_t type) {
  return 1u | (type << 1);
}

void add_packet(Bytes& out, const Packet& p) {
  const auto n = p.number >= 0 ? p.number : static_cast<std::int32_t>(p.words.size() / 2);
  put_le16(out, static_cast<std::uint16_t>(p.type));
  put_le16(out, 1);
  put_le32(out, static_cast<std::uint32_t>(p.event_size));
  put_le32(out, static_cast<std::uint32_t>(p.ts_offset));
  put_le32(out, static_cast<std::uint32_t>(p.overflow));
  put_le32(out, static_cast<std::uint32_t>(p.capacity >= 0 ? p.capacity : n));
  put_le32(out, static_cast<std::uint32_t>(n));
  put_le32(out, static_cast<std::uint32_t>(n));
  for (const auto w : p.words) put_le32(out, w);
}

Bytes file(const std::vector<Packet>& packets, std::string_view hdr = kHeader) {
  Bytes out = bytes_of(hdr);
  for (const auto& p : packets) add_packet(out, p);
  return out;
}

Drained read(const Bytes& data, ReaderOptions o = {}) {
  auto r = make_aedat31_reader(io::memory_source(data), std::move(o));
  return drain(*r);
}

std::vector<Event> random_events(std::size_t n, SensorGeometry g, std::int64_t t0, std::int64_t max_step,
                                 std::uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::vector<Event> ev(n);
  std::int64_t t = t0;
  for (auto& e : ev) {
    t += static_cast<std::int64_t>(rng() % static_cast<std::uint64_t>(max_step + 1));
    e.t_us = t;
    e.x = static_cast<std::uint16_t>(rng() % static_cast<std::uint64_t>(g.width));
    e.y = static_cast<std::uint16_t>(rng() % static_cast<std::uint64_t>(g.height));
    e.polarity = (rng() & 1u) != 0;
  }
  return ev;
}

std::string write_file(const std::string& name, const std::vector<Event>& events, const io::WriterOptions& o) {
  auto path = (temp_dir("aedat31") / name).string();
  auto w = io::open_writer(path, io::Format::aedat31, o);
  // Several write() calls, to cross call boundaries inside packets.
  const std::size_t half = events.size() / 2;
  w->write(std::span(events).first(half));
  w->write(std::span(events).subspan(half));
  w->close();
  return path;
}

// ---- writer -> reader ---------------------------------------------------------------------------

TEST(Aedat31RoundTrip, EventsPastTwoToThe31AreIdentical) {
  // Steps of up to 20 s from 2^31 - 30 s: the overflow counter changes several times.
  const auto events = random_events(5'000, kDavis346, k31 - 30'000'000, 1'500'000, 7);
  ASSERT_GT(events.back().t_us, 2 * k31 + 10'000'000);
  ASSERT_LT(events.back().t_us, 3 * k31);
  io::WriterOptions wo;
  wo.packet_events = 97;
  const auto path = write_file("rt.aedat", events, wo);

  auto r = io::open_reader(path);
  EXPECT_EQ(r->info().format, "aedat3.1");
  EXPECT_EQ(r->info().geometry, kDavis346);
  EXPECT_TRUE(r->info().geometry_known);
  const auto d = drain(*r);
  ASSERT_EQ(d.events.size(), events.size());
  EXPECT_EQ(d.events, events);
  EXPECT_EQ(r->stats().out_of_order, 0u);
  EXPECT_EQ(r->stats().discontinuities, 0u);
  EXPECT_EQ(r->stats().invalid_events, 0u);
  EXPECT_EQ(r->stats().bytes_read, std::filesystem::file_size(path));

  // Packets: a new one whenever the overflow changes, none larger than packet_events.
  const Bytes raw = read_bytes(path);
  const std::string text = text_of(raw);
  ASSERT_EQ(text.rfind("#!AER-DAT3.1\r\n#Format: RAW\r\n#Source 1: DAVIS346 346x260", 0), 0u);
  std::size_t pos = text.find("#!END-HEADER\r\n") + 14;
  std::size_t total = 0;
  std::int64_t last_overflow = -1;
  std::size_t overflow_changes = 0;
  while (pos < raw.size()) {
    ASSERT_LE(pos + 28, raw.size());
    std::int32_t f[7];
    std::memcpy(f, raw.data() + pos + 4, sizeof f);
    EXPECT_EQ(f[0], 8);     // eventSize
    EXPECT_EQ(f[1], 4);     // eventTSOffset
    EXPECT_EQ(f[3], f[4]);  // capacity == number
    EXPECT_EQ(f[5], f[4]);  // all valid
    EXPECT_LE(f[4], 97);
    EXPECT_GE(f[2], last_overflow);
    if (f[2] != last_overflow) ++overflow_changes;
    last_overflow = f[2];
    // Every event of the packet shares its overflow.
    for (std::int32_t i = 0; i < f[4]; ++i) EXPECT_EQ(events[total + static_cast<std::size_t>(i)].t_us >> 31, f[2]);
    total += static_cast<std::size_t>(f[4]);
    pos += 28 + 8 * static_cast<std::size_t>(f[4]);
  }
  EXPECT_EQ(total, events.size());
  EXPECT_EQ(overflow_changes, 3u);  // overflow 0, 1, 2
}

TEST(Aedat31RoundTrip, GeometryTravelsInTheSourceLine) {
  for (const SensorGeometry g : {kDavis240, SensorGeometry{640, 480}, SensorGeometry{1, 1}}) {
    SCOPED_TRACE(std::to_string(g.width) + "x" + std::to_string(g.height));
    const auto events = random_events(300, g, 0, 50, 3);
    io::WriterOptions wo;
    wo.geometry = g;
    const auto path = write_file("geom.aedat", events, wo);
    auto r = io::open_reader(path);
    EXPECT_EQ(r->info().geometry, g);
    EXPECT_TRUE(r->info().geometry_known);
    EXPECT_EQ(drain(*r).events, events);
  }
}

TEST(Aedat31RoundTrip, NegativeAndHugeTimestamps) {
  std::vector<Event> events = {
      {-5 * k31 - 3, 1, 2, true}, {-1, 3, 4, false}, {0, 5, 6, true}, {kMaxAbsTimestampUs - 12345, 7, 8, false}};
  io::WriterOptions wo;
  ReaderOptions ro;
  ro.out_of_order = io::OutOfOrderPolicy::keep;
  const auto path = write_file("neg.aedat", events, wo);
  EXPECT_EQ(drain(*io::open_reader(path, ro)).events, events);

  const auto bad_path = (temp_dir("aedat31") / "bad.aedat").string();
  auto w = io::open_writer(bad_path, io::Format::aedat31, wo);
  const std::vector<Event> out_of_sensor = {{0, 346, 0, true}};
  EXPECT_THROW(w->write(out_of_sensor), std::invalid_argument);
  const std::vector<Event> too_late = {{std::int64_t{1} << 62, 0, 0, true}};
  EXPECT_THROW(w->write(too_late), std::invalid_argument);
  w->close();
}

TEST(Aedat31RoundTrip, TruncatedAtEveryCutPointKeepsCompletePackets) {
  const auto events = random_events(40, kDavis346, 1000, 10, 11);
  io::WriterOptions wo;
  wo.packet_events = 8;
  const Bytes all = read_bytes(write_file("cut.aedat", events, wo));
  const std::size_t header_bytes = text_of(all).find("#!END-HEADER\r\n") + 14;
  for (std::size_t cut = 0; cut <= all.size(); ++cut) {
    SCOPED_TRACE("cut at " + std::to_string(cut));
    const Bytes prefix(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(cut));
    try {
      auto r = make_aedat31_reader(io::memory_source(prefix, "cut.aedat"), {});
      const auto d = drain(*r);
      if (cut < header_bytes) {  // only "#!END-HEADER" without its "\r\n" reads as a complete header
        EXPECT_GE(cut, header_bytes - 2);
        EXPECT_TRUE(d.events.empty());
        continue;
      }
      const std::size_t body = cut - header_bytes;
      const std::size_t packet_bytes = 28 + 8 * 8;
      const std::size_t complete = body / packet_bytes;
      ASSERT_EQ(d.events.size(), complete * 8);
      EXPECT_TRUE(std::equal(d.events.begin(), d.events.end(), events.begin()));
      EXPECT_EQ(r->stats().truncated_bytes, body % packet_bytes);
    } catch (const FormatError& e) {
      EXPECT_LT(cut, header_bytes) << e.what();
      EXPECT_NE(std::string(e.what()).find("cut.aedat"), std::string::npos);
    }
  }
}

// ---- hand-built packets ---------------------------------------------------------------------------

TEST(Aedat31, SkipsOtherPacketsAndInvalidEventsAndCombinesTheOverflow) {
  Packet frame;
  frame.type = 2;
  frame.event_size = 12;
  frame.ts_offset = 0;
  frame.number = 2;
  frame.words = {1, 2, 3, 4, 5, 6};
  Packet p1;
  p1.overflow = 3;
  p1.words = {pol(1, 2, true), 100, pol(3, 4, false, false), 101, pol(345, 259, false), 102};
  Packet imu;
  imu.type = 3;
  imu.event_size = 36;
  imu.number = 0;
  const auto d = read(file({frame, p1, imu}));
  ASSERT_EQ(d.events.size(), 2u);
  EXPECT_EQ(d.events[0], (Event{3 * k31 + 100, 1, 2, true}));
  EXPECT_EQ(d.events[1], (Event{3 * k31 + 102, 345, 259, false}));

  auto r = make_aedat31_reader(io::memory_source(file({frame, p1, imu})), {});
  drain(*r);
  EXPECT_EQ(r->stats().invalid_events, 1u);
  EXPECT_EQ(r->stats().skipped_non_dvs, 2u);
  EXPECT_EQ(r->info().geometry, kDavis346);
}

TEST(Aedat31, TimestampResetSpecialEventIsADiscontinuity) {
  Packet a;
  a.words = {pol(1, 1, true), 5'000, pol(1, 1, true), 6'000};
  Packet reset;
  reset.type = 0;
  reset.words = {special(0) /*wrap: ignored*/, 6'500, special(1), 6'600};
  Packet b;
  b.words = {pol(2, 2, true), 10, pol(2, 2, true), 20};  // small step back: not "out of order"
  auto r = make_aedat31_reader(io::memory_source(file({a, reset, b})), {});
  const auto d = drain(*r);
  ASSERT_EQ(d.batches.size(), 2u);
  EXPECT_FALSE(d.batches[0]->discontinuity_before);
  EXPECT_EQ(d.batches[0]->size(), 2u);
  EXPECT_TRUE(d.batches[1]->discontinuity_before);
  ASSERT_EQ(d.batches[1]->size(), 2u);
  EXPECT_EQ(d.batches[1]->events[0].t_us, 10);
  EXPECT_EQ(r->stats().discontinuities, 1u);
  EXPECT_EQ(r->stats().out_of_order, 0u);
  EXPECT_EQ(r->stats().skipped_non_dvs, 2u);

  // A reset before any event flags the first batch.
  const auto first = read(file({reset, b}));
  ASSERT_EQ(first.batches.size(), 1u);
  EXPECT_TRUE(first.batches[0]->discontinuity_before);
}

TEST(Aedat31, OutOfOrderAndBackwardJumpsFollowThePolicy) {
  Packet p;
  p.words = {pol(1, 1, true), 100, pol(1, 1, true), 200,       pol(1, 1, true), 150,
             pol(1, 1, true), 300, pol(1, 1, true), 2'000'000, pol(1, 1, true), 5};
  auto dropped = make_aedat31_reader(io::memory_source(file({p})), {});
  const auto d = drain(*dropped);
  ASSERT_EQ(d.events.size(), 5u);
  EXPECT_EQ(dropped->stats().out_of_order, 1u);
  EXPECT_EQ(dropped->stats().discontinuities, 1u);
  ASSERT_EQ(d.batches.size(), 2u);
  EXPECT_TRUE(d.batches[1]->discontinuity_before);
  EXPECT_EQ(d.batches[1]->events[0].t_us, 5);

  ReaderOptions keep;
  keep.out_of_order = io::OutOfOrderPolicy::keep;
  EXPECT_EQ(read(file({p}), keep).events.size(), 6u);
}

TEST(Aedat31, HeaderProblemsAreFormatErrors) {
  auto err = read_error(make_aedat31_reader, bytes_of("#!AER-DAT3.1\r\n#Format: RAW\r\n"), {}, "noend.aedat");
  ASSERT_TRUE(err);
  EXPECT_NE(std::string(err->what()).find("noend.aedat"), std::string::npos);
  EXPECT_NE(std::string(err->what()).find("END-HEADER"), std::string::npos);

  err = read_error(make_aedat31_reader, bytes_of("#!AER-DAT2.0\r\n#!END-HEADER\r\n"));
  ASSERT_TRUE(err);
  EXPECT_EQ(err->offset(), 0u);

  err = read_error(make_aedat31_reader, bytes_of("#!AER-DAT3.1\r\n#Format: SerializedTS\r\n#!END-HEADER\r\n"));
  ASSERT_TRUE(err);
  EXPECT_EQ(err->offset(), 14u);

  err = read_error(make_aedat31_reader, bytes_of("#!AER-DAT3.1\r\nnot a comment\r\n#!END-HEADER\r\n"));
  ASSERT_TRUE(err);
  EXPECT_EQ(err->offset(), 14u);

  err = read_error(make_aedat31_reader, bytes_of("#!AER-DAT3.1\r\n#" + std::string((1u << 20) + 1, 'x')));
  ASSERT_TRUE(err);
}

TEST(Aedat31, GeometryFromTheSourceDescription) {
  auto geometry = [](const std::string& source_line, SensorGeometry def = kDavis346) {
    ReaderOptions o;
    o.default_geometry = def;
    auto r = make_aedat31_reader(
        io::memory_source(bytes_of("#!AER-DAT3.1\r\n#Format: RAW\r\n" + source_line + "#!END-HEADER\r\n")), o);
    return std::pair{r->info().geometry, r->info().geometry_known};
  };
  EXPECT_EQ(geometry("#Source 1: DAVIS240C\r\n"), std::pair(kDavis240, true));
  EXPECT_EQ(geometry("#Source 2: DAVIS346B_00000391\r\n"), std::pair(kDavis346, true));
  EXPECT_EQ(geometry("#Source 1: evpipe DAVIS346 640x480\r\n"), std::pair(SensorGeometry{640, 480}, true));
  EXPECT_EQ(geometry("#Source 1: DVXplorer\r\n", {320, 240}), std::pair(SensorGeometry{320, 240}, false));
  EXPECT_EQ(geometry("", kDavis240), std::pair(kDavis240, false));
  EXPECT_EQ(geometry("#Source 1: cam0x0 99999x5\r\n"), std::pair(kDavis346, false));
}

TEST(Aedat31, NonsensePacketHeadersAreFormatErrorsNamingThePacket) {
  const std::size_t at = kHeader.size();
  Packet ok;
  ok.words = {pol(1, 1, true), 1};
  const std::size_t second = at + 28 + 8;
  auto expect_error_at = [](const Bytes& data, std::uint64_t offset, const std::string& needle) {
    auto err = read_error(make_aedat31_reader, data, {}, "bad.aedat");
    ASSERT_TRUE(err) << needle;
    EXPECT_EQ(err->offset(), offset) << err->what();
    EXPECT_NE(std::string(err->what()).find(needle), std::string::npos) << err->what();
    EXPECT_NE(std::string(err->what()).find("bad.aedat: byte " + std::to_string(offset)), std::string::npos);
  };
  Packet p = ok;
  p.event_size = 4;
  expect_error_at(file({ok, p}), second, "eventSize 4");
  p = ok;
  p.ts_offset = 0;
  expect_error_at(file({ok, p}), second, "eventTSOffset 0");
  p = ok;
  p.type = 7;
  p.event_size = 0;
  expect_error_at(file({ok, p}), second, "eventSize 0");
  p = ok;
  p.event_size = -8;
  expect_error_at(file({ok, p}), second, "eventSize -8");
  p = ok;
  p.capacity = 5;
  expect_error_at(file({ok, p}), second, "eventCapacity 5");
  p = ok;
  p.number = -1;
  p.capacity = 0;
  p.words.clear();
  Bytes neg = file({ok});
  add_packet(neg, p);
  // number -1 in add_packet means "count the words": patch the field directly.
  std::int32_t minus_one = -1;
  std::memcpy(neg.data() + second + 20, &minus_one, 4);
  std::memcpy(neg.data() + second + 16, &minus_one, 4);
  expect_error_at(neg, second, "eventNumber -1");
}

TEST(Aedat31, HugePacketSizesDoNotAllocateAndStopAsTruncated) {
  Packet ok;
  ok.words = {pol(1, 1, true), 1};
  Packet huge;
  huge.type = 2;
  huge.event_size = INT32_MAX;
  huge.number = INT32_MAX;
  WarningLog log;
  auto r = make_aedat31_reader(io::memory_source(file({ok, huge, ok})), log.attach());
  const auto d = drain(*r);
  EXPECT_EQ(d.events.size(), 1u);
  EXPECT_EQ(r->stats().truncated_bytes, 28u + 28u + 8u);
  EXPECT_TRUE(log.any_contains("truncated packet"));

  Packet huge_pol;
  huge_pol.number = INT32_MAX;
  huge_pol.words = {pol(1, 1, true), 2};
  auto r2 = make_aedat31_reader(io::memory_source(file({ok, huge_pol})), {});
  EXPECT_EQ(drain(*r2).events.size(), 1u);
  EXPECT_EQ(r2->stats().truncated_bytes, 28u + 8u);
}

TEST(Aedat31, EventOutsideTheSensorNamesItsOffset) {
  Packet p;
  p.words = {pol(1, 1, true), 1, pol(346, 0, true), 2};
  auto err = read_error(make_aedat31_reader, file({p}), {}, "out.aedat");
  ASSERT_TRUE(err);
  EXPECT_EQ(err->offset(), kHeader.size() + 28 + 8);
  EXPECT_NE(std::string(err->what()).find("x=346"), std::string::npos) << err->what();

  p.words = {pol(0, 260, true), 1};
  err = read_error(make_aedat31_reader, file({p}));
  ASSERT_TRUE(err);
  EXPECT_EQ(err->offset(), kHeader.size() + 28);
}

}  // namespace
}  // namespace evpipe::testing
