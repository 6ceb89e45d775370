#pragma once
// Bounded-memory buffered input over a ByteSource, shared by the AEDAT 2.0, AEDAT 3.1 and text readers,
// plus the batch assembly they share (time-order policy, discontinuity splits, counters).

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <optional>
#include <string_view>
#include <utility>
#include <vector>

#include "detail.hpp"
#include "evpipe/io/byte_source.hpp"

namespace evpipe::io::detail {

/// A window of the input: reads the ByteSource in chunks, tracks absolute byte offsets, and grows its
/// buffer only as far as a caller asks (callers bound what they ask for).
class ChunkedInput {
 public:
  static constexpr std::size_t kDefaultChunk = std::size_t{1} << 16;

  explicit ChunkedInput(ByteSource& source, std::size_t chunk = kDefaultChunk)
      : source_(source), chunk_(std::max<std::size_t>(chunk, 64)), base_(source.tell()) {}

  /// Absolute offset of the next unread byte.
  [[nodiscard]] std::uint64_t offset() const noexcept { return base_ + pos_; }
  [[nodiscard]] std::size_t available() const noexcept { return end_ - pos_; }
  [[nodiscard]] const std::byte* data() const noexcept { return buf_.data() + pos_; }
  void consume(std::size_t n) noexcept { pos_ += std::min(n, available()); }

  /// Makes at least `n` bytes available; false when the input ends first (then all that is left is
  /// available). `n` must be bounded by the caller: the buffer grows to hold it.
  bool ensure(std::size_t n) {
    if (available() >= n) return true;
    if (eof_) return false;
    // Compact: move the unread tail to the front.
    if (pos_ > 0) {
      const std::size_t left = available();
      if (left > 0) std::memmove(buf_.data(), buf_.data() + pos_, left);
      base_ += pos_;
      pos_ = 0;
      end_ = left;
    }
    if (buf_.size() < std::max(n, chunk_)) buf_.resize(std::max({n, chunk_, buf_.size() * 2}));
    while (end_ < n) {
      const std::size_t got = source_.read(std::span(buf_.data() + end_, buf_.size() - end_));
      if (got == 0) {
        eof_ = true;
        return false;
      }
      end_ += got;
    }
    return true;
  }

  /// True when no byte is left.
  bool at_end() { return !ensure(1); }

  /// Skips `n` bytes, seeking when the source can; returns the number of bytes actually skipped (less
  /// than `n` only at the end of the input).
  std::uint64_t skip(std::uint64_t n) {
    if (n <= available()) {
      pos_ += static_cast<std::size_t>(n);
      return n;
    }
    const std::uint64_t start = offset();
    const std::uint64_t target = start + n;
    const auto size = source_.size();
    if (!eof_ && size && target <= *size && source_.seek(target)) {
      base_ = target;
      pos_ = end_ = 0;
      return n;
    }
    std::uint64_t done = 0;
    while (done < n) {
      if (available() == 0 && !ensure(1)) break;
      const auto step = static_cast<std::size_t>(std::min<std::uint64_t>(available(), n - done));
      pos_ += step;
      done += step;
    }
    return done;
  }

  enum class LineStatus { ok, end, too_long };

  /// Reads one line, without its '\n' and a '\r' before it. The view is valid until the next call on
  /// this object. A last line without '\n' is returned as a line. `too_long`: no '\n' within
  /// `max_len` bytes (nothing consumed).
  LineStatus read_line(std::string_view& line, std::size_t max_len) {
    std::size_t scanned = 0;
    for (;;) {
      const std::size_t n = available();
      const auto* start = reinterpret_cast<const char*>(data());
      const void* nl = n > scanned ? std::memchr(start + scanned, '\n', n - scanned) : nullptr;
      if (nl != nullptr) {
        std::size_t len = static_cast<std::size_t>(static_cast<const char*>(nl) - start);
        consume(len + 1);
        if (len > 0 && start[len - 1] == '\r') --len;
        if (len > max_len) return LineStatus::too_long;
        line = std::string_view(start, len);
        return LineStatus::ok;
      }
      scanned = n;
      if (n > max_len + 1) return LineStatus::too_long;  // cannot end within max_len (+ '\r')
      if (!ensure(n + 1)) {
        const std::size_t rest = available();
        if (rest == 0) return LineStatus::end;
        const auto* s = reinterpret_cast<const char*>(data());
        consume(rest);
        std::size_t len = rest;
        if (s[len - 1] == '\r') --len;
        if (len > max_len) return LineStatus::too_long;
        line = std::string_view(s, len);
        return LineStatus::ok;
      }
    }
  }

 private:
  ByteSource& source_;
  std::size_t chunk_;
  std::vector<std::byte> buf_;
  std::size_t pos_ = 0;
  std::size_t end_ = 0;
  std::uint64_t base_ = 0;  // absolute offset of buf_[0]
  bool eof_ = false;
};

/// Builds one batch from decoded events, applying the time-order policy: a dropped event is skipped; an
/// event after a clock discontinuity closes the batch (unless it is empty) and opens the next one with
/// discontinuity_before = true, so that the flag applies from that event on.
class BatchBuilder {
 public:
  BatchBuilder(const ReaderOptions& options, SourceStats& stats, const std::string& file)
      : options_(options),
        stats_(stats),
        file_(file),
        clock_(std::in_place, options, stats, file),
        capacity_(std::max<std::size_t>(options.batch_events, 1)) {}

  /// Starts a new batch (carrying over an event held back by a discontinuity).
  void start(bool labelled) {
    batch_ = std::make_shared<EventBatch>();
    batch_->events.reserve(std::min<std::size_t>(capacity_, 1 << 16));
    if (labelled) batch_->labels.reserve(std::min<std::size_t>(capacity_, 1 << 16));
    batch_->discontinuity_before = std::exchange(pending_discontinuity_, false);
    if (carry_) {
      batch_->events.push_back(carry_->first);
      if (labelled) batch_->labels.push_back(carry_->second);
      carry_.reset();
    }
  }

  /// True when the current batch must be returned (full, or closed by a discontinuity).
  [[nodiscard]] bool done() const noexcept { return closed_ || batch_->events.size() >= capacity_; }

  /// Adds one event decoded at byte `offset` (label ignored unless the batch is labelled).
  void add(const Event& e, std::uint64_t offset, Label label = Label::signal, bool labelled = false) {
    switch (clock_->check(e.t_us, offset)) {
      case TimeOrder::Verdict::drop:
        return;
      case TimeOrder::Verdict::keep_after_discontinuity:
        if (!batch_->events.empty()) {
          carry_.emplace(e, label);
          pending_discontinuity_ = true;
          closed_ = true;
          return;
        }
        batch_->discontinuity_before = true;
        break;
      case TimeOrder::Verdict::keep:
        break;
    }
    batch_->events.push_back(e);
    if (labelled) batch_->labels.push_back(label);
  }

  /// A clock reset announced by the file itself (AEDAT 3.1 TIMESTAMP_RESET): counted once, the next
  /// event starts a new batch flagged discontinuity_before, and time order restarts.
  void reset_clock() {
    ++stats_.discontinuities;
    clock_.emplace(options_, stats_, file_);
    if (!batch_->events.empty()) {
      pending_discontinuity_ = true;
      closed_ = true;
    } else {
      batch_->discontinuity_before = true;
    }
  }

  /// Hands out the current batch (nullptr when it holds no event) and updates the counters.
  EventBatchPtr finish() {
    closed_ = false;
    auto b = std::move(batch_);
    if (!b || b->events.empty()) {
      // A flag on an empty batch must survive to the next batch that holds events.
      if (b && b->discontinuity_before) pending_discontinuity_ = true;
      return nullptr;
    }
    stats_.events += b->events.size();
    ++stats_.batches;
    b->read_at = std::chrono::steady_clock::now();
    return b;
  }

  /// True when an event is held back for the next batch.
  [[nodiscard]] bool has_carry() const noexcept { return carry_.has_value(); }

  void warn(std::optional<std::uint64_t> offset, std::string what) const { clock_->warn(offset, std::move(what)); }

 private:
  const ReaderOptions& options_;
  SourceStats& stats_;
  const std::string& file_;
  std::optional<TimeOrder> clock_;
  std::size_t capacity_;
  std::shared_ptr<EventBatch> batch_;
  std::optional<std::pair<Event, Label>> carry_;
  bool pending_discontinuity_ = false;
  bool closed_ = false;
};

}  // namespace evpipe::io::detail
