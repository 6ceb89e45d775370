// AEDAT 3.1 writer: cAER header lines, then polarity packets (formats.md §4). Used to make 3.1 fixtures
// (no 3.1 recording exists in public data). The sensor size goes into the '#Source' line ("WxH"), which
// evpipe's 3.1 reader parses, since the format has no size field.

#include <fmt/format.h>
#include <algorithm>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <stdexcept>
#include <utility>
#include <vector>

#include "detail.hpp"

namespace evpipe::io::detail {

namespace {

constexpr std::int16_t kPolarityEvent = 1;
constexpr std::int16_t kSourceId = 1;

void put_le16(std::vector<std::byte>& out, std::int16_t v) {
  const auto u = static_cast<std::uint16_t>(v);
  out.push_back(static_cast<std::byte>(u & 0xFFu));
  out.push_back(static_cast<std::byte>(u >> 8));
}
void put_le32(std::vector<std::byte>& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::byte>((v >> (8 * i)) & 0xFFu));
}

class Aedat31Writer final : public EventWriter {
 public:
  Aedat31Writer(const std::string& path, const WriterOptions& options)
      : path_(path), options_(options), packet_events_(std::max<std::size_t>(options.packet_events, 1)) {
    if (options_.geometry.width <= 0 || options_.geometry.height <= 0 || options_.geometry.width > kMaxSensorSide ||
        options_.geometry.height > kMaxSensorSide)
      throw std::invalid_argument(fmt::format("{}: sensor size {}x{} cannot be written to AEDAT 3.1", path,
                                              options_.geometry.width, options_.geometry.height));
    // Bounds the packet buffer (a packet could hold INT32_MAX events).
    packet_events_ = std::min<std::size_t>(packet_events_, std::size_t{1} << 20);
    out_ = std::make_unique<OutputFile>(path, options_.inputs);
    write_header();
  }

  ~Aedat31Writer() override {
    try {
      close();
    } catch (...) {  // NOLINT(bugprone-empty-catch): a destructor must not throw; call close() to see errors
    }
  }

  void write(EventSpan events, std::span<const Label> /*labels: AEDAT 3.1 has no label field*/) override {
    if (!out_->is_open()) throw SourceError(path_ + ": write after close");
    for (const Event& e : events) {
      check_in_sensor(path_, options_.geometry, e);
      // t = (overflow << 31) | ts with a 31-bit ts and an int32 overflow counter.
      constexpr std::int64_t kLimit = std::int64_t{1} << 62;
      if (e.t_us >= kLimit || e.t_us < -kLimit)
        throw std::invalid_argument(fmt::format("{}: timestamp {} us cannot be written to AEDAT 3.1", path_, e.t_us));
      const auto overflow = static_cast<std::int32_t>(e.t_us >> 31);
      if (!pending_.empty() && (overflow != overflow_ || pending_.size() >= packet_events_)) flush_packet();
      overflow_ = overflow;
      pending_.push_back(e);
    }
  }

  void close() override {
    if (!out_->is_open()) return;
    flush_packet();
    out_->close();
  }

 private:
  void write_header() {
    char when[64] = "1970-01-01 00:00:00 (TZ+0000)";
    const std::time_t now = std::time(nullptr);
    std::tm local{};
    if (localtime_r(&now, &local) != nullptr) std::strftime(when, sizeof when, "%Y-%m-%d %H:%M:%S (TZ%z)", &local);
    const SensorGeometry& g = options_.geometry;
    const char* sensor = g == kDavis346 ? "DAVIS346 " : g == kDavis240 ? "DAVIS240 " : "";
    std::string name = options_.source_name;
    for (char& c : name)
      if (c == '\r' || c == '\n') c = ' ';
    // The "WxH" token comes first: evpipe's reader takes the first such token as the sensor size.
    const std::string header =
        fmt::format("#!AER-DAT3.1\r\n#Format: RAW\r\n#Source {}: {}{}x{} ({})\r\n#Start-Time: {}\r\n#!END-HEADER\r\n",
                    kSourceId, sensor, g.width, g.height, name, when);
    out_->write(header.data(), header.size());
  }

  void flush_packet() {
    if (pending_.empty()) return;
    const auto n = static_cast<std::uint32_t>(pending_.size());
    buf_.clear();
    buf_.reserve(28 + 8 * pending_.size());
    put_le16(buf_, kPolarityEvent);
    put_le16(buf_, kSourceId);
    put_le32(buf_, 8);  // eventSize
    put_le32(buf_, 4);  // eventTSOffset
    put_le32(buf_, static_cast<std::uint32_t>(overflow_));
    put_le32(buf_, n);  // eventCapacity
    put_le32(buf_, n);  // eventNumber
    put_le32(buf_, n);  // eventValid
    for (const Event& e : pending_) {
      const std::uint32_t data =
          1u /*valid*/ | (e.polarity ? 1u << 1 : 0u) | (std::uint32_t{e.y} << 2) | (std::uint32_t{e.x} << 17);
      put_le32(buf_, data);
      put_le32(buf_, static_cast<std::uint32_t>(e.t_us & 0x7FFFFFFF));
    }
    pending_.clear();
    out_->write(buf_);
  }

  std::string path_;
  WriterOptions options_;
  std::size_t packet_events_;
  std::unique_ptr<OutputFile> out_;  // created after the options are checked
  std::vector<Event> pending_;
  std::vector<std::byte> buf_;
  std::int32_t overflow_ = 0;
};

}  // namespace

std::unique_ptr<EventWriter> make_aedat31_writer(const std::string& path, const WriterOptions& options) {
  return std::make_unique<Aedat31Writer>(path, options);
}

}  // namespace evpipe::io::detail
