// Bad input on the wire (hostile-tester report D2-D4): LCM log files with a corrupt or truncated event are an error
// naming the file and the event's byte offset, after the events before it; lengths are checked against the file
// before anything is allocated. A stats_t whose array count cannot fit in its bytes is refused before the
// generated decode() allocates the array (a 153-byte message took ~15 GB), and wire_error() names the field.
// The same for preview_t (image_bytes, num_segments): decode_preview refuses the count before the generated decode()
// resizes the arrays, and preview_wire_error() names the field.
// This binary replaces the global operator new to see the largest allocation, so it has its own executable.
#include "evpipe/transport/codec.hpp"
#include "evpipe/transport/lcm_capture.hpp"
#include "evpipe/transport/preview.hpp"
#include "lcm_log_bytes.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <unistd.h>

#include <atomic>
#include <cstdlib>
#include <filesystem>
#include <new>
#include <random>

namespace {

std::atomic<bool> g_track{false};
std::atomic<std::size_t> g_largest{0};
char* volatile g_sink = nullptr;  // keeps a probe allocation from being optimised away

}  // namespace

void* operator new(std::size_t n) {
  if (g_track.load(std::memory_order_relaxed)) {
    std::size_t seen = g_largest.load(std::memory_order_relaxed);
    while (n > seen && !g_largest.compare_exchange_weak(seen, n)) {
    }
  }
  if (void* p = std::malloc(n == 0 ? 1 : n)) return p;
  throw std::bad_alloc();
}

// Not inlined: GCC would otherwise see free() of a pointer from operator new (-Wmismatched-new-delete).
__attribute__((noinline)) void operator delete(void* p) noexcept {
  std::free(p);
}

__attribute__((noinline)) void operator delete(void* p, std::size_t /*n*/) noexcept {
  std::free(p);
}

namespace evpipe::transport {
namespace {

namespace fs = std::filesystem;
using evpipe::testing::concat;
using evpipe::testing::lcm_event;
using evpipe::testing::set_be32;
using evpipe::testing::write_bytes;

constexpr std::size_t kMiB = 1024 * 1024;

/// The largest single allocation made by `f`.
template <typename F>
std::size_t largest_allocation(F&& f) {
  g_largest = 0;
  g_track = true;
  try {
    f();
  } catch (...) {
    g_track = false;
    throw;
  }
  g_track = false;
  return g_largest.load();
}

fs::path temp_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("evpipe_wire_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

PoseRecord pose(std::int64_t seq) {
  PoseRecord r;
  r.seq = seq;
  r.t_us = 1000 * seq;
  return r;
}

// A stats_t with source "" and no stages, queues or figures: its counts are at fixed offsets.
constexpr std::size_t kNumStagesAt = 8 + 5 * 8 + 5 + 1 + 8 + 1 + 8 + 8 + 8 + 8;
constexpr std::size_t kNumQueuesAt = kNumStagesAt + 4;
constexpr std::size_t kNumFiguresAt = kNumQueuesAt + 4;

std::vector<std::uint8_t> empty_stats() {
  StatsRecord s;
  s.source = "";
  return encode(s);
}

StatsRecord full_stats() {
  StatsRecord s;
  s.source = "replay";
  s.stages = {{"source", 1, 2, 3, 4, 5, 6.0, 7.0, 8.0}, {"pose", 9, 10, 11, 12, 13, 14.0, 15.0, 16.0}};
  s.queues = {{"batches", 64, 3, 12, 1000, 17, 1'000'000, 24'576, 250'000}, {"windows", 16, 0, 2, 330, 0, 0, 0, 0}};
  s.denoise_figures = {{"noise_rate_hz", 1.125}, {"density_threshold_used", 4}};
  return s;
}

std::string why(const std::vector<std::uint8_t>& bytes) {
  return wire_error(bytes.data(), bytes.size()).value_or("(none)");
}

TEST(WireCodec, TheAllocationProbeSeesAllocations) {
  const std::size_t largest = largest_allocation([] {
    std::vector<char> v(2 * kMiB);
    g_sink = v.data();
  });
  EXPECT_GE(largest, 2 * kMiB);
}

TEST(WireCodec, WellFormedAndForeignMessagesHaveNoWireError) {
  const auto stats = encode(full_stats());
  const auto empty = empty_stats();
  const auto p = encode(pose(3));
  EXPECT_FALSE(wire_error(stats.data(), stats.size())) << why(stats);
  EXPECT_FALSE(wire_error(empty.data(), empty.size())) << why(empty);
  EXPECT_FALSE(wire_error(p.data(), p.size())) << why(p);
  const std::vector<std::uint8_t> foreign(64, 0x5a);
  EXPECT_FALSE(wire_error(foreign.data(), foreign.size()));
  EXPECT_FALSE(wire_error(nullptr, 0));
  EXPECT_EQ(empty.size(), kNumFiguresAt + 4);  // the offsets below are right
  ASSERT_TRUE(decode_stats(stats.data(), stats.size()));
  EXPECT_EQ(decode_stats(stats.data(), stats.size())->queues.size(), 2U);
}

TEST(WireCodec, AHugeArrayCountIsRefusedBeforeAnythingIsAllocated) {
  struct Case {
    std::size_t at;
    std::uint32_t count;
    const char* field;
  };
  for (const Case& c : {Case{kNumQueuesAt, 0x10000000U, "stats_t.num_queues"},
                        Case{kNumFiguresAt, 50'000'000U, "stats_t.num_denoise_figures"},
                        Case{kNumFiguresAt, 0x7fffffffU, "stats_t.num_denoise_figures"},
                        Case{kNumStagesAt, 0x7fffffffU, "stats_t.num_stages"},
                        Case{kNumStagesAt, 1U, "stats_t.num_stages"},  // one stage needs 69 bytes, 8 are left
                        Case{kNumStagesAt, 0xffffffffU, "stats_t.num_stages"}}) {
    auto bytes = empty_stats();
    set_be32(bytes, c.at, c.count);
    std::optional<StatsRecord> out;
    const std::size_t largest = largest_allocation([&] { out = decode_stats(bytes.data(), bytes.size()); });
    EXPECT_FALSE(out) << c.field << " " << c.count;
    EXPECT_LT(largest, kMiB) << c.field << " " << c.count;
    const std::string w = why(bytes);
    EXPECT_EQ(w.rfind(fmt::format("{} at byte {} of {}: ", c.field, c.at, bytes.size()), 0), 0U) << w;
  }
}

TEST(WireCodec, AStringLengthBeyondTheBytesIsRefused) {
  auto bytes = encode(pose(1));
  set_be32(bytes, 8 + 3 * 8, 0x7fffffffU);  // camera_frame's length
  EXPECT_FALSE(decode_pose(bytes.data(), bytes.size()));
  EXPECT_EQ(why(bytes).rfind("pose_t.camera_frame at byte 32 of ", 0), 0U) << why(bytes);
  set_be32(bytes, 8 + 3 * 8, 0);  // a string always has its NUL
  EXPECT_FALSE(decode_pose(bytes.data(), bytes.size()));
  EXPECT_NE(why(bytes).find("string length 0"), std::string::npos) << why(bytes);
}

TEST(WireCodec, EveryTruncationIsRefusedAndNamed) {
  for (const auto& whole : {encode(full_stats()), encode(pose(2))}) {
    for (std::size_t n = 8; n < whole.size(); ++n) {
      EXPECT_NO_THROW({
        EXPECT_FALSE(decode_stats(whole.data(), n)) << n;
        EXPECT_FALSE(decode_pose(whole.data(), n)) << n;
      });
      const auto w = wire_error(whole.data(), n);
      ASSERT_TRUE(w) << n;
      EXPECT_NE(w->find(fmt::format(" of {}: ", n)), std::string::npos) << *w;
    }
  }
}

TEST(WireCodec, RandomCorruptionNeitherCrashesNorAllocatesMuch) {
  const auto whole = encode(full_stats());
  std::mt19937 rng(17);
  std::uniform_int_distribution<std::size_t> at(8, whole.size() - 1);  // keep the fingerprint
  std::uniform_int_distribution<int> byte(0, 255);
  for (int k = 0; k < 3000; ++k) {
    auto bytes = whole;
    for (int j = 0; j < 1 + k % 4; ++j) bytes[at(rng)] = static_cast<std::uint8_t>(byte(rng));
    const std::size_t largest = largest_allocation([&] {
      try {
        (void)decode_stats(bytes.data(), bytes.size());
      } catch (const DecodeError&) {
        // right type, invalid content: named, not a crash
      }
      (void)wire_error(bytes.data(), bytes.size());
    });
    ASSERT_LT(largest, 64 * 1024U) << k;
  }
}

// preview_t: the fixed fields take 100 bytes after the fingerprint's 8 (5 int64, 2 int8, 4 int32, 3 float, 2 int64,
// 2 int16, 2 int8), then image_bytes, the image, num_segments, 4 float arrays, the note.
constexpr std::size_t kImageBytesAt = 8 + 5 * 8 + 2 + 4 * 4 + 3 * 4 + 2 * 8 + 2 * 2 + 2;

std::uint32_t be32_at(const std::vector<std::uint8_t>& bytes, std::size_t at) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < 4; ++i) v = v << 8 | bytes.at(at + i);
  return v;
}

std::size_t num_segments_at(const std::vector<std::uint8_t>& bytes) {
  return kImageBytesAt + 4 + be32_at(bytes, kImageBytesAt);
}

PreviewRecord preview(int width, int height, std::size_t segments, std::uint32_t seed) {
  PreviewRecord r;
  r.seq = 11;
  r.utime_us = 1'700'000'000'000'000;
  r.t_us = 15'000;
  r.window_t1_us = 30'000;
  r.status = kPreviewStatusTracking;
  r.pose_valid = true;
  r.raw_events = 3000;
  r.kept_events = 400;
  r.pose_events = 500;
  r.inliers = 250;
  r.sigma_px = 0.75F;
  r.queue_drops = 2;
  r.width = width;
  r.height = height;
  r.bin = 2;
  std::mt19937 rng(seed);
  r.pixels.assign(static_cast<std::size_t>(width) * static_cast<std::size_t>(height), 0);
  for (auto& p : r.pixels) p = rng() % 8 == 0 ? static_cast<std::uint8_t>(1 + rng() % 3) : 0;  // sparse: RLE
  for (std::size_t i = 0; i < segments; ++i) {
    const auto f = static_cast<float>(i);
    r.segments.push_back({f, f + 0.5F, f + 1.25F, f * 2});
  }
  r.note = "tracking";
  return r;
}

std::string preview_why(const std::vector<std::uint8_t>& bytes) {
  return preview_wire_error(bytes.data(), bytes.size()).value_or("(none)");
}

TEST(WirePreview, WellFormedPreviewsRoundTripAndHaveNoWireError) {
  auto noise = preview(40, 30, 3, 5);
  std::mt19937 rng(9);
  for (auto& p : noise.pixels) p = static_cast<std::uint8_t>(rng() % 4);  // packed
  auto bare = preview(1, 1, 0, 1);
  bare.note.clear();
  for (const PreviewRecord& r : {preview(20, 15, 2, 3), noise, bare, preview(346, 260, 40, 4)}) {
    const auto bytes = encode(r);
    EXPECT_FALSE(preview_wire_error(bytes.data(), bytes.size())) << preview_why(bytes);
    EXPECT_EQ(be32_at(bytes, num_segments_at(bytes)), r.segments.size());  // the offsets the tests use are right
    std::optional<PreviewRecord> d;
    ASSERT_NO_THROW(d = decode_preview(bytes.data(), bytes.size()));
    ASSERT_TRUE(d);
    EXPECT_EQ(d->seq, r.seq);
    EXPECT_EQ(d->utime_us, r.utime_us);
    EXPECT_EQ(d->status, r.status);
    EXPECT_EQ(d->pose_valid, r.pose_valid);
    EXPECT_EQ(d->inliers, r.inliers);
    EXPECT_EQ(d->queue_drops, r.queue_drops);
    EXPECT_EQ(d->width, r.width);
    EXPECT_EQ(d->height, r.height);
    EXPECT_EQ(d->bin, r.bin);
    EXPECT_EQ(d->pixels, r.pixels);
    ASSERT_EQ(d->segments.size(), r.segments.size());
    for (std::size_t i = 0; i < r.segments.size(); ++i) {
      EXPECT_EQ(d->segments[i].x0_px, r.segments[i].x0_px);
      EXPECT_EQ(d->segments[i].y0_px, r.segments[i].y0_px);
      EXPECT_EQ(d->segments[i].x1_px, r.segments[i].x1_px);
      EXPECT_EQ(d->segments[i].y1_px, r.segments[i].y1_px);
    }
    EXPECT_EQ(d->note, r.note);
  }
  // Other types are not previews, and a preview is not one of them: nothing to say either way.
  const auto p = encode(pose(1));
  EXPECT_FALSE(preview_wire_error(p.data(), p.size()));
  EXPECT_FALSE(decode_preview(p.data(), p.size()));
  const auto pv = encode(preview(4, 4, 1, 2));
  EXPECT_FALSE(wire_error(pv.data(), pv.size()));
  EXPECT_FALSE(preview_wire_error(nullptr, 0));
  EXPECT_FALSE(decode_preview(nullptr, 0));
}

TEST(WirePreview, AHugeOrNegativeCountIsRefusedBeforeAnythingIsAllocated) {
  const auto whole = encode(preview(20, 15, 2, 3));  // a couple of hundred bytes
  ASSERT_LT(whole.size(), 400U);
  struct Case {
    std::size_t at;
    std::uint32_t count;
    const char* field;
    const char* reason;
  };
  const std::size_t segs_at = num_segments_at(whole);
  const std::size_t image_left = whole.size() - kImageBytesAt - 4;
  const std::size_t segs_left = whole.size() - segs_at - 4;
  for (const Case& c : {
           Case{kImageBytesAt, 0x10000000U, "preview_t.image_bytes", "count 268435456 needs"},
           Case{kImageBytesAt, 0x7fffffffU, "preview_t.image_bytes", "count 2147483647 needs"},
           Case{kImageBytesAt, static_cast<std::uint32_t>(image_left + 1), "preview_t.image_bytes", "needs"},
           Case{kImageBytesAt, 0xffffffffU, "preview_t.image_bytes", "negative count -1"},
           Case{kImageBytesAt, 0x80000000U, "preview_t.image_bytes", "negative count -2147483648"},
           Case{segs_at, 0x10000000U, "preview_t.num_segments", "count 268435456 needs"},
           Case{segs_at, 0x7fffffffU, "preview_t.num_segments", "count 2147483647 needs"},
           Case{segs_at, static_cast<std::uint32_t>(segs_left / 16 + 1), "preview_t.num_segments", "needs"},
           Case{segs_at, 0xffffffffU, "preview_t.num_segments", "negative count -1"},
           Case{segs_at, 0x80000000U, "preview_t.num_segments", "negative count -2147483648"},
       }) {
    auto bytes = whole;
    set_be32(bytes, c.at, c.count);
    std::optional<PreviewRecord> out;
    const std::size_t largest = largest_allocation([&] { out = decode_preview(bytes.data(), bytes.size()); });
    EXPECT_FALSE(out) << c.field << " " << c.count;
    EXPECT_LT(largest, kMiB) << c.field << " " << c.count;
    const std::string w = preview_why(bytes);
    EXPECT_EQ(w.rfind(fmt::format("{} at byte {} of {}: ", c.field, c.at, bytes.size()), 0), 0U) << w;
    EXPECT_NE(w.find(c.reason), std::string::npos) << w;
  }
  // A count that does fit, leaving too few bytes for the fields after it: the field that runs out is named.
  auto bytes = whole;
  set_be32(bytes, kImageBytesAt, static_cast<std::uint32_t>(image_left));
  EXPECT_FALSE(decode_preview(bytes.data(), bytes.size()));
  EXPECT_EQ(preview_why(bytes), fmt::format("preview_t.num_segments at byte {0} of {0}: 4 bytes needed, 0 left "
                                            "(truncated)",
                                            bytes.size()));
}

TEST(WirePreview, ANoteLengthBeyondTheBytesIsRefused) {
  const auto whole = encode(preview(20, 15, 2, 3));
  const std::size_t note_at = num_segments_at(whole) + 4 + 2 * 16;
  ASSERT_EQ(be32_at(whole, note_at), std::string("tracking").size() + 1);
  for (const std::uint32_t n : {0x7fffffffU, 0U, 0xffffffffU, 10U}) {
    auto bytes = whole;
    set_be32(bytes, note_at, n);
    std::optional<PreviewRecord> out;
    const std::size_t largest = largest_allocation([&] { out = decode_preview(bytes.data(), bytes.size()); });
    EXPECT_FALSE(out) << n;
    EXPECT_LT(largest, kMiB) << n;
    EXPECT_EQ(preview_why(bytes).rfind(fmt::format("preview_t.note at byte {} of ", note_at), 0), 0U)
        << preview_why(bytes);
  }
}

TEST(WirePreview, EveryTruncationIsRefusedAndNamed) {
  for (const auto& whole : {encode(preview(20, 15, 2, 3)), encode(preview(1, 1, 0, 1))}) {
    for (std::size_t n = 0; n < whole.size(); ++n) {
      std::optional<PreviewRecord> out;
      EXPECT_NO_THROW(out = decode_preview(whole.data(), n)) << n;
      EXPECT_FALSE(out) << n;
      const auto w = preview_wire_error(whole.data(), n);
      if (n < 8) {
        EXPECT_FALSE(w) << n;  // no whole fingerprint: not known to be a preview
        continue;
      }
      ASSERT_TRUE(w) << n;
      EXPECT_NE(w->find(fmt::format(" of {}: ", n)), std::string::npos) << *w;
    }
  }
}

TEST(WirePreview, RandomCorruptionNeitherCrashesNorAllocatesMuch) {
  const auto whole = encode(preview(20, 15, 2, 3));
  const std::size_t segs_at = num_segments_at(whole);
  std::mt19937 rng(23);
  std::uniform_int_distribution<std::size_t> at(8, whole.size() - 1);  // keep the fingerprint
  std::uniform_int_distribution<std::size_t> count_byte(0, 7);         // a byte of image_bytes or num_segments
  std::uniform_int_distribution<int> byte(0, 255);
  int decoded = 0;
  int refused = 0;
  int invalid = 0;
  for (int k = 0; k < 4000; ++k) {
    auto bytes = whole;
    for (int j = 0; j < 1 + k % 4; ++j) bytes[at(rng)] = static_cast<std::uint8_t>(byte(rng));
    if (k % 2 == 0) {
      const std::size_t b = count_byte(rng);
      bytes[b < 4 ? kImageBytesAt + b : segs_at + b - 4] = static_cast<std::uint8_t>(byte(rng));
    }
    const std::size_t largest = largest_allocation([&] {
      try {
        if (decode_preview(bytes.data(), bytes.size())) {
          ++decoded;
        } else {
          ++refused;
          EXPECT_TRUE(preview_wire_error(bytes.data(), bytes.size())) << k;
        }
      } catch (const DecodeError&) {
        ++invalid;  // right type, invalid content (image, size, coordinates): named, not a crash
      }
    });
    // A preview has at most 1 000 000 pixels (a byte each once decoded); a corrupt width x height may claim that.
    ASSERT_LT(largest, 2 * kMiB) << k;
  }
  EXPECT_GT(refused, 0);
  EXPECT_GT(decoded + invalid, 0);
}

TEST(WireLog, AWholeLogIsReadEventByEvent) {
  const fs::path dir = temp_dir("good");
  const fs::path log = dir / "good.lcmlog";
  write_bytes(log, concat({lcm_event("EVPIPE_POSE", encode(pose(0)), 0), lcm_event("OTHER", {}, 1),
                           lcm_event("EVPIPE_STATS", encode(full_stats()), 2)}));
  const auto events = read_lcm_log(log);
  ASSERT_EQ(events.size(), 3U);
  EXPECT_EQ(events[0].channel, "EVPIPE_POSE");
  EXPECT_EQ(events[0].recv_utime_us, 1'700'000'000'000'000);
  EXPECT_EQ(decode_pose(events[0].data.data(), events[0].data.size())->seq, 0);
  EXPECT_EQ(events[1].channel, "OTHER");
  EXPECT_TRUE(events[1].data.empty());
  EXPECT_EQ(events[2].recv_utime_us, 1'700'000'000'000'002);
  EXPECT_TRUE(decode_stats(events[2].data.data(), events[2].data.size()));
  write_bytes(log, {});
  EXPECT_TRUE(read_lcm_log(log).empty());
  fs::remove_all(dir);
}

// Each bad log: the events before the bad one are returned, the error names the file and the bad event's offset.
TEST(WireLog, ABadEventIsAnErrorNamingFileAndOffsetAfterTheEventsBeforeIt) {
  const fs::path dir = temp_dir("bad");
  const auto good0 = lcm_event("EVPIPE_POSE", encode(pose(0)), 0);
  const auto good1 = lcm_event("EVPIPE_POSE", encode(pose(1)), 1);
  const auto next = lcm_event("EVPIPE_POSE", encode(pose(2)), 2);
  auto bad_sync = next;
  bad_sync[0] = 0x00;
  const std::vector<std::uint8_t> cut(next.begin(), next.end() - 100);
  const std::vector<std::uint8_t> cut_header(next.begin(), next.begin() + 10);
  struct Case {
    const char* name;
    std::vector<std::uint8_t> bad;
    const char* reason;
  };
  const std::vector<Case> cases = {
      {"cut", cut, "truncated or corrupt: channel name and data are 11 + "},
      {"cut_header", cut_header, "truncated: the file ends 10 bytes into the 28-byte event header"},
      {"bad_sync", bad_sync, "no event sync word 0xEDA1DA01 (found 0x00A1DA01)"},
      {"huge_len", lcm_event("EVPIPE_POSE", encode(pose(2)), 2, {}, 0x7fffffffU),
       "truncated or corrupt: channel name and data are 11 + 2147483647 bytes"},
      {"negative_len", lcm_event("EVPIPE_POSE", encode(pose(2)), 2, {}, 0x80000100U),
       "negative data length -2147483392"},
      {"huge_channel", lcm_event("EVPIPE_POSE", encode(pose(2)), 2, 0x7fffffffU), "channel name length 2147483647"},
      {"no_channel", lcm_event("EVPIPE_POSE", encode(pose(2)), 2, 0U), "channel name length 0"},
  };
  for (const Case& c : cases) {
    for (const bool first : {false, true}) {  // after two good events, and as the first event
      const fs::path log = dir / (std::string(c.name) + (first ? "_first" : "") + ".lcmlog");
      write_bytes(log, first ? c.bad : concat({good0, good1, c.bad}));
      const std::size_t offset = first ? 0 : good0.size() + good1.size();
      try {
        std::vector<ReceivedMessage> events;
        const std::size_t largest = largest_allocation([&] { events = read_lcm_log(log); });
        ADD_FAILURE() << c.name << ": accepted, " << events.size() << " events, largest allocation " << largest;
      } catch (const LcmLogError& e) {
        const std::string what = e.what();
        if (first && std::string_view(c.name) == "bad_sync") {  // at byte 0: not a log at all
          EXPECT_EQ(what, log.string() + ": not an LCM log file (no LCM event sync word 0xEDA1DA01 at byte 0)");
        } else {
          EXPECT_EQ(what.rfind(fmt::format("{}: LCM log event at byte {}: ", log.string(), offset), 0), 0U) << what;
          EXPECT_NE(what.find(c.reason), std::string::npos) << what;
        }
        EXPECT_EQ(e.offset(), offset);
        ASSERT_EQ(e.messages().size(), first ? 0U : 2U) << what;
        if (!first) {
          const auto p = decode_pose(e.messages()[1].data.data(), e.messages()[1].data.size());
          ASSERT_TRUE(p);
          EXPECT_EQ(p->seq, 1);
        }
      }
      // The streaming form has delivered the same events before it throws.
      std::size_t delivered = 0;
      EXPECT_THROW(read_lcm_log(log, [&](ReceivedMessage&&) { ++delivered; }), LcmLogError) << c.name;
      EXPECT_EQ(delivered, first ? 0U : 2U) << c.name;
    }
  }
  fs::remove_all(dir);
}

TEST(WireLog, AHugeDataLengthAllocatesNothing) {
  const fs::path dir = temp_dir("huge");
  const fs::path log = dir / "huge.lcmlog";
  write_bytes(log, lcm_event("EVPIPE_POSE", encode(pose(0)), 0, {}, 0x7fffffffU));
  const std::size_t largest = largest_allocation([&] { EXPECT_THROW((void)read_lcm_log(log), LcmLogError); });
  EXPECT_LT(largest, kMiB);
  fs::remove_all(dir);
}

TEST(WireLog, AFileThatIsNotALogIsStillNamedAsSuch) {
  const fs::path dir = temp_dir("notlog");
  const fs::path text = dir / "notes.txt";
  write_bytes(text, {'h', 'i', '\n'});
  try {
    (void)read_lcm_log(text);
    FAIL();
  } catch (const LcmLogError& e) {
    EXPECT_EQ(std::string(e.what()),
              text.string() + ": not an LCM log file (no LCM event sync word 0xEDA1DA01 at byte 0)");
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace evpipe::transport
