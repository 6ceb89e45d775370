// Writes seed corpora for the reader fuzzers: small valid files made by evpipe's own writers (AEDAT 4.0,
// AEDAT 3.1, text), hand-built AEDAT 2.0 files, and, when the third-party recordings are available,
// small crops of their starts (generated at fuzz time into the build directory, never into the repo); for the
// LCM fuzzer, evpipe's pose_t, stats_t and preview_t messages, alone and as a log.
//
//   evpipe_fuzz_seeds OUT_DIR [REAL_DATA_DIR]
//   -> OUT_DIR/{aedat2,aedat31,aedat4,text,lcm}/<seed files>

#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "evpipe/io/writer.hpp"
#include "evpipe/transport/codec.hpp"
#include "evpipe/transport/preview.hpp"

namespace fs = std::filesystem;
using evpipe::Event;
using evpipe::Label;

namespace {

std::vector<Event> synthetic_events(std::size_t n, evpipe::SensorGeometry g, std::int64_t t0, std::int64_t step) {
  std::vector<Event> ev;
  std::uint32_t state = 12345;
  auto rnd = [&state] {
    state = state * 1'103'515'245u + 12'345u;
    return state >> 8;
  };
  std::int64_t t = t0;
  for (std::size_t i = 0; i < n; ++i) {
    t += static_cast<std::int64_t>(rnd() % static_cast<std::uint32_t>(step + 1));
    ev.push_back({t, static_cast<std::uint16_t>(rnd() % static_cast<std::uint32_t>(g.width)),
                  static_cast<std::uint16_t>(rnd() % static_cast<std::uint32_t>(g.height)), (rnd() & 1u) != 0});
  }
  return ev;
}

void write_with(const fs::path& path, evpipe::io::Format format, const std::vector<Event>& events,
                evpipe::io::WriterOptions options, const std::vector<Label>& labels = {}) {
  auto w = evpipe::io::open_writer(path.string(), format, options);
  w->write(events, labels);
  w->close();
}

void put_be32(std::string& out, std::uint32_t v) {
  for (int i = 3; i >= 0; --i) out += static_cast<char>((v >> (8 * i)) & 0xFFu);
}

void save(const fs::path& path, const std::string& bytes) {
  std::ofstream f(path, std::ios::binary);
  f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

// One event of an LCM log (lcm-logger's format: sync word, event number, time, channel length, data length,
// channel, data; big-endian).
std::string lcm_event(std::uint64_t number, const std::string& channel, const std::vector<std::uint8_t>& data) {
  std::string out;
  put_be32(out, 0xEDA1DA01u);
  for (const std::uint64_t v : {number, std::uint64_t{1'700'000'000'000'000} + number}) {
    put_be32(out, static_cast<std::uint32_t>(v >> 32));
    put_be32(out, static_cast<std::uint32_t>(v));
  }
  put_be32(out, static_cast<std::uint32_t>(channel.size()));
  put_be32(out, static_cast<std::uint32_t>(data.size()));
  return out + channel + std::string(data.begin(), data.end());
}

std::string load(const fs::path& path, std::size_t max_bytes) {
  std::ifstream f(path, std::ios::binary);
  std::string s(max_bytes, '\0');
  f.read(s.data(), static_cast<std::streamsize>(max_bytes));
  s.resize(static_cast<std::size_t>(f.gcount()));
  return s;
}

/// A jAER file: header lines (CRLF or LF), DVS words, IMU/APS/special words, a 2^31 wrap.
std::string aedat2_file(const char* chip, const char* eol, bool wrap, bool partial_tail) {
  std::string s = std::string("#!AER-DAT2.0") + eol + "# This is a raw AE data file" + eol + "# AEChip: " + chip + eol +
                  "#End Of ASCII Header" + eol;
  std::int32_t ts = wrap ? INT32_MAX - 40 : 1000;
  for (std::uint32_t i = 0; i < 40; ++i) {
    const std::uint32_t x = (i * 37) % 240;
    const std::uint32_t y = (i * 11) % 180;
    std::uint32_t addr = (y << 22) | (x << 12) | ((i & 1u) << 11);
    if (i % 9 == 4) addr = 0x80000C00u | (i << 12);  // IMU word
    if (i % 13 == 6) addr = 0x00000400u;             // special
    put_be32(s, addr);
    put_be32(s, static_cast<std::uint32_t>(ts));
    ts = static_cast<std::int32_t>(static_cast<std::uint32_t>(ts) + 3u);  // wraps through INT32_MIN
  }
  if (partial_tail) s += std::string("\x01\x02\x03", 3);
  return s;
}

/// The first `keep_lines` header lines of a jAER recording, its last header line, and `records` body words.
std::string crop_aedat2(const fs::path& path, std::size_t keep_lines, std::size_t records) {
  std::ifstream f(path, std::ios::binary);
  std::string out;
  std::string line;
  std::size_t n = 0;
  std::string last;
  while (f.peek() == '#' && std::getline(f, line)) {
    if (n++ < keep_lines) out += line + "\n";
    last = line + "\n";
  }
  out += last;
  std::string body(records * 8, '\0');
  f.read(body.data(), static_cast<std::streamsize>(body.size()));
  body.resize(static_cast<std::size_t>(f.gcount()));
  return out + body;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: %s OUT_DIR [REAL_DATA_DIR]\n", argv[0]);
    return 2;
  }
  try {
    const fs::path out = argv[1];
    for (const char* sub : {"aedat2", "aedat31", "aedat4", "text", "lcm"}) fs::create_directories(out / sub);
    using evpipe::io::Format;
    evpipe::io::WriterOptions o;
    o.packet_events = 16;

    // AEDAT 4.0: each compression, the DAVIS346 default and a small odd size.
    const auto ev346 = synthetic_events(50, evpipe::kDavis346, 1'589'163'147'368'868, 300);
    for (const char* c : {"none", "lz4", "zstd"}) {
      o.compression = c;
      write_with(out / "aedat4" / (std::string("writer-") + c + ".aedat4"), Format::aedat4, ev346, o);
    }
    evpipe::io::WriterOptions small = o;
    small.geometry = {17, 9};
    small.compression = "none";
    write_with(out / "aedat4" / "writer-17x9.aedat4", Format::aedat4, synthetic_events(20, small.geometry, 0, 5),
               small);

    // AEDAT 3.1: times across 2^31 (the overflow counter changes), and a 240x180 file.
    o.compression = "lz4";
    write_with(out / "aedat31" / "writer-overflow.aedat", Format::aedat31,
               synthetic_events(60, evpipe::kDavis346, (std::int64_t{1} << 31) - 200, 10), o);
    evpipe::io::WriterOptions o240 = o;
    o240.geometry = evpipe::kDavis240;
    write_with(out / "aedat31" / "writer-240.aedat", Format::aedat31, synthetic_events(30, o240.geometry, 5, 3), o240);
    save(out / "aedat31" / "header-only.aedat",
         "#!AER-DAT3.1\r\n#Format: RAW\r\n#Source 1: DAVIS346\r\n#Start-Time: 2020-01-01 00:00:00 (TZ+0000)\r\n"
         "#!END-HEADER\r\n");

    // Text: labelled and unlabelled writer output, plus the hand-written variants of the contract.
    std::vector<Label> labels;
    for (std::size_t i = 0; i < 30; ++i) labels.push_back(i % 3 == 0 ? Label::noise : Label::signal);
    write_with(out / "text" / "writer-labelled.txt", Format::text, synthetic_events(30, evpipe::kDavis346, 100, 9), o,
               labels);
    write_with(out / "text" / "writer-plain.txt", Format::text, synthetic_events(30, evpipe::kDavis240, 1, 2), o240);
    save(out / "text" / "seconds.txt",
         "# seconds, commas, tabs, -1/1 polarity\n1645793388.095964,1,2,-1\n1645793388.1\t3\t4\t1\n"
         "1645793389.0000005 5 6 1\n");
    save(out / "text" / "height-width.txt", "180 240\r\n1645793388095964  96 133 0\r\n1645793388095973 127 171 1\r\n");

    // AEDAT 2.0 (evpipe has no 2.0 writer): hand-built files.
    save(out / "aedat2" / "davis240-crlf.aedat",
         aedat2_file("eu.seebetter.ini.chips.davis.DAVIS240C", "\r\n", false, false));
    save(out / "aedat2" / "davis346-lf-wrap.aedat",
         aedat2_file("eu.seebetter.ini.chips.davis.Davis346red", "\n", true, true));
    save(out / "aedat2" / "unknown-chip.aedat",
         aedat2_file("ch.unizh.ini.jaer.chip.retina.DVS128", "\r\n", false, false));

    // LCM: a pose, a statistics message and a preview, each alone and the three as a log.
    evpipe::transport::PoseRecord pose;
    pose.status = evpipe::transport::TrackingStatus::tracking;
    pose.pose_valid = true;
    evpipe::transport::StatsRecord stats;
    stats.queues.resize(2);
    evpipe::transport::PreviewRecord preview;
    preview.width = 8;
    preview.height = 6;
    preview.pixels.assign(48, 0);
    preview.pixels[9] = 1;
    preview.segments.resize(2);
    const std::vector<std::vector<std::uint8_t>> messages = {
        evpipe::transport::encode(pose), evpipe::transport::encode(stats), evpipe::transport::encode(preview)};
    const char* channels[] = {"EVPIPE_POSE", "EVPIPE_STATS", "EVPIPE_PREVIEW"};
    std::string log;
    for (std::size_t i = 0; i < messages.size(); ++i) {
      save(out / "lcm" / (std::string(channels[i]) + ".msg"), std::string(messages[i].begin(), messages[i].end()));
      log += lcm_event(i, channels[i], messages[i]);
    }
    save(out / "lcm" / "three.lcmlog", log);

    // Crops of the real recordings, when present.
    if (argc >= 3 && fs::is_directory(argv[2])) {
      const fs::path real = argv[2];
      for (const char* rel : {"davis240c-rotdisk/IMU_rotDisk.aedat", "davis240c-translboxes/IMU_translBoxes.aedat"})
        if (fs::exists(real / rel))
          save(out / "aedat2" / ("crop-" + fs::path(rel).parent_path().string() + ".aedat"),
               crop_aedat2(real / rel, 12, 300));
      if (const auto p = real / "davis346red-aedat2-header/sample_aedat_header.aedat"; fs::exists(p))
        save(out / "aedat2" / "crop-davis346red-header.aedat", load(p, 4096));
      if (const auto p = real / "davis240-text-taro/test-02.txt"; fs::exists(p))
        save(out / "text" / "crop-taro.txt", load(p, 2048));
      for (const char* rel : {"davis346-faery-trimmed/sample.aedat4", "dvxplorer-tonic/sample.aedat4"})
        if (fs::exists(real / rel))
          save(out / "aedat4" / ("crop-" + fs::path(rel).parent_path().string() + ".aedat4"), load(real / rel, 12'000));
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "evpipe_fuzz_seeds: %s\n", e.what());
    return 1;
  }
  return 0;
}
