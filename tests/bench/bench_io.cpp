// Decode throughput of the file readers, in million events per second (counter "Mev/s"; also
// items_per_second). Synthetic recordings are written to a temporary folder at start-up: AEDAT 4.0 (LZ4,
// zstd, none) and text with evpipe's writers, AEDAT 2.0 by hand in jAER's big-endian layout.
// EVPIPE_BENCH_FILE=<path> adds a benchmark that decodes that file (any format evpipe reads).

#include <benchmark/benchmark.h>

#include <unistd.h>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "evpipe/io/reader.hpp"
#include "evpipe/io/writer.hpp"

namespace {

namespace fs = std::filesystem;
using evpipe::Event;
using evpipe::kDavis346;

constexpr std::size_t kEvents = 2'000'000;

std::vector<Event> synthetic_events(std::size_t n) {
  std::vector<Event> events(n);
  std::uint32_t s = 12345;
  auto next = [&s] {
    s = s * 1664525u + 1013904223u;
    return s >> 8;
  };
  std::int64_t t = 0;  // starts at 0 so that AEDAT 2.0's int32 timestamps hold it (~40 s for 2 M events)
  for (auto& e : events) {
    t += next() % 40;
    e = Event{t, static_cast<std::uint16_t>(next() % kDavis346.width),
              static_cast<std::uint16_t>(next() % kDavis346.height), (next() & 1u) != 0};
  }
  return events;
}

/// jAER AEDAT 2.0 (formats.md §3): '#' header lines, then {uint32 address, int32 t} big-endian, DVS address
/// y<<22 | x<<12 | p<<11 with y counted from the bottom.
void write_aedat2(const fs::path& path, const std::vector<Event>& events) {
  std::ofstream out(path, std::ios::binary);
  out << "#!AER-DAT2.0\r\n# AEChip: eu.seebetter.ini.chips.davis.Davis346red\r\n";
  auto be32 = [](std::uint32_t v, char* p) {
    p[0] = static_cast<char>(v >> 24);
    p[1] = static_cast<char>(v >> 16);
    p[2] = static_cast<char>(v >> 8);
    p[3] = static_cast<char>(v);
  };
  std::vector<char> buf(events.size() * 8);
  char* p = buf.data();
  for (const Event& e : events) {
    const auto y_raw = static_cast<std::uint32_t>(kDavis346.height - 1 - e.y);
    const std::uint32_t address = (y_raw << 22) | (std::uint32_t{e.x} << 12) | (e.polarity ? 0x800u : 0u);
    be32(address, p);
    be32(static_cast<std::uint32_t>(e.t_us), p + 4);
    p += 8;
  }
  out.write(buf.data(), static_cast<std::streamsize>(buf.size()));
}

struct Fixtures {
  fs::path dir;
  std::string aedat4_lz4, aedat4_zstd, aedat4_none, aedat2, text;
  std::string error;  // first failure while writing (the dependent benchmarks then report it)

  Fixtures() {
    dir = fs::temp_directory_path() / ("evpipe-bench-io-" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const auto events = synthetic_events(kEvents);
    auto try_write = [&](const std::string& name, evpipe::io::Format format, const std::string& compression) {
      std::string path = (dir / name).string();
      try {
        evpipe::io::WriterOptions options;
        options.compression = compression;
        auto writer = evpipe::io::open_writer(path, format, options);
        writer->write(events);
        writer->close();
        return path;
      } catch (const std::exception& e) {
        if (error.empty()) error = e.what();
        return std::string{};
      }
    };
    aedat4_lz4 = try_write("synthetic-lz4.aedat4", evpipe::io::Format::aedat4, "lz4");
    aedat4_zstd = try_write("synthetic-zstd.aedat4", evpipe::io::Format::aedat4, "zstd");
    aedat4_none = try_write("synthetic-none.aedat4", evpipe::io::Format::aedat4, "none");
    text = try_write("synthetic.txt", evpipe::io::Format::text, "");
    aedat2 = (dir / "synthetic.aedat").string();
    write_aedat2(aedat2, events);
  }
  ~Fixtures() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
  Fixtures(const Fixtures&) = delete;
  Fixtures& operator=(const Fixtures&) = delete;
};

const Fixtures& fixtures() {
  static const Fixtures f;
  return f;
}

void decode_file(benchmark::State& state, const std::string& path) {
  if (path.empty()) {
    state.SkipWithError(("fixture not written: " + fixtures().error).c_str());
    return;
  }
  evpipe::io::ReaderOptions options;
  options.out_of_order = evpipe::io::OutOfOrderPolicy::keep;
  std::uint64_t events = 0;
  std::uint64_t bytes = 0;
  try {
    for (auto _ : state) {
      auto reader = evpipe::io::open_reader(path, options);
      std::uint64_t n = 0;
      while (auto batch = reader->next()) {
        n += batch->size();
        benchmark::DoNotOptimize(batch->events.data());
      }
      events += n;
      bytes += fs::file_size(path);
      state.counters["events"] = static_cast<double>(n);
    }
  } catch (const std::exception& e) {
    state.SkipWithError(e.what());
    return;
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(events));
  state.SetBytesProcessed(static_cast<std::int64_t>(bytes));
  state.counters["Mev/s"] = benchmark::Counter(static_cast<double>(events) / 1e6, benchmark::Counter::kIsRate);
}

void BM_DecodeAedat4Lz4(benchmark::State& state) {
  decode_file(state, fixtures().aedat4_lz4);
}
void BM_DecodeAedat4Zstd(benchmark::State& state) {
  decode_file(state, fixtures().aedat4_zstd);
}
void BM_DecodeAedat4None(benchmark::State& state) {
  decode_file(state, fixtures().aedat4_none);
}
void BM_DecodeAedat2(benchmark::State& state) {
  decode_file(state, fixtures().aedat2);
}
void BM_DecodeText(benchmark::State& state) {
  decode_file(state, fixtures().text);
}

BENCHMARK(BM_DecodeAedat4Lz4)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_DecodeAedat4Zstd)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_DecodeAedat4None)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_DecodeAedat2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_DecodeText)->Unit(benchmark::kMillisecond)->UseRealTime();

// EVPIPE_BENCH_FILE=<path>: decode a given recording (e.g. a real AEDAT 4.0 file).
const bool kFileBenchmark = [] {
  const char* path = std::getenv("EVPIPE_BENCH_FILE");
  if (path == nullptr || *path == '\0') return false;
  benchmark::RegisterBenchmark("BM_DecodeFile",
                               [p = std::string(path)](benchmark::State& state) {
                                 decode_file(state, p);
                                 state.SetLabel(p);
                               })
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
  return true;
}();

}  // namespace
