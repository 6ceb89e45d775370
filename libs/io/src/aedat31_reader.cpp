// AEDAT 3.1 (cAER) reader: '#' header lines up to '#!END-HEADER', then little-endian packets of a 28-byte
// libcaer packet header followed by eventNumber x eventSize bytes (formats.md §4). Only polarity packets
// give events; TIMESTAMP_RESET special events are clock discontinuities; everything else is skipped.

#include <fmt/format.h>
#include <algorithm>
#include <cctype>
#include <charconv>
#include <string>
#include <string_view>

#include "chunked_input.hpp"
#include "detail.hpp"

namespace evpipe::io {

namespace {

constexpr std::size_t kMaxHeaderLine = std::size_t{1} << 20;
constexpr std::size_t kPacketHeaderBytes = 28;
constexpr std::size_t kEventBytes = 8;  // polarity and special events: {uint32 data; int32 timestamp}
constexpr std::string_view kMagic = "#!AER-DAT3.1";
constexpr std::string_view kEndHeader = "#!END-HEADER";

constexpr std::int16_t kSpecialEvent = 0;
constexpr std::int16_t kPolarityEvent = 1;
constexpr std::uint32_t kSpecialTimestampReset = 1;

std::string upper(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  return out;
}

/// Geometry from a '#Source <id>: <description>' line: an explicit "WxH" token (written by evpipe's
/// AEDAT 3.1 writer), else the sensor named by the description; nullopt when neither is present.
std::optional<SensorGeometry> geometry_of_source(std::string_view description) {
  auto alnum = [](char c) { return std::isalnum(static_cast<unsigned char>(c)) != 0; };
  auto parse_int = [](std::string_view digits, int& v) {
    const auto [p, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), v);
    return ec == std::errc{} && p == digits.data() + digits.size() && !digits.empty();
  };
  std::size_t i = 0;
  while (i < description.size()) {
    if (!alnum(description[i])) {
      ++i;
      continue;
    }
    std::size_t j = i;
    while (j < description.size() && alnum(description[j])) ++j;
    const auto token = description.substr(i, j - i);
    i = j;
    const auto x = token.find_first_of("xX");
    if (x == std::string_view::npos) continue;
    int w = 0;
    int h = 0;
    // 15-bit address fields: a larger size cannot be addressed.
    if (parse_int(token.substr(0, x), w) && parse_int(token.substr(x + 1), h) && w > 0 && h > 0 && w <= 32768 &&
        h <= 32768)
      return SensorGeometry{w, h};
  }
  const std::string name = upper(description);
  if (name.find("DAVIS346") != std::string::npos) return kDavis346;
  if (name.find("DAVIS240") != std::string::npos) return kDavis240;
  return std::nullopt;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t')) s.remove_suffix(1);
  return s;
}

struct PacketHeader {
  std::int16_t type = 0;
  std::int16_t source = 0;
  std::int32_t event_size = 0;
  std::int32_t ts_offset = 0;
  std::int32_t ts_overflow = 0;
  std::int32_t capacity = 0;
  std::int32_t number = 0;
  std::int32_t valid = 0;
};

PacketHeader parse_packet_header(const std::byte* p) {
  using detail::load_le;
  PacketHeader h;
  h.type = load_le<std::int16_t>(p);
  h.source = load_le<std::int16_t>(p + 2);
  h.event_size = load_le<std::int32_t>(p + 4);
  h.ts_offset = load_le<std::int32_t>(p + 8);
  h.ts_overflow = load_le<std::int32_t>(p + 12);
  h.capacity = load_le<std::int32_t>(p + 16);
  h.number = load_le<std::int32_t>(p + 20);
  h.valid = load_le<std::int32_t>(p + 24);
  return h;
}

class Aedat31Reader final : public FileReader {
 public:
  Aedat31Reader(std::unique_ptr<ByteSource> source, ReaderOptions options)
      : source_(std::move(source)),
        options_(std::move(options)),
        in_(*source_),
        builder_(options_, stats_, source_->name()) {
    info_.name = source_->name();
    info_.format = "aedat3.1";
    read_header();
  }

  EventBatchPtr next() override {
    if (finished_) return nullptr;
    builder_.start(false);
    while (!builder_.done() && !stopped_) {
      if (events_left_ > 0) {
        decode_events();
      } else {
        read_packet_header();
      }
    }
    stats_.bytes_read = in_.offset();
    auto batch = builder_.finish();
    if (!batch && !builder_.has_carry()) finished_ = true;
    return batch;
  }

  [[nodiscard]] std::optional<double> progress() const override {
    return detail::byte_progress(stats_.bytes_read, source_->size());
  }

 private:
  enum class Kind { polarity, special };

  [[noreturn]] void fail(std::uint64_t offset, const std::string& what) {
    finished_ = true;
    throw FormatError(source_->name(), offset, what);
  }

  void read_header() {
    const std::uint64_t start = in_.offset();
    std::optional<SensorGeometry> geometry;
    bool first = true;
    for (;;) {
      const std::uint64_t line_offset = in_.offset();
      std::string_view line;
      const auto status = in_.read_line(line, kMaxHeaderLine);
      if (status == detail::ChunkedInput::LineStatus::too_long)
        fail(line_offset, fmt::format("header line longer than {} bytes", kMaxHeaderLine));
      if (status == detail::ChunkedInput::LineStatus::end)
        fail(line_offset, "the header ends without '#!END-HEADER' (no event data)");
      if (first) {
        if (!line.starts_with(kMagic)) fail(line_offset, "not an AEDAT 3.1 file: the first line is not '#!AER-DAT3.1'");
        first = false;
        continue;
      }
      if (!line.starts_with('#')) fail(line_offset, "header line does not start with '#' before '#!END-HEADER'");
      if (line.starts_with(kEndHeader)) break;
      const auto body = trim(line.substr(1));
      if (body.starts_with("Format:")) {
        const auto format = trim(body.substr(7));
        if (format != "RAW")
          fail(line_offset,
               fmt::format("AEDAT 3.1 format '{}' is not supported (only RAW)", std::string(format.substr(0, 64))));
      } else if (body.starts_with("Source") && !geometry) {
        const auto colon = body.find(':');
        if (colon != std::string_view::npos) geometry = geometry_of_source(body.substr(colon + 1));
      }
    }
    stats_.bytes_read = in_.offset();
    if (geometry) {
      info_.geometry = *geometry;
      info_.geometry_known = true;
    } else {
      info_.geometry = options_.default_geometry;
      info_.geometry_known = false;
      builder_.warn(start, fmt::format("the header names no known sensor: assuming {}x{}", info_.geometry.width,
                                       info_.geometry.height));
      if (info_.geometry.width <= 0 || info_.geometry.height <= 0)
        fail(start, fmt::format("invalid sensor size {}x{}", info_.geometry.width, info_.geometry.height));
    }
  }

  void stop_truncated(std::uint64_t offset, std::uint64_t bytes, const std::string& what) {
    stats_.truncated_bytes += bytes;
    builder_.warn(offset, what);
    stopped_ = true;
  }

  void read_packet_header() {
    const std::uint64_t offset = in_.offset();
    if (!in_.ensure(kPacketHeaderBytes)) {
      const std::size_t rest = in_.available();
      if (rest > 0) {
        in_.consume(rest);
        stop_truncated(offset, rest,
                       fmt::format("truncated packet header: {} of {} bytes (ignored)", rest, kPacketHeaderBytes));
      }
      stopped_ = true;
      return;
    }
    const PacketHeader h = parse_packet_header(in_.data());
    in_.consume(kPacketHeaderBytes);
    if (h.event_size <= 0)
      fail(offset, fmt::format("packet of type {} has eventSize {} (must be > 0)", h.type, h.event_size));
    if (h.number < 0)
      fail(offset, fmt::format("packet of type {} has eventNumber {} (must be >= 0)", h.type, h.number));
    if (h.capacity != h.number)
      fail(offset,
           fmt::format("packet of type {} has eventCapacity {} != eventNumber {}", h.type, h.capacity, h.number));
    const bool decoded = h.type == kPolarityEvent || h.type == kSpecialEvent;
    if (decoded && (h.event_size != static_cast<std::int32_t>(kEventBytes) || h.ts_offset != 4))
      fail(offset, fmt::format("{} packet with eventSize {} and eventTSOffset {} (expected 8 and 4)",
                               h.type == kPolarityEvent ? "polarity" : "special", h.event_size, h.ts_offset));
    const std::uint64_t payload = static_cast<std::uint64_t>(h.number) * static_cast<std::uint64_t>(h.event_size);
    if (const auto size = source_->size(); size) {
      const std::uint64_t left = *size > in_.offset() ? *size - in_.offset() : 0;
      if (payload > left) {
        in_.skip(left);
        stop_truncated(offset, kPacketHeaderBytes + left,
                       fmt::format("truncated packet: {} events of {} bytes need {} bytes, {} left (packet "
                                   "ignored)",
                                   h.number, h.event_size, payload, left));
        return;
      }
    }
    if (!decoded) {
      const std::uint64_t skipped = in_.skip(payload);
      stats_.skipped_non_dvs += static_cast<std::uint64_t>(h.number);
      if (skipped < payload)
        stop_truncated(offset, kPacketHeaderBytes + skipped,
                       fmt::format("truncated packet: {} of {} payload bytes", skipped, payload));
      return;
    }
    kind_ = h.type == kPolarityEvent ? Kind::polarity : Kind::special;
    events_left_ = static_cast<std::uint32_t>(h.number);
    packet_offset_ = offset;
    packet_events_ = events_left_;
    ts_high_ = static_cast<std::int64_t>(h.ts_overflow) * (std::int64_t{1} << 31);
  }

  void decode_events() {
    if (!in_.ensure(kEventBytes)) {
      const std::size_t rest = in_.available();
      in_.consume(rest);
      stop_truncated(packet_offset_, rest,
                     fmt::format("truncated packet: {} of its {} events missing", events_left_, packet_events_));
      events_left_ = 0;
      return;
    }
    const int width = info_.geometry.width;
    const int height = info_.geometry.height;
    while (events_left_ > 0 && in_.available() >= kEventBytes && !builder_.done()) {
      const std::byte* p = in_.data();
      const std::uint64_t offset = in_.offset();
      const auto data = detail::load_le<std::uint32_t>(p);
      const auto ts = detail::load_le<std::int32_t>(p + 4);
      in_.consume(kEventBytes);
      --events_left_;
      if (kind_ == Kind::special) {
        ++stats_.skipped_non_dvs;
        if ((data & 1u) != 0 && ((data >> 1) & 0x7Fu) == kSpecialTimestampReset) builder_.reset_clock();
        continue;
      }
      if ((data & 1u) == 0) {
        ++stats_.invalid_events;
        continue;
      }
      if (ts < 0) {
        // libcaer timestamps are 31-bit: a negative one cannot be combined with the overflow counter.
        ++stats_.invalid_events;
        if (++bad_timestamps_ <= 10)
          builder_.warn(offset, fmt::format("negative event timestamp {} (event skipped)", ts));
        continue;
      }
      const int x = static_cast<int>((data >> 17) & 0x7FFFu);
      const int y = static_cast<int>((data >> 2) & 0x7FFFu);
      if (x >= width || y >= height)
        fail(offset, fmt::format("event at x={} y={} is outside the {}x{} sensor{}", x, y, width, height,
                                 info_.geometry_known ? "" : " (size assumed: the header names no known sensor)"));
      Event e;
      e.t_us = ts_high_ | static_cast<std::int64_t>(ts);
      e.x = static_cast<std::uint16_t>(x);
      e.y = static_cast<std::uint16_t>(y);
      e.polarity = ((data >> 1) & 1u) != 0;
      builder_.add(e, offset);
    }
  }

  std::unique_ptr<ByteSource> source_;
  ReaderOptions options_;
  detail::ChunkedInput in_;
  detail::BatchBuilder builder_;
  Kind kind_ = Kind::polarity;
  std::uint32_t events_left_ = 0;
  std::uint32_t packet_events_ = 0;
  std::uint64_t packet_offset_ = 0;
  std::int64_t ts_high_ = 0;
  std::uint64_t bad_timestamps_ = 0;
  bool stopped_ = false;
};

}  // namespace

std::unique_ptr<FileReader> make_aedat31_reader(std::unique_ptr<ByteSource> source, ReaderOptions options) {
  return std::make_unique<Aedat31Reader>(std::move(source), std::move(options));
}

}  // namespace evpipe::io
