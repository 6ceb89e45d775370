#pragma once
// Internal helpers shared by the readers and writers of libs/io.

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <memory>
#include <optional>
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

std::unique_ptr<EventWriter> make_text_writer(const std::string& path, const WriterOptions& options);
std::unique_ptr<EventWriter> make_aedat4_writer(const std::string& path, const WriterOptions& options);
std::unique_ptr<EventWriter> make_aedat31_writer(const std::string& path, const WriterOptions& options);

}  // namespace evpipe::io::detail
