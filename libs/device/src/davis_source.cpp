// Live DAVIS346 source on libcaer's C API. The sequence of libcaer calls is documented in
// docs/device.md; comments here say why a step is there.

#include "evpipe/device/davis_source.hpp"

#include <fmt/format.h>
#include <libcaer/devices/davis.h>
#include <libcaer/libcaer.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <deque>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <utility>

namespace evpipe::device {

namespace {

constexpr std::int64_t kFilterUnitUs = 250;     // DVS filter times are sent in 250 µs units
constexpr std::int64_t kFilterMaxUnits = 4095;  // 12-bit register
constexpr int kMaxContainersPerNext = 64;       // bound the work of one next() call (e.g. only special events)
constexpr std::string_view kRingDropText = "Dropped EventPacket Container because ring-buffer full";

// ---- process-wide routing of libcaer's log ----

struct LogRouting {
  std::mutex mu;
  LogHandler handler;
  LogLevel max_level = LogLevel::notice;
};

LogRouting& routing() {
  static LogRouting r;
  return r;
}

// libcaer reports ring-buffer overflows only in its log: count them here, sources read the delta.
std::atomic<std::uint64_t> g_ring_drops{0};

constexpr std::array<std::pair<std::string_view, LogLevel>, 8> kLevelTags{{
    {": EMERGENCY: ", LogLevel::emergency},
    {": ALERT: ", LogLevel::alert},
    {": CRITICAL: ", LogLevel::critical},
    {": ERROR: ", LogLevel::error},
    {": WARNING: ", LogLevel::warning},
    {": NOTICE: ", LogLevel::notice},
    {": INFO: ", LogLevel::info},
    {": DEBUG: ", LogLevel::debug},
}};

// libcaer formats "<time>: <LEVEL>: <subsystem>: <message>\n" and hands us only the string.
void caer_log_trampoline(const char* msg, std::size_t length) {
  if (msg == nullptr) return;
  std::string_view line(msg, length);
  if (line.find(kRingDropText) != std::string_view::npos) g_ring_drops.fetch_add(1, std::memory_order_relaxed);

  LogLevel level = LogLevel::info;
  std::size_t best = std::string_view::npos;
  std::size_t text_from = 0;
  for (const auto& [tag, tag_level] : kLevelTags) {
    const auto pos = line.find(tag);
    if (pos != std::string_view::npos && pos < best) {
      best = pos;
      level = tag_level;
      text_from = pos + tag.size();
    }
  }
  std::string_view text = line.substr(text_from);
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.remove_suffix(1);

  LogHandler handler;
  {
    auto& r = routing();
    std::lock_guard lock(r.mu);
    if (!r.handler || static_cast<int>(level) > static_cast<int>(r.max_level)) return;
    handler = r.handler;  // call outside the lock: the handler may log or reconfigure
  }
  handler(level, text);
}

void install_trampoline() {
  caerLogCallbackSet(&caer_log_trampoline);
}

// libcaer calls this from its USB thread on an exceptional shutdown (unplug, transfer failure).
void on_data_shutdown(void* flag) {
  static_cast<std::atomic<bool>*>(flag)->store(true, std::memory_order_release);
}

std::string open_error_reason(int error) {
  switch (error) {
    case CAER_ERROR_OPEN_ACCESS:
      return "no DAVIS camera found or access denied (CAER_ERROR_OPEN_ACCESS): check that the camera is plugged "
             "in and not used by another program, and that the udev rule for USB vendor 152a is installed and "
             "the user is in its group (docs/device.md)";
    case CAER_ERROR_MEMORY_ALLOCATION:
      return "out of memory (CAER_ERROR_MEMORY_ALLOCATION)";
    case CAER_ERROR_RESOURCE_ALLOCATION:
      return "could not allocate USB resources (CAER_ERROR_RESOURCE_ALLOCATION)";
    case CAER_ERROR_COMMUNICATION:
      return "USB communication with the camera failed (CAER_ERROR_COMMUNICATION): replug it, or try another "
             "port or cable";
    case CAER_ERROR_FW_VERSION:
      return "the camera's firmware is too old for this libcaer (CAER_ERROR_FW_VERSION): update it with "
             "iniVation's flashing tool";
    case CAER_ERROR_LOGIC_VERSION:
      return "the camera's FPGA logic is too old for this libcaer (CAER_ERROR_LOGIC_VERSION): update it with "
             "iniVation's flashing tool";
    default:
      return fmt::format("libcaer reported error {} ({})", error,
                         error > 0 ? std::strerror(error) : "unknown libcaer error code");
  }
}

std::string fixed_string(const char* s, std::size_t max) {
  if (s == nullptr) return {};
  return std::string(s, ::strnlen(s, max));
}

}  // namespace

bool using_real_libcaer() noexcept {
#if defined(LIBCAER_IS_STUB) && LIBCAER_IS_STUB
  return false;
#else
  return true;
#endif
}

std::string_view log_level_name(LogLevel level) noexcept {
  switch (level) {
    case LogLevel::emergency:
      return "emergency";
    case LogLevel::alert:
      return "alert";
    case LogLevel::critical:
      return "critical";
    case LogLevel::error:
      return "error";
    case LogLevel::warning:
      return "warning";
    case LogLevel::notice:
      return "notice";
    case LogLevel::info:
      return "info";
    case LogLevel::debug:
      return "debug";
  }
  return "unknown";
}

std::string_view libcaer_version() noexcept {
#if defined(LIBCAER_IS_STUB) && LIBCAER_IS_STUB
  return "stub: no camera support";
#else
  return LIBCAER_VERSION_STRING;
#endif
}

LogLevel log_level_from_name(std::string_view name) noexcept {
  if (name == "trace" || name == "debug") return LogLevel::debug;
  if (name == "info") return LogLevel::info;
  if (name == "warn" || name == "warning") return LogLevel::warning;
  if (name == "err" || name == "error") return LogLevel::error;
  if (name == "critical") return LogLevel::critical;
  if (name == "off") return LogLevel::emergency;
  return LogLevel::notice;
}

void set_libcaer_log_level(LogLevel level) {
  {
    auto& r = routing();
    std::lock_guard lock(r.mu);
    r.max_level = level;
  }
  caerLogLevelSet(static_cast<enum caer_log_level>(level));
}

void set_libcaer_log_handler(LogHandler handler, LogLevel max_level) {
  const bool have_handler = static_cast<bool>(handler);
  {
    auto& r = routing();
    std::lock_guard lock(r.mu);
    r.handler = std::move(handler);
    r.max_level = max_level;
  }
  install_trampoline();
  // With a handler the application owns the output; without one libcaer writes to stderr as usual.
  caerLogFileDescriptorsSet(have_handler ? -1 : STDERR_FILENO, -1);
}

std::string_view state_name(DeviceState state) noexcept {
  switch (state) {
    case DeviceState::connected:
      return "connected";
    case DeviceState::disconnected:
      return "disconnected";
    case DeviceState::closed:
      return "closed";
  }
  return "unknown";
}

std::uint32_t filter_time_units(std::int64_t time_us, std::string_view field) {
  if (time_us < 0 || time_us > kFilterMaxUnits * kFilterUnitUs) {
    throw std::invalid_argument(fmt::format("DavisOptions.{} = {} µs is out of range: the camera accepts 0 to {} µs",
                                            field, time_us, kFilterMaxUnits * kFilterUnitUs));
  }
  if (time_us % kFilterUnitUs != 0) {
    throw std::invalid_argument(
        fmt::format("DavisOptions.{} = {} µs is not a multiple of {} µs (the camera's filter time unit); use {} or {}",
                    field, time_us, kFilterUnitUs, time_us / kFilterUnitUs * kFilterUnitUs,
                    (time_us / kFilterUnitUs + 1) * kFilterUnitUs));
  }
  return static_cast<std::uint32_t>(time_us / kFilterUnitUs);
}

void validate(const DavisOptions& o) {
  (void)filter_time_units(o.ba_filter_time_us, "ba_filter_time_us");
  (void)filter_time_units(o.refractory_time_us, "refractory_time_us");
  auto require = [](bool ok, std::string_view field, auto value, std::string_view rule) {
    if (!ok) throw std::invalid_argument(fmt::format("DavisOptions.{} = {}: {}", field, value, rule));
  };
  require(o.container_interval_us >= 1 && o.container_interval_us <= 1'000'000, "container_interval_us",
          o.container_interval_us, "must be in [1, 1000000] µs");
  require(o.container_max_events >= 0 && o.container_max_events <= 10'000'000, "container_max_events",
          o.container_max_events, "must be in [0, 10000000] events (0 = no size limit)");
  const auto ring = o.data_exchange_buffer;
  require(ring >= 1 && ring <= 65536 && (ring & (ring - 1)) == 0, "data_exchange_buffer", ring,
          "must be a power of two in [1, 65536] containers (libcaer's ring buffer)");
  require(o.reconnect_interval_ms >= 0 && o.reconnect_interval_ms <= 3'600'000, "reconnect_interval_ms",
          o.reconnect_interval_ms, "must be in [0, 3600000] ms");
  require(o.statistics_interval_ms >= 0 && o.statistics_interval_ms <= 3'600'000, "statistics_interval_ms",
          o.statistics_interval_ms, "must be in [0, 3600000] ms (0 = never read the counters)");
  require(o.discontinuity_us > 0, "discontinuity_us", o.discontinuity_us, "must be positive");
  require(o.serial_number.size() <= 8, "serial_number", fmt::format("\"{}\"", o.serial_number),
          "a DAVIS serial number has at most 8 characters");
  const int level = static_cast<int>(o.libcaer_log_level);
  require(level >= 0 && level <= 7, "libcaer_log_level", level, "must be one of emergency (0) .. debug (7)");
}

// ---------------------------------------------------------------------------------------------------

struct DavisSource::Impl {
  DavisOptions opt;
  caerDeviceHandle handle = nullptr;
  DeviceState state = DeviceState::closed;
  std::atomic<bool> shutdown{false};  // set by libcaer's shutdown callback

  SourceInfo info;
  SourceStats stats;
  DavisDeviceInfo device;
  bool ever_connected = false;

  std::deque<EventBatchPtr> ready;  // a container can yield two batches (split at a backward jump)
  bool pending_discontinuity = false;
  bool have_last_t = false;
  std::int64_t last_t_us = 0;

  std::chrono::steady_clock::time_point last_reconnect_attempt{};
  std::chrono::steady_clock::time_point last_statistics_poll{};
  std::uint64_t reconnects = 0;
  bool reconnect_failure_reported = false;

  std::uint64_t dropped_before_session = 0;  // camera drop counts of earlier sessions
  std::uint64_t dropped_counter_baseline = 0;
  std::uint64_t ring_drops_seen = 0;

  [[nodiscard]] std::chrono::steady_clock::time_point now() const {
    return opt.clock ? opt.clock() : std::chrono::steady_clock::now();
  }

  void warn(std::string what) const {
    if (opt.on_warning) opt.on_warning(Warning{info.name, std::nullopt, std::move(what)});
  }

  [[nodiscard]] std::string camera_name() const {
    return device.serial_number.empty() ? std::string("DAVIS camera") : "DAVIS camera SN " + device.serial_number;
  }

  void close_handle() {
    if (handle != nullptr) {
      caerDeviceDataStop(handle);  // harmless after an exceptional shutdown
      caerDeviceClose(&handle);
      handle = nullptr;
    }
  }

  // Opens, configures and starts the camera. Returns the reason on failure (handle closed again).
  std::optional<std::string> open_and_start() {
    const std::string& serial = opt.serial_number;
    errno = 0;
    caerDeviceHandle h =
        caerDeviceOpen(opt.device_id, CAER_DEVICE_DAVIS, 0, 0, serial.empty() ? nullptr : serial.c_str());
    if (h == nullptr) {
      return fmt::format(
          "cannot open {}: {}",
          serial.empty() ? std::string("a DAVIS camera") : "the DAVIS camera with serial number " + serial,
          open_error_reason(errno));
    }
    auto fail = [&](std::string why) -> std::optional<std::string> {
      caerDeviceClose(&h);
      return why;
    };

    const caer_davis_info ci = caerDavisInfoGet(h);
    DavisDeviceInfo d;
    d.serial_number = fixed_string(ci.deviceSerialNumber, sizeof ci.deviceSerialNumber);
    d.device_string = fixed_string(ci.deviceString, 256);
    d.chip_id = ci.chipID;
    d.is_davis346 = IS_DAVIS346(ci.chipID);
    d.firmware_version = ci.firmwareVersion;
    d.logic_version = ci.logicVersion;
    d.has_ba_filter = ci.dvsHasBackgroundActivityFilter;
    d.has_mux_statistics = ci.muxHasStatistics;
    d.geometry = SensorGeometry{ci.dvsSizeX, ci.dvsSizeY};
    const std::string name = "DAVIS camera SN " + d.serial_number;
    if (d.geometry.width <= 0 || d.geometry.height <= 0) {
      return fail(
          fmt::format("{} reported an invalid DVS array size {}x{}", name, d.geometry.width, d.geometry.height));
    }
    if (ever_connected && d.geometry != device.geometry) {
      return fail(fmt::format("{} has a {}x{} DVS array, but the stream so far came from a {}x{} one; not using it",
                              name, d.geometry.width, d.geometry.height, device.geometry.width,
                              device.geometry.height));
    }
    if (!d.is_davis346) {
      warn(fmt::format("{} is not a DAVIS346 (chip ID {}); using its {}x{} DVS array anyway", name, d.chip_id,
                       d.geometry.width, d.geometry.height));
    }

    // Nothing is configured automatically: defaults first, then our changes on top (libcaer's order).
    if (!caerDeviceSendDefaultConfig(h))
      return fail(fmt::format("sending the default configuration to {} failed", name));

    std::optional<std::string> config_error;
    auto set = [&](std::int8_t module, std::uint8_t param, std::uint32_t value) {
      if (!config_error && !caerDeviceConfigSet(h, module, param, value)) {
        config_error =
            fmt::format("configuring {} failed (module {}, parameter {}, value {})", name, module, param, value);
      }
    };
    // NOTICE at least for this camera, so libcaer's "ring-buffer full" drops reach the trampoline.
    const int device_log_level = std::max(static_cast<int>(opt.libcaer_log_level), static_cast<int>(LogLevel::notice));
    set(CAER_HOST_CONFIG_LOG, CAER_HOST_CONFIG_LOG_LEVEL, static_cast<std::uint32_t>(device_log_level));
    set(DAVIS_CONFIG_APS, DAVIS_CONFIG_APS_RUN, opt.aps_enabled ? 1 : 0);
    set(DAVIS_CONFIG_IMU, DAVIS_CONFIG_IMU_RUN_ACCELEROMETER, opt.imu_enabled ? 1 : 0);
    set(DAVIS_CONFIG_IMU, DAVIS_CONFIG_IMU_RUN_GYROSCOPE, opt.imu_enabled ? 1 : 0);
    set(DAVIS_CONFIG_IMU, DAVIS_CONFIG_IMU_RUN_TEMPERATURE, opt.imu_enabled ? 1 : 0);
    if (ci.dvsHasBackgroundActivityFilter) {
      set(DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_BACKGROUND_ACTIVITY, opt.ba_filter_enabled ? 1 : 0);
      set(DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_BACKGROUND_ACTIVITY_TIME,
          filter_time_units(opt.ba_filter_time_us, "ba_filter_time_us"));
      set(DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_REFRACTORY_PERIOD, opt.refractory_enabled ? 1 : 0);
      set(DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_REFRACTORY_PERIOD_TIME,
          filter_time_units(opt.refractory_time_us, "refractory_time_us"));
    } else if (opt.ba_filter_enabled || opt.refractory_enabled) {
      warn(
          fmt::format("{} has no hardware background-activity / refractory filter (e.g. a DAVIS240C); the "
                      "ba_filter / refractory options are ignored: use a software filter instead",
                      name));
    }
    set(CAER_HOST_CONFIG_PACKETS, CAER_HOST_CONFIG_PACKETS_MAX_CONTAINER_INTERVAL,
        static_cast<std::uint32_t>(opt.container_interval_us));
    set(CAER_HOST_CONFIG_PACKETS, CAER_HOST_CONFIG_PACKETS_MAX_CONTAINER_PACKET_SIZE,
        static_cast<std::uint32_t>(opt.container_max_events));
    set(CAER_HOST_CONFIG_DATAEXCHANGE, CAER_HOST_CONFIG_DATAEXCHANGE_BUFFER_SIZE,
        static_cast<std::uint32_t>(opt.data_exchange_buffer));
    // next() must never block the pipeline: poll, NULL = nothing yet.
    set(CAER_HOST_CONFIG_DATAEXCHANGE, CAER_HOST_CONFIG_DATAEXCHANGE_BLOCKING, 0);
    set(CAER_HOST_CONFIG_DATAEXCHANGE, CAER_HOST_CONFIG_DATAEXCHANGE_START_PRODUCERS, 1);
    set(CAER_HOST_CONFIG_DATAEXCHANGE, CAER_HOST_CONFIG_DATAEXCHANGE_STOP_PRODUCERS, 1);
    if (config_error) return fail(*config_error);

    shutdown.store(false, std::memory_order_release);
    if (!caerDeviceDataStart(h, nullptr, nullptr, nullptr, &on_data_shutdown, &shutdown)) {
      return fail(fmt::format("starting the data transfer from {} failed", name));
    }

    handle = h;
    device = std::move(d);
    ever_connected = true;
    state = DeviceState::connected;
    info.name = device.serial_number;
    info.format = "davis-live";
    info.geometry = device.geometry;
    info.geometry_known = true;
    info.labelled = false;

    // The camera's drop counter may not start at zero: count from here, on top of earlier sessions.
    dropped_before_session = stats.dropped_events;
    dropped_counter_baseline = 0;
    if (device.has_mux_statistics) {
      std::uint64_t v = 0;
      if (caerDeviceConfigGet64(handle, DAVIS_CONFIG_MUX, DAVIS_CONFIG_MUX_STATISTICS_DVS_DROPPED, &v)) {
        dropped_counter_baseline = v;
      }
    }
    last_statistics_poll = now();
    return std::nullopt;
  }

  void handle_shutdown() {
    close_handle();
    state = DeviceState::disconnected;
    have_last_t = false;
    last_reconnect_attempt = now();
    reconnect_failure_reported = false;
    warn(fmt::format("{} disconnected (libcaer stopped the data transfer); reopening every {} ms", camera_name(),
                     opt.reconnect_interval_ms));
  }

  bool reconnect_now() {
    last_reconnect_attempt = now();
    if (auto error = open_and_start()) {
      if (!reconnect_failure_reported) {
        warn(fmt::format("{}; still retrying every {} ms", *error, opt.reconnect_interval_ms));
        reconnect_failure_reported = true;
      }
      return false;
    }
    ++reconnects;
    // Device time restarted with the new session: windows must not span the gap.
    pending_discontinuity = true;
    have_last_t = false;
    ++stats.discontinuities;
    warn(fmt::format("{} reconnected; device time restarted (the next batch has discontinuity_before)", camera_name()));
    return true;
  }

  void poll_statistics() {
    const std::uint64_t ring_drops = g_ring_drops.load(std::memory_order_relaxed);
    stats.dropped_packets += ring_drops - ring_drops_seen;
    ring_drops_seen = ring_drops;
    if (state != DeviceState::connected || !device.has_mux_statistics || opt.statistics_interval_ms <= 0) return;
    const auto t = now();
    if (t - last_statistics_poll < std::chrono::milliseconds(opt.statistics_interval_ms)) return;
    last_statistics_poll = t;
    std::uint64_t v = 0;
    if (caerDeviceConfigGet64(handle, DAVIS_CONFIG_MUX, DAVIS_CONFIG_MUX_STATISTICS_DVS_DROPPED, &v) &&
        v >= dropped_counter_baseline) {
      stats.dropped_events = dropped_before_session + (v - dropped_counter_baseline);
    }
  }

  void emit(EventBatch& batch) {
    if (batch.events.empty()) return;
    batch.discontinuity_before = pending_discontinuity;
    pending_discontinuity = false;
    stats.events += batch.events.size();
    ++stats.batches;
    batch.read_at = std::chrono::steady_clock::now();
    ready.push_back(std::make_shared<const EventBatch>(std::move(batch)));
    batch = EventBatch{};
  }

  void convert_polarity(caerEventPacketHeaderConst header, EventBatch& batch) {
    const std::int32_t number = caerEventPacketHeaderGetEventNumber(header);
    if (number < 0 || number > caerEventPacketHeaderGetEventCapacity(header) ||
        caerEventPacketHeaderGetEventSize(header) != static_cast<std::int32_t>(sizeof(struct caer_polarity_event))) {
      ++stats.corrupt_packets;  // never seen from libcaer; guards the pointer arithmetic below
      return;
    }
    caerPolarityEventPacketConst packet = caerPolarityEventPacketFromPacketHeaderConst(header);
    batch.events.reserve(batch.events.size() + static_cast<std::size_t>(number));
    for (std::int32_t i = 0; i < number; ++i) {
      caerPolarityEventConst ev = caerPolarityEventPacketGetEventConst(packet, i);
      if (!caerPolarityEventIsValid(ev)) {
        ++stats.invalid_events;
        continue;
      }
      const std::int64_t t_us = caerPolarityEventGetTimestamp64(ev, packet);
      const std::uint16_t x = caerPolarityEventGetX(ev);
      const std::uint16_t y = caerPolarityEventGetY(ev);
      if (!device.geometry.contains(x, y)) {
        ++stats.invalid_events;  // outside the reported array: not a usable pixel
        continue;
      }
      if (have_last_t && t_us < last_t_us) {
        if (last_t_us - t_us > opt.discontinuity_us) {
          emit(batch);  // the flag must apply from this event on
          pending_discontinuity = true;
          ++stats.discontinuities;
        } else {
          ++stats.out_of_order;  // downstream windows need time order
          continue;
        }
      }
      batch.events.push_back(Event{t_us, x, y, caerPolarityEventGetPolarity(ev)});
      last_t_us = t_us;
      have_last_t = true;
    }
  }

  void convert(caerEventPacketContainer container) {
    EventBatch batch;
    bool timestamp_reset = false;
    const std::int32_t slots = caerEventPacketContainerGetEventPacketsNumber(container);
    // Polarity packets first: libcaer commits a container when the timestamp resets, so a reset is
    // always the last thing in its container (3.3 even sends it in a container of its own).
    for (std::int32_t i = 0; i < slots; ++i) {
      caerEventPacketHeaderConst header = caerEventPacketContainerGetEventPacketConst(container, i);
      if (header == nullptr) continue;
      const std::int32_t number = std::max<std::int32_t>(0, caerEventPacketHeaderGetEventNumber(header));
      const std::int32_t size = std::max<std::int32_t>(0, caerEventPacketHeaderGetEventSize(header));
      stats.bytes_read +=
          CAER_EVENT_PACKET_HEADER_SIZE + static_cast<std::uint64_t>(number) * static_cast<std::uint64_t>(size);
      const auto type = caerEventPacketHeaderGetEventType(header);
      if (type == POLARITY_EVENT) {
        convert_polarity(header, batch);
      } else if (type == SPECIAL_EVENT) {
        stats.skipped_non_dvs += static_cast<std::uint64_t>(number);
        if (number > caerEventPacketHeaderGetEventCapacity(header) ||
            size != static_cast<std::int32_t>(sizeof(struct caer_special_event))) {
          ++stats.corrupt_packets;
          continue;
        }
        caerSpecialEventPacketConst special = caerSpecialEventPacketFromPacketHeaderConst(header);
        for (std::int32_t k = 0; k < number; ++k) {
          caerSpecialEventConst ev = caerSpecialEventPacketGetEventConst(special, k);
          if (caerSpecialEventIsValid(ev) && caerSpecialEventGetType(ev) == TIMESTAMP_RESET) timestamp_reset = true;
        }
      } else {
        stats.skipped_non_dvs += static_cast<std::uint64_t>(number);  // frames, IMU samples, ...
      }
    }
    emit(batch);
    if (timestamp_reset) {
      pending_discontinuity = true;
      have_last_t = false;  // device time starts again from 0
      ++stats.discontinuities;
    }
  }
};

// ---------------------------------------------------------------------------------------------------

DavisSource::DavisSource(DavisOptions options) : impl_(std::make_unique<Impl>()) {
  validate(options);
  impl_->opt = std::move(options);
  Impl& m = *impl_;
  if (m.opt.on_log) set_libcaer_log_handler(m.opt.on_log, m.opt.libcaer_log_level);
  install_trampoline();
  caerLogLevelSet(static_cast<enum caer_log_level>(m.opt.libcaer_log_level));
  m.info.name = m.opt.serial_number.empty() ? std::string("DAVIS") : m.opt.serial_number;
  m.info.format = "davis-live";
  m.info.geometry = kDavis346;
  m.ring_drops_seen = g_ring_drops.load(std::memory_order_relaxed);
  if (auto error = m.open_and_start()) throw SourceError(*error);
}

DavisSource::~DavisSource() {
  close();
}

EventBatchPtr DavisSource::next() {
  Impl& m = *impl_;
  if (m.state == DeviceState::closed) return nullptr;
  if (m.state == DeviceState::connected && m.shutdown.load(std::memory_order_acquire)) m.handle_shutdown();

  if (m.ready.empty() && m.state == DeviceState::disconnected &&
      m.now() - m.last_reconnect_attempt >= std::chrono::milliseconds(m.opt.reconnect_interval_ms)) {
    m.reconnect_now();
  }

  for (int i = 0; i < kMaxContainersPerNext && m.ready.empty() && m.state == DeviceState::connected; ++i) {
    caerEventPacketContainer container = caerDeviceDataGet(m.handle);
    if (container == nullptr) {
      if (m.shutdown.load(std::memory_order_acquire)) m.handle_shutdown();
      break;
    }
    m.convert(container);
    caerEventPacketContainerFree(container);
  }
  m.poll_statistics();

  if (m.ready.empty()) return nullptr;
  EventBatchPtr batch = std::move(m.ready.front());
  m.ready.pop_front();
  return batch;
}

bool DavisSource::finished() const {
  return impl_->state == DeviceState::closed;
}

const SourceInfo& DavisSource::info() const {
  return impl_->info;
}

const SourceStats& DavisSource::stats() const {
  return impl_->stats;
}

DeviceState DavisSource::state() const noexcept {
  return impl_->state;
}

SourceConnection DavisSource::connection() const noexcept {
  switch (impl_->state) {
    case DeviceState::connected:
      return SourceConnection::connected;
    case DeviceState::disconnected:
      return SourceConnection::disconnected;
    case DeviceState::closed:
      break;
  }
  return SourceConnection::closed;
}

const DavisDeviceInfo& DavisSource::device_info() const noexcept {
  return impl_->device;
}

const DavisOptions& DavisSource::options() const noexcept {
  return impl_->opt;
}

std::uint64_t DavisSource::reconnects() const noexcept {
  return impl_->reconnects;
}

bool DavisSource::try_reconnect() {
  Impl& m = *impl_;
  if (m.state == DeviceState::closed) return false;
  if (m.state == DeviceState::connected && m.shutdown.load(std::memory_order_acquire)) m.handle_shutdown();
  if (m.state == DeviceState::connected) return true;
  return m.reconnect_now();
}

void DavisSource::close() {
  if (!impl_) return;
  impl_->close_handle();
  impl_->state = DeviceState::closed;
  impl_->ready.clear();
}

}  // namespace evpipe::device
