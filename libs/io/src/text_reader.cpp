// Text reader: one event per line `t x y p [label]` (interfaces.md "Event files evpipe reads", formats.md
// §6). Separators: runs of spaces, tabs and commas. Lines starting with '#' are comments; `# width=W
// height=H` before the first event sets the sensor size. A first non-comment line of exactly two integers
// is `H W` (height first: the taro-dvstoolkit convention of davis240-text-taro).
//
// Time column: integer microseconds, or seconds when the first event's time holds a decimal point; the
// choice holds for the whole file (an integer time in a seconds file is whole seconds; a decimal point in
// a microseconds file is an error, since the two cannot be told apart line by line). Seconds are parsed as
// integer and fraction parts, never through a double, so Unix times keep microsecond precision. More than
// 6 fraction digits are ROUNDED to the nearest microsecond (ties away from zero): files printed with
// "%.9f" are common and their extra digits carry no information at µs resolution.

#include <fmt/format.h>
#include <algorithm>
#include <array>
#include <charconv>
#include <string>
#include <string_view>

#include "chunked_input.hpp"
#include "detail.hpp"

namespace evpipe::io {

namespace {

constexpr std::size_t kMaxLine = 4096;
constexpr std::size_t kMaxColumns = 5;

bool is_separator(char c) {
  return c == ' ' || c == '\t' || c == ',';
}

/// Printable excerpt of a token for messages.
std::string show(std::string_view token) {
  std::string out;
  for (char c : token.substr(0, 32)) {
    const auto u = static_cast<unsigned char>(c);
    out += (u >= 0x20 && u < 0x7f) ? std::string(1, c) : fmt::format("\\x{:02x}", u);
  }
  if (token.size() > 32) out += "...";
  return out;
}

/// Parses all of `s` as a base-10 integer (optional '-' or '+'); false on anything else or overflow.
bool parse_int(std::string_view s, std::int64_t& v) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  if (s.empty() || s.front() == '+') return false;
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  return ec == std::errc{} && p == s.data() + s.size();
}

bool all_digits(std::string_view s) {
  return std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; });
}

/// Seconds with an optional decimal point to exact microseconds (see the file comment for rounding).
bool parse_seconds(std::string_view s, std::int64_t& t_us) {
  bool negative = false;
  if (!s.empty() && (s.front() == '-' || s.front() == '+')) {
    negative = s.front() == '-';
    s.remove_prefix(1);
  }
  const auto dot = s.find('.');
  const std::string_view int_part = s.substr(0, dot);
  const std::string_view frac_part = dot == std::string_view::npos ? std::string_view{} : s.substr(dot + 1);
  if (int_part.empty() && frac_part.empty()) return false;
  if (!all_digits(int_part) || !all_digits(frac_part)) return false;
  std::int64_t whole = 0;
  if (!int_part.empty()) {
    const auto [p, ec] = std::from_chars(int_part.data(), int_part.data() + int_part.size(), whole);
    if (ec != std::errc{} || p != int_part.data() + int_part.size()) return false;
  }
  constexpr std::int64_t kMaxSeconds = (INT64_MAX - 1'000'000) / 1'000'000;
  if (whole > kMaxSeconds) return false;
  std::int64_t frac_us = 0;
  for (std::size_t i = 0; i < 6; ++i) frac_us = frac_us * 10 + (i < frac_part.size() ? frac_part[i] - '0' : 0);
  if (frac_part.size() > 6 && frac_part[6] >= '5') ++frac_us;  // round half away from zero
  const std::int64_t magnitude = whole * 1'000'000 + frac_us;
  t_us = negative ? -magnitude : magnitude;
  return true;
}

struct Parsed {
  Event event;
  Label label = Label::signal;
  std::size_t columns = 0;
  std::uint64_t offset = 0;
};

class TextReader final : public FileReader {
 public:
  TextReader(std::unique_ptr<ByteSource> source, ReaderOptions options)
      : source_(std::move(source)),
        options_(std::move(options)),
        in_(*source_),
        builder_(options_, stats_, source_->name()) {
    info_.name = source_->name();
    info_.format = "text";
    info_.geometry = options_.default_geometry;
    info_.geometry_known = false;
    read_preamble();
  }

  EventBatchPtr next() override {
    if (finished_) return nullptr;
    builder_.start(info_.labelled);
    if (first_) {
      builder_.add(first_->event, first_->offset, first_->label, info_.labelled);
      first_.reset();
    }
    while (!builder_.done() && !at_end_) {
      Parsed p;
      if (!next_data_line(p)) break;
      builder_.add(p.event, p.offset, p.label, info_.labelled);
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
    throw FormatError(source_->name(), offset, fmt::format("line {}: {}", line_no_, what));
  }

  /// Splits a line into at most kMaxColumns + 1 tokens (one more than allowed, to detect excess).
  std::size_t split(std::string_view line, std::array<std::string_view, kMaxColumns + 1>& tokens) {
    std::size_t n = 0;
    std::size_t i = 0;
    while (i < line.size() && n < tokens.size()) {
      while (i < line.size() && is_separator(line[i])) ++i;
      if (i == line.size()) break;
      const std::size_t start = i;
      while (i < line.size() && !is_separator(line[i])) ++i;
      tokens[n++] = line.substr(start, i - start);
    }
    return n;
  }

  /// Reads the next line; false at the end of the input.
  bool read_line(std::string_view& line, std::uint64_t& offset) {
    offset = in_.offset();
    const auto status = in_.read_line(line, kMaxLine);
    if (status == detail::ChunkedInput::LineStatus::end) {
      at_end_ = true;
      return false;
    }
    ++line_no_;
    if (line_no_ == 1 && line.starts_with("\xEF\xBB\xBF")) line.remove_prefix(3);  // a UTF-8 byte order mark
    if (status == detail::ChunkedInput::LineStatus::too_long)
      fail(offset, fmt::format("line longer than {} bytes (not an event text file?)", kMaxLine));
    return true;
  }

  static bool is_comment_or_blank(std::string_view line) {
    const auto first = line.find_first_not_of(" \t,");
    return first == std::string_view::npos || line[first] == '#';
  }

  /// `# width=W height=H`: returns the geometry when the comment sets both.
  std::optional<SensorGeometry> geometry_comment(std::string_view line, std::uint64_t offset) {
    std::optional<std::int64_t> w;
    std::optional<std::int64_t> h;
    std::size_t i = line.find('#') + 1;
    while (i < line.size()) {
      while (i < line.size() && (is_separator(line[i]) || line[i] == '#')) ++i;
      const std::size_t start = i;
      while (i < line.size() && !is_separator(line[i])) ++i;
      const auto token = line.substr(start, i - start);
      for (auto [key, slot] : {std::pair{std::string_view("width="), &w}, std::pair{std::string_view("height="), &h}}) {
        if (!token.starts_with(key)) continue;
        std::int64_t v = 0;
        if (!parse_int(token.substr(key.size()), v) || v <= 0 || v > kMaxSensorSide)
          fail(offset, fmt::format("bad sensor size '{}' (expected {}N with 0 < N <= {}, the largest sensor evpipe "
                                   "accepts)",
                                   show(token), key, kMaxSensorSide));
        *slot = v;
      }
    }
    if (w && h) return SensorGeometry{static_cast<int>(*w), static_cast<int>(*h)};
    if (w || h) builder_.warn(offset, fmt::format("line {}: '# width= height=' needs both values (ignored)", line_no_));
    return std::nullopt;
  }

  void read_preamble() {
    std::string_view line;
    std::uint64_t offset = 0;
    bool first_non_comment = true;
    while (read_line(line, offset)) {
      if (is_comment_or_blank(line)) {
        if (line.find("width=") != std::string_view::npos || line.find("height=") != std::string_view::npos) {
          if (const auto g = geometry_comment(line, offset)) {
            info_.geometry = *g;
            info_.geometry_known = true;
          }
        }
        continue;
      }
      std::array<std::string_view, kMaxColumns + 1> tokens;
      const std::size_t n = split(line, tokens);
      if (first_non_comment && n == 2) {
        first_non_comment = false;
        std::int64_t h = 0;
        std::int64_t w = 0;
        if (!parse_int(tokens[0], h) || !parse_int(tokens[1], w) || h <= 0 || w <= 0 || h > kMaxSensorSide ||
            w > kMaxSensorSide)
          fail(offset, fmt::format("a first line of two numbers must be the sensor size 'H W' (height width, each "
                                   "in 1..{}), got '{}'",
                                   kMaxSensorSide, show(line)));
        const SensorGeometry g{static_cast<int>(w), static_cast<int>(h)};
        if (info_.geometry_known && g != info_.geometry)
          fail(offset, fmt::format("sensor size line 'H W' = {}x{} (width x height) contradicts the '# width= "
                                   "height=' comment ({}x{})",
                                   g.width, g.height, info_.geometry.width, info_.geometry.height));
        info_.geometry = g;
        info_.geometry_known = true;
        continue;
      }
      seconds_ = tokens[0].find('.') != std::string_view::npos;
      columns_ = n;
      info_.labelled = n == kMaxColumns;
      Parsed p;
      parse_event(tokens, n, offset, p);
      first_ = p;
      return;
    }
  }

  /// The next event line (comments skipped); false at the end of the input.
  bool next_data_line(Parsed& p) {
    std::string_view line;
    std::uint64_t offset = 0;
    while (read_line(line, offset)) {
      if (is_comment_or_blank(line)) {
        if (line.find("width=") != std::string_view::npos && line.find("height=") != std::string_view::npos &&
            ++late_geometry_warnings_ == 1)
          builder_.warn(offset,
                        fmt::format("line {}: a sensor size comment after the first event is ignored", line_no_));
        continue;
      }
      std::array<std::string_view, kMaxColumns + 1> tokens;
      const std::size_t n = split(line, tokens);
      parse_event(tokens, n, offset, p);
      return true;
    }
    return false;
  }

  void parse_event(const std::array<std::string_view, kMaxColumns + 1>& tokens, std::size_t n, std::uint64_t offset,
                   Parsed& p) {
    if (n < 4 || n > kMaxColumns)
      fail(offset, fmt::format("expected 4 or 5 columns 't x y p [label]', found {}{}",
                               n > kMaxColumns ? "more than " : "", std::min(n, kMaxColumns)));
    if (columns_ != 0 && n != columns_)
      fail(offset, fmt::format("{} columns, but the first event line has {} (labels must be given for every "
                               "event or for none)",
                               n, columns_));
    std::int64_t t = 0;
    if (seconds_) {
      if (!parse_seconds(tokens[0], t)) fail(offset, fmt::format("bad time '{}' (expected seconds)", show(tokens[0])));
    } else if (tokens[0].find('.') != std::string_view::npos) {
      fail(offset, fmt::format("time '{}' has a decimal point, but the first event's time has none: times in "
                               "this file are integer microseconds",
                               show(tokens[0])));
    } else if (!parse_int(tokens[0], t)) {
      fail(offset, fmt::format("bad time '{}' (expected integer microseconds)", show(tokens[0])));
    }
    if (!within_timestamp_limits(t)) {
      fail(offset, fmt::format("time {} us is outside the supported range of +-2^61 us", t));
    }
    std::int64_t x = 0;
    std::int64_t y = 0;
    if (!parse_int(tokens[1], x)) fail(offset, fmt::format("bad x '{}' (expected an integer)", show(tokens[1])));
    if (!parse_int(tokens[2], y)) fail(offset, fmt::format("bad y '{}' (expected an integer)", show(tokens[2])));
    if (!info_.geometry.contains(static_cast<int>(std::clamp<std::int64_t>(x, -1, 1 << 20)),
                                 static_cast<int>(std::clamp<std::int64_t>(y, -1, 1 << 20))))
      fail(offset, fmt::format("event at x={} y={} is outside the {}x{} sensor{}", x, y, info_.geometry.width,
                               info_.geometry.height,
                               info_.geometry_known ? "" : " (default size: add a '# width=W height=H' line)"));
    const std::string_view pol = tokens[3];
    bool on = false;
    if (pol == "1" || pol == "+1") {
      on = true;
    } else if (pol != "0" && pol != "-1") {
      fail(offset, fmt::format("bad polarity '{}' (expected 0/1 or -1/1)", show(pol)));
    }
    p.label = Label::signal;
    if (n == kMaxColumns) {
      if (tokens[4] == "1") {
        p.label = Label::signal;
      } else if (tokens[4] == "0") {
        p.label = Label::noise;
      } else {
        fail(offset, fmt::format("bad label '{}' (expected 1 = signal or 0 = noise)", show(tokens[4])));
      }
    }
    p.event.t_us = t;
    p.event.x = static_cast<std::uint16_t>(x);
    p.event.y = static_cast<std::uint16_t>(y);
    p.event.polarity = on;
    p.columns = n;
    p.offset = offset;
  }

  std::unique_ptr<ByteSource> source_;
  ReaderOptions options_;
  detail::ChunkedInput in_;
  detail::BatchBuilder builder_;
  std::optional<Parsed> first_;
  std::uint64_t line_no_ = 0;
  std::size_t columns_ = 0;
  std::uint64_t late_geometry_warnings_ = 0;
  bool seconds_ = false;
  bool at_end_ = false;
};

}  // namespace

std::unique_ptr<FileReader> make_text_reader(std::unique_ptr<ByteSource> source, ReaderOptions options) {
  return std::make_unique<TextReader>(std::move(source), std::move(options));
}

}  // namespace evpipe::io
