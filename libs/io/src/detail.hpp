#pragma once
// Internal helpers shared by the readers and writers of libs/io.

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include "evpipe/io/reader.hpp"
#include "evpipe/io/writer.hpp"

namespace evpipe::io::detail {

/// Applies ReaderOptions' time-order policy to each decoded event, in file order.
/// Usage per event: `switch (clock.check(t_us, offset)) { case Verdict::drop: continue; ... }`.
class TimeOrder {
 public:
  enum class Verdict { keep, drop, keep_after_discontinuity };

  TimeOrder(const ReaderOptions& options, SourceStats& stats, const std::string& file)
      : options_(options), stats_(stats), file_(file) {}

  Verdict check(std::int64_t t_us, std::uint64_t offset) {
    if (!within_timestamp_limits(t_us)) {
      throw FormatError(
          file_, offset,
          "timestamp " + std::to_string(t_us) + " us is outside the supported range of +-2^61 us (a corrupt record)");
    }
    if (!last_ || t_us >= *last_) {
      last_ = t_us;
      return Verdict::keep;
    }
    // unsigned: the jump between two arbitrary int64 timestamps (corrupt input) can exceed INT64_MAX
    const std::uint64_t back_us = static_cast<std::uint64_t>(*last_) - static_cast<std::uint64_t>(t_us);
    if (options_.discontinuity_us < 0 || back_us > static_cast<std::uint64_t>(options_.discontinuity_us)) {
      ++stats_.discontinuities;
      warn(offset,
           "timestamp jumps back by " + std::to_string(back_us) + " us: treated as a clock reset (discontinuity)");
      last_ = t_us;
      return Verdict::keep_after_discontinuity;
    }
    ++stats_.out_of_order;
    if (stats_.out_of_order <= 10)
      warn(offset, "timestamp " + std::to_string(t_us) + " us is before the previous event's " +
                       std::to_string(*last_) + " us" +
                       (options_.out_of_order == OutOfOrderPolicy::drop ? " (event dropped)" : ""));
    if (options_.out_of_order == OutOfOrderPolicy::drop) return Verdict::drop;
    return Verdict::keep;
  }

  void warn(std::optional<std::uint64_t> offset, std::string what) const {
    if (options_.on_warning) options_.on_warning(Warning{file_, offset, std::move(what)});
  }

 private:
  const ReaderOptions& options_;
  SourceStats& stats_;
  const std::string& file_;
  std::optional<std::int64_t> last_;
};

/// Share of the input consumed, for FileReader::progress(): nullopt when the size is unknown or zero.
inline std::optional<double> byte_progress(std::uint64_t bytes_read, std::optional<std::uint64_t> size) {
  if (!size || *size == 0) return std::nullopt;
  return std::min(1.0, static_cast<double>(bytes_read) / static_cast<double>(*size));
}

/// Little/big-endian loads from unaligned bytes.
template <typename T>
inline T load_le(const std::byte* p) noexcept {
  T v;
  std::memcpy(&v, p, sizeof(T));
  return v;  // x86-64 and every target evpipe supports are little-endian
}
inline std::uint32_t load_be32(const std::byte* p) noexcept {
  return (static_cast<std::uint32_t>(p[0]) << 24) | (static_cast<std::uint32_t>(p[1]) << 16) |
         (static_cast<std::uint32_t>(p[2]) << 8) | static_cast<std::uint32_t>(p[3]);
}

/// A file being written by one of the writers. Created ("wb") or SourceError naming the path. Any failure
/// throws SourceError naming the path and byte offset and closes the file (later writes report "write after
/// close"); the destructor closes without throwing.
class OutputFile {
 public:
  /// `inputs`: files it must not be (evpipe/core/file.hpp: refused before anything is truncated).
  explicit OutputFile(std::string path, std::span<const std::string> inputs = {});
  ~OutputFile();
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;

  void write(const void* data, std::size_t n);
  void write(std::span<const std::byte> bytes) { write(bytes.data(), bytes.size()); }
  /// Moves to an absolute offset (AEDAT 4.0 patches its header at close).
  void seek(std::uint64_t offset);
  /// Closes, reporting any buffered write or close error; a no-op when already closed.
  void close();
  [[nodiscard]] bool is_open() const noexcept { return file_ != nullptr; }
  /// Current position: bytes written so far unless seek() moved it.
  [[nodiscard]] std::uint64_t tell() const noexcept { return pos_; }
  [[nodiscard]] const std::string& path() const noexcept { return path_; }

 private:
  [[noreturn]] void fail(const char* what, int err);

  std::string path_;
  std::FILE* file_ = nullptr;
  std::uint64_t pos_ = 0;
};

/// Throws std::invalid_argument naming the file when `e` lies outside `geometry` (writers never write an
/// event their own readers would reject).
void check_in_sensor(const std::string& path, const SensorGeometry& geometry, const Event& e);

std::unique_ptr<EventWriter> make_text_writer(const std::string& path, const WriterOptions& options);
std::unique_ptr<EventWriter> make_aedat4_writer(const std::string& path, const WriterOptions& options);
std::unique_ptr<EventWriter> make_aedat31_writer(const std::string& path, const WriterOptions& options);

}  // namespace evpipe::io::detail
