#pragma once
// Plain event types shared by every evpipe library.
//
// Conventions (docs/architecture.md): time in integer microseconds on the recording's or device's clock;
// image origin top-left, x right, y down; polarity true = ON (brightness increase).

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <iterator>
#include <memory>
#include <span>
#include <vector>

namespace evpipe {

struct Event {
  std::int64_t t_us = 0;
  std::uint16_t x = 0;
  std::uint16_t y = 0;
  bool polarity = false;  // true = ON

  friend bool operator==(const Event&, const Event&) = default;
};

using EventSpan = std::span<const Event>;

/// Label of an event in a labelled recording (text files with a fifth column, evsim output).
enum class Label : std::uint8_t { noise = 0, signal = 1 };

/// A contiguous batch of events, produced once by a source and then only shared (never copied or mutated):
/// hand it on as `EventBatchPtr`.
struct EventBatch {
  std::vector<Event> events;
  /// Empty, or one label per event (same index) when the source is labelled.
  std::vector<Label> labels;
  /// True when the source's clock jumped (device timestamp reset, backward jump in a file) before this
  /// batch: windows and trackers that span batches must restart here.
  bool discontinuity_before = false;
  /// Host (steady clock) time the source delivered the events: when a reader or the camera made the batch, when a
  /// paced replay released it; a filter's kept batch carries that of the input batch holding its newest event.
  /// Latency figures start here; {} when unknown.
  std::chrono::steady_clock::time_point read_at{};

  [[nodiscard]] EventSpan span() const noexcept { return events; }
  [[nodiscard]] bool empty() const noexcept { return events.empty(); }
  [[nodiscard]] std::size_t size() const noexcept { return events.size(); }
  [[nodiscard]] bool labelled() const noexcept { return !labels.empty(); }
};

using EventBatchPtr = std::shared_ptr<const EventBatch>;

/// Sensor size in pixels.
struct SensorGeometry {
  int width = 346;
  int height = 260;

  [[nodiscard]] constexpr bool contains(int x, int y) const noexcept {
    return x >= 0 && y >= 0 && x < width && y < height;
  }
  [[nodiscard]] constexpr std::size_t pixels() const noexcept {
    return static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
  }
  friend bool operator==(const SensorGeometry&, const SensorGeometry&) = default;
};

/// The events of `events` later than t_us, in their order. In a time-ordered span they are a suffix, returned as a
/// subspan; otherwise (a source that keeps small backward jumps: source.drop_out_of_order: false) they are copied
/// into `scratch`.
inline EventSpan events_after(EventSpan events, std::int64_t t_us, std::vector<Event>& scratch) {
  const auto later = [t_us](const Event& e) { return e.t_us > t_us; };
  const auto first = std::find_if(events.begin(), events.end(), later);
  if (std::all_of(first, events.end(), later)) return {first, events.end()};
  scratch.clear();
  std::copy_if(first, events.end(), std::back_inserter(scratch), later);
  return scratch;
}

/// Appends `fresh` (events later than all of `held`) to `held`, which keeps at most `cap` events and none older than
/// `oldest_us` (held ∪ fresh loses its oldest first). Trimmed before appending, so that `held` never holds more than
/// it keeps: appending a ~350 000-event window first made the pose buffers grow to twice their bound.
inline void append_bounded(std::vector<Event>& held, EventSpan fresh, std::size_t cap, std::int64_t oldest_us) {
  const std::size_t n_held = held.size();
  const std::size_t total = n_held + fresh.size();
  const auto at = [&](std::size_t k) -> const Event& { return k < n_held ? held[k] : fresh[k - n_held]; };
  std::size_t drop = total > cap ? total - cap : 0;
  while (drop < total && at(drop).t_us < oldest_us) ++drop;
  held.erase(held.begin(), held.begin() + static_cast<std::ptrdiff_t>(std::min(drop, n_held)));
  held.insert(held.end(), fresh.begin() + static_cast<std::ptrdiff_t>(drop > n_held ? drop - n_held : 0), fresh.end());
}

/// The timestamps evpipe accepts: |t_us| <= 2^61 us (73 000 years; recordings carry microseconds since 1970, ~2^51).
/// The difference of any two then fits in int64 with room for every window, look-ahead and rate period added to
/// them; readers refuse a record outside it as corrupt (a damaged packet or a mistyped text line near the int64
/// limits made the filters' time steps overflow and spin).
inline constexpr std::int64_t kMaxAbsTimestampUs = std::int64_t{1} << 61;
[[nodiscard]] constexpr bool within_timestamp_limits(std::int64_t t_us) noexcept {
  return t_us >= -kMaxAbsTimestampUs && t_us <= kMaxAbsTimestampUs;
}

/// The largest sensor evpipe accepts, per side (docs/operations.md, "Limits"). The largest event sensors made are
/// 1280 x 720 (Prophesee IMX636) and 1280 x 960 (Samsung Gen4); 2048 x 2048 leaves 3.4x their pixel count as
/// headroom while bounding every per-pixel array (denoise::kMaxFilterBytesPerPixel) to a few hundred MB. Readers,
/// the configuration, evsim and the camera loader refuse larger sizes instead of letting a filter try to allocate
/// per-pixel state for 2^32 pixels.
inline constexpr int kMaxSensorSide = 2048;
[[nodiscard]] constexpr bool within_sensor_limits(const SensorGeometry& g) noexcept {
  return g.width >= 1 && g.height >= 1 && g.width <= kMaxSensorSide && g.height <= kMaxSensorSide;
}

inline constexpr SensorGeometry kDavis346{346, 260};
inline constexpr SensorGeometry kDavis240{240, 180};

}  // namespace evpipe
