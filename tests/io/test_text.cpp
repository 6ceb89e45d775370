// Text reader and writer: the real taro-dvstoolkit file (formats.md §10.1), the contract of interfaces.md,
// exact seconds parsing, error messages that name the line and byte offset, and round trips.

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "evpipe/io/reader.hpp"
#include "evpipe/io/writer.hpp"
#include "evpipe_test_data.hpp"
#include "io_test_util.hpp"
#include "sha1.hpp"

namespace evpipe::testing {
namespace {

using io::make_text_reader;
using io::ReaderOptions;

constexpr const char* kTaro = "davis240-text-taro/test-02.txt";

Drained read(const std::string& text, ReaderOptions o = {}) {
  auto r = make_text_reader(io::memory_source(bytes_of(text)), std::move(o));
  return drain(*r);
}

std::optional<FormatError> error_of(const std::string& text, ReaderOptions o = {}) {
  return read_error(make_text_reader, bytes_of(text), std::move(o), "events.txt");
}

/// Expects a FormatError naming the file, `line N` and the byte offset of that line.
void expect_error(const std::string& text, std::size_t line, const std::string& needle) {
  SCOPED_TRACE(text.substr(0, 200));
  const auto err = error_of(text);
  ASSERT_TRUE(err) << "no error for: " << needle;
  std::size_t offset = 0;
  for (std::size_t l = 1; l < line; ++l) offset = text.find('\n', offset) + 1;
  EXPECT_EQ(err->offset(), offset) << err->what();
  const std::string msg = err->what();
  EXPECT_NE(msg.find("events.txt: byte " + std::to_string(offset) + ": line " + std::to_string(line) + ":"),
            std::string::npos)
      << msg;
  EXPECT_NE(msg.find(needle), std::string::npos) << msg;
}

TEST(TextReal, TaroFileWithHeightWidthLine) {
  EVPIPE_REQUIRE_REAL(path, kTaro);
  auto r = io::open_reader(path);
  EXPECT_EQ(r->info().format, "text");
  EXPECT_EQ(r->info().geometry, kDavis240);
  EXPECT_TRUE(r->info().geometry_known);
  EXPECT_FALSE(r->info().labelled);
  const auto d = drain(*r);
  ASSERT_EQ(d.events.size(), 1'224u);
  EXPECT_EQ(d.events.front().t_us, 1'645'793'388'095'964);
  EXPECT_EQ(d.events.back().t_us, 1'645'793'388'104'036);
  EXPECT_EQ(fingerprint(d.events), "f4cef403eb87");
  EXPECT_TRUE(d.labels.empty());
  EXPECT_EQ(r->stats().out_of_order, 0u);
  EXPECT_EQ(r->stats().bytes_read, std::filesystem::file_size(path));
  EXPECT_TRUE(r->finished());
}

TEST(TextReal, TaroFileCutAnywhereNeverCrashes) {
  EVPIPE_REQUIRE_REAL(path, kTaro);
  const Bytes all = read_bytes(path);
  for (std::size_t cut = 0; cut <= all.size(); cut += (cut < 300 ? 1 : 97)) {
    const Bytes prefix(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(cut));
    try {
      auto r = make_text_reader(io::memory_source(prefix, "cut.txt"), {});
      drain(*r);
    } catch (const FormatError& e) {
      // A cut inside a line leaves a line of fewer columns: an error that names it.
      EXPECT_NE(std::string(e.what()).find("cut.txt: byte "), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(": line "), std::string::npos) << e.what();
      const std::string text = text_of(prefix);
      EXPECT_NE(text.back(), '\n') << "a cut at a line end must read cleanly: " << e.what();
    }
  }
}

TEST(Text, SeparatorsCommentsBlankLinesAndCrlf) {
  const auto d = read(
      "# a comment\r\n"
      "\r\n"
      "1 2 3 1\r\n"
      "  2,3,4,0\n"
      "3\t4\t5\t-1\n"
      "   # indented comment\n"
      "4 ,\t5 , 6 , +1  \n"
      "5 6 7 1");  // no final newline
  ASSERT_EQ(d.events.size(), 5u);
  EXPECT_EQ(d.events[0], (Event{1, 2, 3, true}));
  EXPECT_EQ(d.events[1], (Event{2, 3, 4, false}));
  EXPECT_EQ(d.events[2], (Event{3, 4, 5, false}));
  EXPECT_EQ(d.events[3], (Event{4, 5, 6, true}));
  EXPECT_EQ(d.events[4], (Event{5, 6, 7, true}));
}

TEST(Text, Utf8ByteOrderMarkIsSkipped) {
  const auto d = read("\xEF\xBB\xBF# width=10 height=20\n1 2 3 1\n");
  ASSERT_EQ(d.events.size(), 1U);
  EXPECT_EQ(d.events[0], (Event{1, 2, 3, true}));
  const auto e = read(
      "\xEF\xBB\xBF"
      "1 2 3 1\n");
  ASSERT_EQ(e.events.size(), 1U);
}

TEST(Text, GeometryFromCommentOrHeightWidthLineOrDefault) {
  auto r = make_text_reader(io::memory_source(bytes_of("# width=640 height=480\n1 639 479 1\n")), {});
  EXPECT_EQ(r->info().geometry, (SensorGeometry{640, 480}));
  EXPECT_TRUE(r->info().geometry_known);
  EXPECT_EQ(drain(*r).events.size(), 1u);

  auto hw = make_text_reader(io::memory_source(bytes_of("# taro\n180 240\n1 239 179 0\n")), {});
  EXPECT_EQ(hw->info().geometry, kDavis240);
  EXPECT_TRUE(hw->info().geometry_known);

  ReaderOptions o;
  o.default_geometry = {100, 50};
  auto def = make_text_reader(io::memory_source(bytes_of("1 99 49 0\n")), o);
  EXPECT_EQ(def->info().geometry, (SensorGeometry{100, 50}));
  EXPECT_FALSE(def->info().geometry_known);
  EXPECT_EQ(drain(*def).events.size(), 1u);

  expect_error("# width=240 height=180\n260 346\n1 1 1 1\n", 2, "contradicts");
  expect_error("0 240\n", 1, "sensor size 'H W'");
  expect_error("# width=abc height=5\n", 1, "bad sensor size");
}

TEST(Text, CommentsOnlyAndEmptyInputGiveNoEvents) {
  for (const char* text : {"", "# only\n# comments\n", "\n\n", "180 240\n"}) {
    auto r = make_text_reader(io::memory_source(bytes_of(text)), {});
    EXPECT_EQ(r->next(), nullptr) << text;
    EXPECT_TRUE(r->finished());
    EXPECT_EQ(r->stats().events, 0u);
  }
}

TEST(Text, SecondsAreParsedExactly) {
  const auto d = read(
      "1645793388.095964 1 1 1\n"
      "1645793388.1 1 1 1\n"
      "1645793389 1 1 1\n"             // integer in a seconds file: whole seconds
      "1645793389.0000004999 1 1 1\n"  // > 6 digits: rounded to the nearest microsecond
      "1645793389.0000005 1 1 1\n"     // half: away from zero
      "1645793389.9999996 1 1 1\n"     // rounds up into the next second
      "1645793391. 1 1 1\n");
  ASSERT_EQ(d.events.size(), 7u);
  EXPECT_EQ(d.events[0].t_us, 1'645'793'388'095'964);
  EXPECT_EQ(d.events[1].t_us, 1'645'793'388'100'000);
  EXPECT_EQ(d.events[2].t_us, 1'645'793'389'000'000);
  EXPECT_EQ(d.events[3].t_us, 1'645'793'389'000'000);
  EXPECT_EQ(d.events[4].t_us, 1'645'793'389'000'001);
  EXPECT_EQ(d.events[5].t_us, 1'645'793'390'000'000);
  EXPECT_EQ(d.events[6].t_us, 1'645'793'391'000'000);

  const auto small = read("0.000001 1 1 0\n.5 1 1 1\n-0.25 1 1 1\n", [] {
    ReaderOptions keep;
    keep.out_of_order = io::OutOfOrderPolicy::keep;
    return keep;
  }());
  ASSERT_EQ(small.events.size(), 3u);
  EXPECT_EQ(small.events[0].t_us, 1);
  EXPECT_EQ(small.events[1].t_us, 500'000);
  EXPECT_EQ(small.events[2].t_us, -250'000);
}

TEST(Text, MicrosecondFileRejectsADecimalPointLater) {
  expect_error("1 1 1 1\n2 1 1 1\n0.5 1 1 1\n", 3, "decimal point");
  expect_error("1.5e3 1 1 1\n", 1, "bad time");
  expect_error("1.2.3 1 1 1\n", 1, "bad time");
  expect_error("99999999999999999999 1 1 1\n", 1, "bad time");
  expect_error("99999999999999999.5 1 1 1\n", 1, "bad time");
}

TEST(Text, BadTokensNameTheLineAndOffset) {
  const std::string good = "# c\n1 1 1 1\n";
  expect_error(good + "2 a 1 1\n", 3, "bad x 'a'");
  expect_error(good + "2 1 1.0 1\n", 3, "bad y");
  expect_error(good + "2 1 1 2\n", 3, "bad polarity '2'");
  expect_error(good + "2 1 1\n", 3, "expected 4 or 5 columns");
  expect_error(good + "2 1 1 1 1 1\n", 3, "more than 5");
  expect_error(good + "2 1 1 1 1\n", 3, "5 columns, but the first event line has 4");
  expect_error("1 1 1 1 0\n2 1 1 1\n", 2, "4 columns, but the first event line has 5");
  expect_error("1 1 1 1 7\n", 1, "bad label '7'");
  expect_error(good + "2 1 1 1\x01\n", 3, "bad polarity '1\\x01'");
  expect_error("hello world 1 2\n", 1, "bad time 'hello'");
  expect_error(good + std::string(5000, '1') + "\n", 3, "longer than 4096");
}

TEST(Text, OutOfSensorCoordinatesNameTheLine) {
  expect_error("1 345 259 1\n2 346 0 1\n", 2, "x=346 y=0 is outside the 346x260 sensor");
  expect_error("# width=240 height=180\n1 0 180 1\n", 2, "outside the 240x180");
  expect_error("1 -1 0 1\n", 1, "x=-1");
  expect_error("1 0 99999999999 1\n", 1, "outside");
}

TEST(Text, LabelsFromTheFifthColumn) {
  ReaderOptions o;
  o.batch_events = 2;
  auto r = make_text_reader(io::memory_source(bytes_of("1 1 1 1 1\n2 2 2 0 0\n3 3 3 1 0\n")), o);
  EXPECT_TRUE(r->info().labelled);
  const auto d = drain(*r);
  ASSERT_EQ(d.events.size(), 3u);
  ASSERT_EQ(d.batches.size(), 2u);
  EXPECT_EQ(d.batches[0]->labels.size(), 2u);
  EXPECT_EQ(d.batches[1]->labels.size(), 1u);
  EXPECT_EQ(d.labels, (std::vector<Label>{Label::signal, Label::noise, Label::noise}));
}

TEST(Text, OutOfOrderAndDiscontinuities) {
  const std::string text = "100 1 1 1\n200 1 1 1\n150 1 1 1\n300 1 1 1\n5000000 1 1 1\n7 1 1 1\n8 1 1 1\n";
  WarningLog log;
  auto r = make_text_reader(io::memory_source(bytes_of(text)), log.attach());
  const auto d = drain(*r);
  ASSERT_EQ(d.events.size(), 6u);
  EXPECT_EQ(r->stats().out_of_order, 1u);
  EXPECT_EQ(r->stats().discontinuities, 1u);
  ASSERT_EQ(d.batches.size(), 2u);
  EXPECT_FALSE(d.batches[0]->discontinuity_before);
  EXPECT_TRUE(d.batches[1]->discontinuity_before);
  EXPECT_EQ(d.batches[1]->events.front().t_us, 7);
  ASSERT_GE(log.items->size(), 2u);
  EXPECT_EQ(log.items->at(0).offset, text.find("150"));

  ReaderOptions keep;
  keep.out_of_order = io::OutOfOrderPolicy::keep;
  const auto k = read(text, keep);
  ASSERT_EQ(k.events.size(), 7u);
  EXPECT_EQ(k.events[2].t_us, 150);
}

// Times up to +-2^61 us are read (their differences fit in int64); beyond that a line is refused as corrupt: one
// event at INT64_MAX made the filters' time steps overflow and spin (hostile test, session 23).
TEST(Text, ExtremeTimestampsAreHandledWithoutOverflow) {
  WarningLog log;
  auto r = make_text_reader(io::memory_source(bytes_of(
                                "2305843009213693952 1 1 1\n-2305843009213693952 1 1 1\n-2305843009213693951 1 1 0\n")),
                            log.attach());
  const auto d = drain(*r);
  ASSERT_EQ(d.events.size(), 3u);
  EXPECT_EQ(d.events[0].t_us, kMaxAbsTimestampUs);
  EXPECT_EQ(d.events[1].t_us, -kMaxAbsTimestampUs);
  EXPECT_EQ(r->stats().discontinuities, 1u);
  EXPECT_TRUE(log.any_contains("jumps back by 4611686018427387904 us"));
  expect_error("2305843009213693953 1 1 1\n", 1, "outside the supported range");
  expect_error("0 1 1 1\n-9223372036854775808 1 1 1\n", 2, "outside the supported range");
  expect_error("9223372036854775807 1 1 1\n", 1, "outside the supported range");
  expect_error("9223372036854775808 1 1 1\n", 1, "bad time");
  expect_error("9223372036854.775808 1 1 1\n", 1, "bad time");
}

TEST(Text, LabelledDiscontinuityKeepsLabelsAligned) {
  const auto d = read("5000000 1 1 1 0\n6000000 1 1 1 1\n1 2 2 0 0\n2 2 2 0 1\n");
  ASSERT_EQ(d.batches.size(), 2u);
  EXPECT_EQ(d.batches[0]->labels, (std::vector<Label>{Label::noise, Label::signal}));
  EXPECT_EQ(d.batches[1]->labels, (std::vector<Label>{Label::noise, Label::signal}));
  EXPECT_TRUE(d.batches[1]->discontinuity_before);
}

TEST(Text, CutAtEveryPointNeverCrashes) {
  const std::string text = "# width=64 height=32\n10 1 2 1 1\n20.5 3 4 0 0\n30 5 6 -1 1\n";
  for (std::size_t cut = 0; cut <= text.size(); ++cut) {
    try {
      read(text.substr(0, cut));
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("line "), std::string::npos) << e.what();
    }
  }
}

// ---- writer -------------------------------------------------------------------------------------

TEST(TextWriter, RoundTripWithAndWithoutLabels) {
  std::vector<Event> events;
  std::vector<Label> labels;
  for (int i = 0; i < 3000; ++i) {
    events.push_back({1'645'793'388'095'964 + std::int64_t{i} * 3, static_cast<std::uint16_t>(i % 346),
                      static_cast<std::uint16_t>((i * 7) % 260), (i % 3) == 0});
    labels.push_back(i % 5 == 0 ? Label::noise : Label::signal);
  }
  const auto dir = temp_dir("text");
  {
    const auto path = (dir / "labelled.txt").string();
    auto w = io::open_writer(path, io::Format::text);
    w->write(std::span(events).first(1000), std::span(labels).first(1000));
    w->write(std::span(events).subspan(1000), std::span(labels).subspan(1000));
    w->close();
    auto r = io::open_reader(path);
    EXPECT_TRUE(r->info().labelled);
    EXPECT_EQ(r->info().geometry, kDavis346);
    EXPECT_TRUE(r->info().geometry_known);
    const auto d = drain(*r);
    EXPECT_EQ(d.events, events);
    EXPECT_EQ(d.labels, labels);
    std::ifstream f(path);
    std::string first;
    std::getline(f, first);
    EXPECT_EQ(first, "# width=346 height=260");
    std::getline(f, first);
    EXPECT_EQ(first, "1645793388095964 0 0 1 0");
  }
  {
    const auto path = (dir / "plain.txt").string();
    io::WriterOptions o;
    o.write_labels = false;
    o.geometry = kDavis240;
    std::vector<Event> small(events.begin(), events.begin() + 10);
    for (auto& e : small) e.x = static_cast<std::uint16_t>(e.x % 240);
    auto w = io::open_writer(path, io::Format::text, o);
    w->write(small, std::span(labels).first(10));
    w->close();
    auto r = io::open_reader(path);
    EXPECT_FALSE(r->info().labelled);
    EXPECT_EQ(r->info().geometry, kDavis240);
    EXPECT_EQ(drain(*r).events, small);
  }
}

TEST(TextWriter, RejectsInconsistentInput) {
  const auto path = (temp_dir("text") / "bad.txt").string();
  auto w = io::open_writer(path, io::Format::text);
  const std::vector<Event> two = {{1, 1, 1, true}, {2, 2, 2, false}};
  const std::vector<Label> one = {Label::signal};
  EXPECT_THROW(w->write(two, one), std::invalid_argument);
  w->write(two);
  const std::vector<Label> both = {Label::signal, Label::noise};
  EXPECT_THROW(w->write(two, both), std::invalid_argument);  // labels after unlabelled lines
  const std::vector<Event> outside = {{3, 346, 0, true}};
  EXPECT_THROW(w->write(outside), std::invalid_argument);
  w->close();
  EXPECT_THROW(w->write(two), SourceError);
  EXPECT_THROW(io::open_writer("/nonexistent-dir/x.txt", io::Format::text), SourceError);
}

// Issue 17 row 3: '# width=65536 height=65536' was accepted and the filters then tried to allocate per-pixel state
// for 2^32 pixels (bad_alloc abort). A declared size beyond kMaxSensorSide is an error naming the line.
TEST(Text, SensorSizeBeyondTheLargestAcceptedIsAnError) {
  expect_error("# width=65536 height=65536\n1 1 1 1\n", 1, "0 < N <= 2048");
  expect_error("# width=2049 height=10\n1 1 1 1\n", 1, "the largest sensor evpipe accepts");
  expect_error("4096 4096\n1 1 1 1\n", 1, "each in 1..2048");
  EXPECT_EQ(read("# width=2048 height=2048\n1 2047 2047 1\n").events.size(), 1U);
  // The default size (source.default_width/height) is checked where a reader is opened.
  ReaderOptions o;
  o.default_geometry = {4096, 4096};
  EXPECT_THROW((void)io::open_reader(io::memory_source(bytes_of("1 1 1 1\n")), o), FormatError);
}

}  // namespace
}  // namespace evpipe::testing
