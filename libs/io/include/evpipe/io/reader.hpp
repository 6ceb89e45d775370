#pragma once
// Event file readers, chosen by file content (never by extension). All stream in bounded memory.
//
//   auto reader = evpipe::io::open_reader("rec.aedat4");
//   while (auto batch = reader->next()) { ... }   // nullptr at end of file
//
// Fatal problems throw evpipe::FormatError ("<file>: byte <offset>: <what>"); every batch returned
// before the throw is valid. Recoverable ones (one corrupt packet in a long file, an out-of-order
// timestamp, a truncated last record) are reported through ReaderOptions::on_warning, counted in
// SourceStats, and reading goes on.

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "evpipe/core/error.hpp"
#include "evpipe/core/source.hpp"
#include "evpipe/io/byte_source.hpp"

namespace evpipe::io {

enum class Format { aedat2, aedat31, aedat4, text, unknown };

/// "aedat2", "aedat3.1", "aedat4", "text", "unknown".
std::string_view format_name(Format f) noexcept;

/// Identifies the format from the first bytes of a file. `head` is the start of the file (64 bytes are
/// enough). Returns Format::unknown for anything else; `why` then says what the bytes look like
/// (e.g. "Prophesee EVT 2.0 RAW", "AEDAT 1.0") for the error message.
Format detect_format(std::span<const std::byte> head, std::string* why = nullptr);

enum class OutOfOrderPolicy {
  drop,  ///< events with t_us < the previous event's are dropped and counted (pipeline default: windows
         ///< and filters need time order)
  keep,  ///< kept and counted (converters: output equals input)
};

struct ReaderOptions {
  /// Events per batch delivered by next() (formats with packets may deliver whole packets instead).
  std::size_t batch_events = 8192;
  OutOfOrderPolicy out_of_order = OutOfOrderPolicy::drop;
  /// A backward jump larger than this is a clock discontinuity (timestamp reset), not disorder: the next
  /// batch gets discontinuity_before = true and later events are compared against the new clock.
  std::int64_t discontinuity_us = 1'000'000;
  /// AEDAT 2.0 only: jAER's origin is bottom-left; flip y to evpipe's top-left (default) and optionally x.
  bool aedat2_flip_y = true;
  bool aedat2_flip_x = false;
  /// Used when the file states no sensor size (AEDAT 2.0 with an unknown chip class, text without a
  /// `# width= height=` line).
  SensorGeometry default_geometry = kDavis346;
  /// Receives every recoverable problem; default: ignored (still counted in stats).
  std::function<void(const Warning&)> on_warning;
};

/// An EventSource over a file.
class FileReader : public EventSource {
 public:
  [[nodiscard]] bool finished() const override { return finished_; }
  [[nodiscard]] const SourceInfo& info() const override { return info_; }
  [[nodiscard]] const SourceStats& stats() const override { return stats_; }

 protected:
  SourceInfo info_;
  SourceStats stats_;
  bool finished_ = false;
};

/// Opens a reader for `source`, choosing the format by content. Throws FormatError for unknown content,
/// a bad header, or an empty file (naming the file).
std::unique_ptr<FileReader> open_reader(std::unique_ptr<ByteSource> source, ReaderOptions options = {});
std::unique_ptr<FileReader> open_reader(const std::string& path, ReaderOptions options = {});

// Per-format factories (used by open_reader, tests and fuzzers).
std::unique_ptr<FileReader> make_aedat2_reader(std::unique_ptr<ByteSource> source, ReaderOptions options);
std::unique_ptr<FileReader> make_aedat31_reader(std::unique_ptr<ByteSource> source, ReaderOptions options);
std::unique_ptr<FileReader> make_aedat4_reader(std::unique_ptr<ByteSource> source, ReaderOptions options);
std::unique_ptr<FileReader> make_text_reader(std::unique_ptr<ByteSource> source, ReaderOptions options);

/// Reads a whole file into one batch (tests, small tools; not for the pipeline).
EventBatch read_all(const std::string& path, ReaderOptions options = {});

}  // namespace evpipe::io
