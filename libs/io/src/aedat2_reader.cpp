// AEDAT 2.0 (jAER) reader: '#' header lines, then big-endian {uint32 address, int32 timestamp} records
// with the DAVIS address layout (formats.md §3).

#include <fmt/format.h>
#include <algorithm>
#include <cctype>
#include <string>
#include <string_view>

#include "chunked_input.hpp"
#include "detail.hpp"

namespace evpipe::io {

namespace {

constexpr std::size_t kMaxHeaderLine = std::size_t{1} << 20;  // real headers have lines < 1 kB
constexpr std::size_t kRecordBytes = 8;
constexpr std::string_view kMagic = "#!AER-DAT2.0";

constexpr std::uint32_t kNotDvsMask = 0x80000000u;  // APS / IMU words
constexpr std::uint32_t kSpecialMask = 0x400u;      // external input / special events

std::string lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r')) s.remove_suffix(1);
  return s;
}

/// Sensor size from the jAER chip class ("eu.seebetter.ini.chips.davis.DAVIS240C"); nullopt if unknown.
std::optional<SensorGeometry> geometry_of_chip(std::string_view chip_class) {
  const auto dot = chip_class.rfind('.');
  const std::string name = lower(dot == std::string_view::npos ? chip_class : chip_class.substr(dot + 1));
  if (name.starts_with("davis240")) return kDavis240;
  if (name.starts_with("davis346")) return kDavis346;
  return std::nullopt;
}

/// A '#' line that holds control bytes is not a header line but the first record of the body (an
/// address whose top byte happens to be '#'): jAER's rule "lines while the first byte is '#'" would
/// swallow it and misalign every record after it. Real header lines are printable text.
bool looks_like_text(std::string_view line) {
  return std::none_of(line.begin(), line.end(), [](char ch) {
    const auto c = static_cast<unsigned char>(ch);
    return (c < 0x20 && c != '\t' && c != '\r') || c == 0x7f;
  });
}

class Aedat2Reader final : public FileReader {
 public:
  Aedat2Reader(std::unique_ptr<ByteSource> source, ReaderOptions options)
      : source_(std::move(source)),
        options_(std::move(options)),
        in_(*source_),
        builder_(options_, stats_, source_->name()) {
    info_.name = source_->name();
    info_.format = "aedat2";
    read_header();
  }

  EventBatchPtr next() override {
    if (finished_) return nullptr;
    builder_.start(false);
    while (!builder_.done()) {
      if (!in_.ensure(kRecordBytes)) {
        end_of_body();
        break;
      }
      decode_available();
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
  [[noreturn]] void fail(std::uint64_t offset, const std::string& what) {
    finished_ = true;
    throw FormatError(source_->name(), offset, what);
  }

  void read_header() {
    const std::uint64_t start = in_.offset();
    std::optional<std::string> chip;
    bool first = true;
    while (in_.ensure(1) && static_cast<char>(*in_.data()) == '#') {
      const std::uint64_t line_offset = in_.offset();
      std::string_view line;
      // Peek first: a '#' "line" with binary bytes is the first record (see looks_like_text).
      if (!first) {
        in_.ensure(kRecordBytes);
        const auto n = std::min(in_.available(), kRecordBytes);
        std::string_view head(reinterpret_cast<const char*>(in_.data()), n);
        const auto nl = head.find('\n');
        if (!looks_like_text(head.substr(0, nl))) break;
      }
      const auto status = in_.read_line(line, kMaxHeaderLine);
      if (status == detail::ChunkedInput::LineStatus::too_long)
        fail(line_offset, fmt::format("header line longer than {} bytes (not an AEDAT 2.0 header)", kMaxHeaderLine));
      if (status == detail::ChunkedInput::LineStatus::end) break;
      if (first) {
        if (!line.starts_with(kMagic)) fail(line_offset, "not an AEDAT 2.0 file: the first line is not '#!AER-DAT2.0'");
        first = false;
        continue;
      }
      const auto body = trim(line.substr(1));
      if (body.starts_with("AEChip:")) chip = std::string(trim(body.substr(7)));
    }
    if (first) fail(start, "not an AEDAT 2.0 file: the first line is not '#!AER-DAT2.0'");
    stats_.bytes_read = in_.offset();

    std::optional<SensorGeometry> geometry;
    if (chip) geometry = geometry_of_chip(*chip);
    if (geometry) {
      info_.geometry = *geometry;
      info_.geometry_known = true;
    } else {
      info_.geometry = options_.default_geometry;
      info_.geometry_known = false;
      builder_.warn(std::nullopt, fmt::format("{}: assuming a {}x{} sensor with the DAVIS address layout",
                                              chip ? fmt::format("unknown jAER chip class '{}'", *chip)
                                                   : std::string("no '# AEChip:' header line"),
                                              info_.geometry.width, info_.geometry.height));
    }
    if (info_.geometry.width <= 0 || info_.geometry.height <= 0)
      fail(start, fmt::format("invalid sensor size {}x{}", info_.geometry.width, info_.geometry.height));
  }

  void end_of_body() {
    const std::size_t rest = in_.available();
    if (rest > 0) {
      const std::uint64_t at = in_.offset();
      stats_.truncated_bytes += rest;
      builder_.warn(at, fmt::format("truncated last record: {} of {} bytes (ignored)", rest, kRecordBytes));
      in_.consume(rest);
    }
  }

  /// Decodes the complete records in the buffer until the batch is done.
  void decode_available() {
    const int width = info_.geometry.width;
    const int height = info_.geometry.height;
    while (in_.available() >= kRecordBytes && !builder_.done()) {
      const std::byte* p = in_.data();
      const std::uint64_t offset = in_.offset();
      const std::uint32_t addr = detail::load_be32(p);
      const auto raw_ts = static_cast<std::int32_t>(detail::load_be32(p + 4));
      in_.consume(kRecordBytes);
      if ((addr & kNotDvsMask) != 0 || (addr & kSpecialMask) != 0) {
        // APS, IMU and special words are skipped one by one: an IMU sample is 7 words, but the last one
        // of a cut recording may be incomplete.
        ++stats_.skipped_non_dvs;
        continue;
      }
      const int x_raw = static_cast<int>((addr >> 12) & 0x3FFu);
      const int y_raw = static_cast<int>((addr >> 22) & 0x1FFu);
      if (x_raw >= width || y_raw >= height)
        fail(offset, fmt::format("event at x={} y={} is outside the {}x{} sensor{}", x_raw, y_raw, width, height,
                                 info_.geometry_known ? "" : " (size assumed: the header names no known chip)"));
      // 32-bit wrap: the previous raw value high, the new one low (a drop of more than 2^31).
      if (last_raw_ts_ && static_cast<std::int64_t>(*last_raw_ts_) - raw_ts > (std::int64_t{1} << 31))
        wrap_offset_ += std::int64_t{1} << 32;
      last_raw_ts_ = raw_ts;
      Event e;
      e.t_us = wrap_offset_ + raw_ts;
      e.x = static_cast<std::uint16_t>(options_.aedat2_flip_x ? width - 1 - x_raw : x_raw);
      e.y = static_cast<std::uint16_t>(options_.aedat2_flip_y ? height - 1 - y_raw : y_raw);
      e.polarity = ((addr >> 11) & 1u) != 0;
      builder_.add(e, offset);
    }
  }

  std::unique_ptr<ByteSource> source_;
  ReaderOptions options_;
  detail::ChunkedInput in_;
  detail::BatchBuilder builder_;
  std::optional<std::int32_t> last_raw_ts_;
  std::int64_t wrap_offset_ = 0;
};

}  // namespace

std::unique_ptr<FileReader> make_aedat2_reader(std::unique_ptr<ByteSource> source, ReaderOptions options) {
  return std::make_unique<Aedat2Reader>(std::move(source), std::move(options));
}

}  // namespace evpipe::io
