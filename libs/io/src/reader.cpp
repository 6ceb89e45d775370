#include "evpipe/io/reader.hpp"

#include <fmt/format.h>
#include <array>
#include <cstring>
#include <string_view>

namespace evpipe::io {

std::string_view format_name(Format f) noexcept {
  switch (f) {
    case Format::aedat2:
      return "aedat2";
    case Format::aedat31:
      return "aedat3.1";
    case Format::aedat4:
      return "aedat4";
    case Format::text:
      return "text";
    case Format::unknown:
      break;
  }
  return "unknown";
}

namespace {

bool starts_with(std::span<const std::byte> head, std::string_view prefix) {
  return head.size() >= prefix.size() && std::memcmp(head.data(), prefix.data(), prefix.size()) == 0;
}

bool is_text_byte(std::byte b) {
  const auto c = static_cast<unsigned char>(b);
  return c == '\n' || c == '\r' || c == '\t' || (c >= 0x20 && c < 0x7f);
}

}  // namespace

Format detect_format(std::span<const std::byte> head, std::string* why) {
  auto say = [why](std::string s) {
    if (why) *why = std::move(s);
  };
  if (head.empty()) {
    say("the file is empty");
    return Format::unknown;
  }
  if (starts_with(head, "#!AER-DAT2.0")) return Format::aedat2;
  if (starts_with(head, "#!AER-DAT3.1")) return Format::aedat31;
  if (starts_with(head, "#!AER-DAT4.0")) return Format::aedat4;
  // A file starting like an AEDAT version line (even only "#!AER") is never read as text (a '#' comment line).
  if (starts_with(head, "#!AER")) {
    constexpr std::string_view kMagic = "#!AER-DAT";
    const std::string_view text(reinterpret_cast<const char*>(head.data()), head.size());
    if (head.size() < 12 && (kMagic.starts_with(text) || text.starts_with(kMagic))) {
      say(fmt::format("the AEDAT version line is cut after {} byte(s) (truncated file?)", head.size()));
      return Format::unknown;
    }
    if (!starts_with(head, kMagic)) {
      say("starts with '#!AER' but not with an '#!AER-DAT' version line");
      return Format::unknown;
    }
  }
  if (starts_with(head, "#!AER-DAT")) {
    std::string version;
    for (std::size_t i = 9; i < head.size() && i < 16 && is_text_byte(head[i]) && static_cast<char>(head[i]) != '\r' &&
                            static_cast<char>(head[i]) != '\n';
         ++i)
      version += static_cast<char>(head[i]);
    say(fmt::format("AEDAT version '{}' is not supported", version));
    return Format::unknown;
  }
  if (starts_with(head, "%")) {
    // Prophesee header: the format line ("% evt 2.0", "% format EVT3") need not be the first one.
    const std::string_view text(reinterpret_cast<const char*>(head.data()), head.size());
    if (text.find("\n% evt 2.0") != std::string_view::npos || text.starts_with("% evt 2.0"))
      say("Prophesee RAW EVT 2.0 is not an evpipe format");
    else if (text.find("\n% evt 3.0") != std::string_view::npos || text.starts_with("% evt 3.0") ||
             text.find("\n% format EVT3") != std::string_view::npos)
      say("Prophesee RAW EVT 3.0 is not an evpipe format");
    else if (text.starts_with("% Data file containing"))
      say("a Prophesee DAT file is not an evpipe format");
    else
      say("a Prophesee file ('%' header: DAT or RAW) is not an evpipe format");
    return Format::unknown;
  }
  // Text: printable bytes only (after a UTF-8 byte order mark), and the first line that is not a comment starts
  // like a number.
  if (starts_with(head, "\xEF\xBB\xBF")) head = head.subspan(3);
  std::size_t i = 0;
  bool all_text = true;
  for (const auto b : head) {
    if (!is_text_byte(b)) {
      all_text = false;
      break;
    }
  }
  if (!all_text) {
    say(static_cast<char>(head[0]) == '#'
            ? "'#' header lines without an '#!AER-DAT' version line (AEDAT 1.0?) followed by binary data"
            : "binary data of an unknown format (no '#!AER-DAT' version line)");
    return Format::unknown;
  }
  while (i < head.size()) {
    // skip blank lines and comments
    const auto c = static_cast<char>(head[i]);
    if (c == '#') {
      while (i < head.size() && static_cast<char>(head[i]) != '\n') ++i;
      ++i;
      continue;
    }
    if (c == ' ' || c == '\t' || c == '\r' || c == '\n') {
      ++i;
      continue;
    }
    if ((c >= '0' && c <= '9') || c == '-' || c == '+' || c == '.') return Format::text;
    say(fmt::format("text whose first data line starts with '{}' rather than a number", c));
    return Format::unknown;
  }
  // Only comments in the head: text (possibly an empty text file; the reader decides).
  return Format::text;
}

std::unique_ptr<FileReader> open_reader(std::unique_ptr<ByteSource> source, ReaderOptions options) {
  if (!within_sensor_limits(options.default_geometry))
    throw FormatError(
        source->name(), std::nullopt,
        fmt::format("default sensor size {}x{}: each side must be in 1..{} (docs/operations.md \"Limits\")",
                    options.default_geometry.width, options.default_geometry.height, kMaxSensorSide));
  std::array<std::byte, 4096> buf{};
  std::size_t n = 0;
  while (n < buf.size()) {
    const std::size_t got = source->read(std::span(buf).subspan(n));
    if (got == 0) break;
    n += got;
  }
  if (!source->seek(0)) throw FormatError(source->name(), std::nullopt, "cannot rewind the input");
  std::string why;
  switch (detect_format(std::span(buf.data(), n), &why)) {
    case Format::aedat2:
      return make_aedat2_reader(std::move(source), std::move(options));
    case Format::aedat31:
      return make_aedat31_reader(std::move(source), std::move(options));
    case Format::aedat4:
      return make_aedat4_reader(std::move(source), std::move(options));
    case Format::text:
      return make_text_reader(std::move(source), std::move(options));
    case Format::unknown:
      break;
  }
  throw FormatError(source->name(), 0,
                    fmt::format("unrecognised content: {} (evpipe reads AEDAT 2.0, 3.1, 4.0 and text 't x y p')", why));
}

std::unique_ptr<FileReader> open_reader(const std::string& path, ReaderOptions options) {
  return open_reader(open_file(path), std::move(options));
}

EventBatch read_all(const std::string& path, ReaderOptions options) {
  auto reader = open_reader(path, std::move(options));
  EventBatch all;
  while (auto b = reader->next()) {
    all.events.insert(all.events.end(), b->events.begin(), b->events.end());
    all.labels.insert(all.labels.end(), b->labels.begin(), b->labels.end());
  }
  return all;
}

}  // namespace evpipe::io
