#pragma once
// Live DAVIS346 event source on libcaer's C API (docs/device.md).
//
//   evpipe::device::DavisSource cam;            // opens the first DAVIS found, or throws SourceError
//   while (running) {
//     if (auto batch = cam.next()) { ... }      // nullptr = nothing new right now (never blocks)
//   }
//
// One batch per libcaer packet container (container_interval_us of device time). Times are device
// time since the camera's last timestamp reset (µs); a reset, a reconnect or a large backward jump
// sets discontinuity_before on the next batch. When the camera is unplugged the source goes to
// DeviceState::disconnected, next() returns nullptr and retries opening at most every
// reconnect_interval_ms; it never throws after construction. Call it from one thread (libcaer's USB
// thread only sets an atomic flag through the shutdown callback).
//
// libcaer's log is process-wide: route it with set_libcaer_log_handler() (or DavisOptions::on_log).
// This library has no logging dependency of its own; the application wires the handler to its logger.

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

#include "evpipe/core/error.hpp"
#include "evpipe/core/source.hpp"

namespace evpipe::device {

/// True when built against the real libcaer; false with evpipe's stub, whose caerDeviceOpen() only ever
/// finds the scripted fake camera of the tests (EVPIPE_WITH_LIBCAER, docs/device.md).
[[nodiscard]] bool using_real_libcaer() noexcept;

/// libcaer's syslog-style levels (same numbers as enum caer_log_level).
enum class LogLevel : int {
  emergency = 0,
  alert = 1,
  critical = 2,
  error = 3,
  warning = 4,
  notice = 5,
  info = 6,
  debug = 7
};

[[nodiscard]] std::string_view log_level_name(LogLevel level) noexcept;

/// The libcaer this build uses, for `evpipe --version`: its version from the headers it was compiled against
/// (LIBCAER_VERSION_STRING, e.g. "3.3.15"), or "stub: no camera support" with evpipe's stub.
[[nodiscard]] std::string_view libcaer_version() noexcept;

/// libcaer's level for an application log level name (spdlog's: trace, debug, info, warn/warning, err/error,
/// critical, off): trace and debug → debug, info → info, warn → warning, error → error, critical → critical,
/// off → emergency (libcaer cannot be silenced further). Unknown names → notice (libcaer's default for evpipe).
[[nodiscard]] LogLevel log_level_from_name(std::string_view name) noexcept;

/// Sets libcaer's process-wide log level (caerLogLevelSet) and the level up to which lines reach the handler of
/// set_libcaer_log_handler(). Each DavisSource also sets it from DavisOptions::libcaer_log_level.
void set_libcaer_log_level(LogLevel level);

/// Receives one libcaer log line: its level and the text after the level ("<subsystem>: <message>",
/// without libcaer's time prefix and trailing newline).
using LogHandler = std::function<void(LogLevel level, std::string_view message)>;

/// Installs the process-wide handler for libcaer's log (an empty function restores libcaer's default
/// output to stderr). Lines above `max_level` are not forwarded.
void set_libcaer_log_handler(LogHandler handler, LogLevel max_level = LogLevel::notice);

struct DavisOptions {
  /// Empty: the first DAVIS found; otherwise only the camera with this serial number (e.g. "00000346").
  std::string serial_number;
  /// libcaer device ID (becomes the eventSource of packets; any value is fine for one camera).
  std::uint16_t device_id = 1;

  // Hardware DVS filters (DAVIS346 FPGA). Times in µs, sent to the camera in units of 250 µs, so they
  // must be multiples of 250 in [0, 4095 * 250]. The camera's own default is BA on at 2 ms: switch it off
  // when the software denoisers should see raw noise.
  bool ba_filter_enabled = true;
  std::int64_t ba_filter_time_us = 2000;
  bool refractory_enabled = false;
  std::int64_t refractory_time_us = 250;

  /// libcaer commits a packet container after this much device time (CAER_HOST_CONFIG_PACKETS_
  /// MAX_CONTAINER_INTERVAL); one container = one batch. [1, 1 000 000] µs.
  std::int64_t container_interval_us = 5000;
  /// ...or once a packet holds this many events (CAER_HOST_CONFIG_PACKETS_MAX_CONTAINER_PACKET_SIZE);
  /// 0 = no size limit (libcaer's default). At most 10 000 000.
  std::int64_t container_max_events = 0;
  /// Containers libcaer's ring can hold before it drops the newest (power of two, 1..65536).
  std::int64_t data_exchange_buffer = 64;

  /// APS frames and IMU samples are switched off on the camera (evpipe uses DVS events only); turning
  /// them on only costs USB bandwidth: their packets are skipped and counted in skipped_non_dvs.
  bool aps_enabled = false;
  bool imu_enabled = false;

  /// Minimum time between two reopen attempts after the camera was lost.
  std::int64_t reconnect_interval_ms = 1000;
  /// How often next() reads the camera's drop counter (a USB control transfer); 0 = never.
  std::int64_t statistics_interval_ms = 1000;
  /// A backward jump in device time larger than this without a TIMESTAMP_RESET is treated as a
  /// discontinuity; smaller ones are out-of-order events and are dropped (counted).
  std::int64_t discontinuity_us = 1'000'000;

  /// Level for libcaer's messages about this camera (lines above it are not forwarded).
  LogLevel libcaer_log_level = LogLevel::notice;
  /// If set, installed as the process-wide libcaer log handler (see set_libcaer_log_handler()).
  LogHandler on_log;
  /// Recoverable problems of this source (camera not a DAVIS346, no hardware BA filter, camera lost,
  /// reopen failed, ...). Default: ignored (still visible in stats() / state()).
  std::function<void(const Warning&)> on_warning;
  /// Monotonic clock for the reconnect and statistics intervals (tests inject a fake one).
  std::function<std::chrono::steady_clock::time_point()> clock;
};

/// Throws std::invalid_argument naming the offending field when an option is out of range.
void validate(const DavisOptions& options);

/// `time_us` in the camera's 250 µs filter units; throws std::invalid_argument naming `field` when it is
/// not a multiple of 250 or outside [0, 4095 * 250].
std::uint32_t filter_time_units(std::int64_t time_us, std::string_view field);

enum class DeviceState { connected, disconnected, closed };
[[nodiscard]] std::string_view state_name(DeviceState state) noexcept;

/// What the opened camera reported (caerDavisInfoGet).
struct DavisDeviceInfo {
  std::string serial_number;
  std::string device_string;
  int chip_id = -1;
  bool is_davis346 = false;
  int firmware_version = 0;
  int logic_version = 0;
  bool has_ba_filter = false;
  bool has_mux_statistics = false;
  SensorGeometry geometry{};
};

class DavisSource final : public EventSource {
 public:
  /// Opens and configures the camera and starts the data transfer. Throws std::invalid_argument for bad
  /// options and evpipe::SourceError when no usable camera can be opened.
  explicit DavisSource(DavisOptions options = {});
  /// DataStop + Close.
  ~DavisSource() override;

  /// The next batch (one libcaer container's valid polarity events), or nullptr when nothing is
  /// available now, while disconnected, or after close(). Non-blocking.
  EventBatchPtr next() override;
  /// True after close() only (a lost camera is retried, not finished).
  [[nodiscard]] bool finished() const override;
  [[nodiscard]] const SourceInfo& info() const override;
  /// events / batches / invalid_events / discontinuities / skipped_non_dvs / out_of_order / bytes_read;
  /// dropped_events = the camera's DVS drop counter (DAVIS_CONFIG_MUX_STATISTICS_DVS_DROPPED, summed over
  /// reconnects); dropped_packets = containers libcaer dropped because its ring was full.
  [[nodiscard]] const SourceStats& stats() const override;

  [[nodiscard]] DeviceState state() const noexcept;
  /// state() as every source says it (connected / disconnected / closed).
  [[nodiscard]] SourceConnection connection() const noexcept override;
  [[nodiscard]] const DavisDeviceInfo& device_info() const noexcept;
  [[nodiscard]] const DavisOptions& options() const noexcept;
  /// Successful reopenings after a loss.
  [[nodiscard]] std::uint64_t reconnects() const noexcept override;

  /// Tries to reopen a lost camera now, ignoring reconnect_interval_ms. True when connected afterwards
  /// (also when it already was); false after close().
  bool try_reconnect();
  /// Stops the transfer and closes the camera for good (idempotent).
  void close();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace evpipe::device
