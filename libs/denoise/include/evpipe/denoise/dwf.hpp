#pragma once
// DWF, the double window filter (Guo & Delbruck, IEEE TPAMI 2023): no time surface, only two FIFOs of recent
// event positions: one of events judged signal, one of events judged noise. An event is kept when at least
// `threshold` events of the two windows lie within L1 distance `l1_radius` of it (inclusive); it then enters
// the signal FIFO if kept, the noise FIFO if not, pushing out that FIFO's oldest entry.
//
// variant cuke (default) = CUKE (cuke-emlb double_window_filter.hpp), the version E-MLB evaluates: 36 events
// per window, L1 <= 9, threshold 1. CUKE's circular buffers start FULL of default events at (0, 0), so until
// they are flushed, events within L1 9 of the top-left corner are supported by them; this pre-fill is reproduced.
// variant jaer = jAER DoubleWindowFilter (wlen 512 = 256 + 256, disThr 5 strict, i.e. L1 <= 4,
// numMustBeCorrelated 1): the first 2·buffer events are dropped while the windows fill; jAER writes them all to
// its signal array but only compares its first `buffer` entries, so the signal window starts with the first
// `buffer` events of the stream and the next `buffer` are forgotten; the noise window starts full of (−1, −1).
// Both quirks are reproduced. `buffer` and `l1_radius` default to the variant's values when not set.

#include <cstdint>
#include <vector>

#include "evpipe/core/event.hpp"
#include "evpipe/denoise/registry.hpp"

namespace evpipe::denoise {

struct DwfOptions {
  enum class Variant : std::uint8_t { cuke, jaer };
  static constexpr int kMaxSensorSide = 8000;  ///< coordinates are held in int16
  Variant variant = Variant::cuke;
  int buffer = 36;    ///< events per window
  int l1_radius = 9;  ///< |dx| + |dy| <= l1_radius supports
  int threshold = 1;  ///< supporting window events needed
};

class Dwf {
 public:
  Dwf(const SensorGeometry& geometry, DwfOptions options);
  [[nodiscard]] bool accept(const Event& e) noexcept;
  /// Number of window events within the L1 radius (higher = more signal-like); −1 while jAER's windows fill.
  [[nodiscard]] float last_score() const noexcept { return score_; }
  void reset() noexcept;

 private:
  // Both FIFOs live in one pair of coordinate arrays (x, y), int16 so that 8 / 16 / 32 lanes compare at once:
  // [signal window | padding | noise window | padding], each window padded to a multiple of kBlock with positions
  // so far away that they never support. Order inside a window does not matter for counting, so a window is a
  // ring with one write index.
  static constexpr std::size_t kBlock = 16;
  static constexpr std::int16_t kFar = -16'000;  // |dx| + |dy| stays < 32 768 for sensors up to 8 000 px

  [[nodiscard]] int count_near(std::int16_t x, std::int16_t y) const noexcept;
  void push(std::size_t window, std::int16_t x, std::int16_t y) noexcept;

  SensorGeometry geometry_;
  DwfOptions options_;
  std::size_t padded_;  // buffer rounded up to kBlock
  std::vector<std::int16_t> x_, y_;
  std::size_t next_[2] = {0, 0};  // write index of the signal (0) and noise (1) window
  std::int64_t fill_seen_ = 0;    // jAER: events consumed while filling
  float score_ = 0.0F;
};

FilterSpec dwf_spec();

}  // namespace evpipe::denoise
