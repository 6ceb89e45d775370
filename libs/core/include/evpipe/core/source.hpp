#pragma once
// One interface for every event source: recorded files (libs/io) and the live camera (libs/device).
// In the spirit of dv-processing's camera_input_base: "nothing new yet" is not an error.

#include <cstdint>
#include <optional>
#include <string>

#include "evpipe/core/event.hpp"

namespace evpipe {

struct SourceInfo {
  std::string name;    ///< file path or device serial
  std::string format;  ///< "aedat2", "aedat3.1", "aedat4", "text", "davis-live", ...
  SensorGeometry geometry{};
  bool geometry_known = false;  ///< false when the format carries no size and the default was assumed
  bool labelled = false;        ///< batches carry labels
};

/// Counters every source keeps. Recoverable problems are counted here (and reported as warnings),
/// fatal ones are thrown.
struct SourceStats {
  std::uint64_t events = 0;           ///< events delivered
  std::uint64_t batches = 0;          ///< batches delivered
  std::uint64_t bytes_read = 0;       ///< bytes consumed from the file / device
  std::uint64_t skipped_non_dvs = 0;  ///< APS/IMU/trigger/special words or packets skipped
  std::uint64_t out_of_order = 0;     ///< events with t_us < previous t_us (dropped or kept per policy)
  std::uint64_t discontinuities = 0;  ///< clock resets / large backward jumps
  std::uint64_t corrupt_packets = 0;  ///< packets skipped as unreadable (rest of the file still read)
  std::uint64_t dropped_packets = 0;  ///< live: whole packets dropped because a consumer was full
  std::uint64_t dropped_events = 0;   ///< live: events in those packets
  std::uint64_t invalid_events = 0;   ///< events with the valid bit cleared (AEDAT 3.1 / libcaer)
  std::uint64_t truncated_bytes = 0;  ///< bytes of a trailing partial record / packet ignored
};

/// Whether a source's device is there. Files are `connected` from start to end; a live camera that was unplugged is
/// `disconnected` while the source retries, and `closed` once it is closed for good.
enum class SourceConnection : std::uint8_t { connected, disconnected, closed };

class EventSource {
 public:
  virtual ~EventSource() = default;
  EventSource() = default;
  EventSource(const EventSource&) = delete;
  EventSource& operator=(const EventSource&) = delete;

  /// The next batch, or nullptr when nothing is available right now (live) or the source has ended
  /// (check `finished()`). Throws `evpipe::SourceError` (or a subclass) on a fatal error; every batch
  /// returned before the throw is valid.
  virtual EventBatchPtr next() = 0;
  /// True once a file is exhausted or a device is closed for good.
  [[nodiscard]] virtual bool finished() const = 0;
  [[nodiscard]] virtual const SourceInfo& info() const = 0;
  [[nodiscard]] virtual const SourceStats& stats() const = 0;
  /// Fraction of the input consumed, in [0, 1], when known (files); nullopt for live sources.
  [[nodiscard]] virtual std::optional<double> progress() const { return std::nullopt; }
  /// Is the device there? On the thread that calls next() (DavisSource's state is not synchronised); a wrapper
  /// forwards its inner source's.
  [[nodiscard]] virtual SourceConnection connection() const noexcept { return SourceConnection::connected; }
  /// Times a disconnected device came back. On the thread that calls next(), as connection().
  [[nodiscard]] virtual std::uint64_t reconnects() const noexcept { return 0; }
  /// Ends a wait inside next() at once (a paced replay's sleep): a source that overrides it then ends (next()
  /// returns nullptr, finished() true). Lock-free, any thread, safe from a signal handler; a wrapper forwards it.
  /// Default: nothing (the source never waits, e.g. the file readers and the non-blocking DavisSource; the
  /// pipeline's own stop flag ends its reading).
  virtual void stop() noexcept {}
};

}  // namespace evpipe
