// evpipe libcaer stub: the device functions of libcaer's C API, implemented against one scripted fake
// DAVIS (libcaer_stub/fake_device.h explains what it simulates).

#include <libcaer/devices/davis.h>
#include <libcaer_stub/fake_device.h>

#include <algorithm>
#include <cerrno>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <deque>
#include <functional>
#include <map>
#include <mutex>
#include <stdexcept>
#include <string>
#include <utility>

// The handle libcaer returns is opaque; the stub's handle only remembers which open session it belongs to.
struct caer_device_handle {
  std::uint64_t session = 0;
  std::int16_t device_id = 0;
  std::string device_string;
};

namespace caer_stub {

namespace {

constexpr std::int64_t kMaxTimeUs = std::int64_t{1} << 62;
constexpr std::int32_t kTsMask = 0x7FFFFFFF;
constexpr int kDavisSlots = 4;  // special, polarity, frame, IMU6: slot index = event type
using ConfigKey = std::pair<std::int8_t, std::uint8_t>;

struct Item {
  enum class Kind { polarity, special, reset } kind = Kind::polarity;
  FakeEvent event;  // polarity: the event; special: t_us only
  std::uint8_t special_type = 0;
  std::uint32_t special_data = 0;
};

struct SpecialOut {
  std::int32_t ts = 0;
  std::uint8_t type = 0;
  std::uint32_t data = 0;
};

// Container under construction (one overflow epoch).
struct Building {
  std::vector<FakeEvent> polarity;
  std::vector<SpecialOut> special;
  [[nodiscard]] bool empty() const { return polarity.empty() && special.empty(); }
};

// libcaer packets carry spare capacity; round up so consumers must honour eventNumber.
std::int32_t capacity_for(std::size_t n) {
  return static_cast<std::int32_t>(((n / 64) + 1) * 64);
}

std::map<ConfigKey, std::uint32_t> host_defaults(int log_level) {
  return {
      {{CAER_HOST_CONFIG_USB, CAER_HOST_CONFIG_USB_BUFFER_NUMBER}, 8},
      {{CAER_HOST_CONFIG_USB, CAER_HOST_CONFIG_USB_BUFFER_SIZE}, 8192},
      {{CAER_HOST_CONFIG_DATAEXCHANGE, CAER_HOST_CONFIG_DATAEXCHANGE_BUFFER_SIZE}, 64},
      {{CAER_HOST_CONFIG_DATAEXCHANGE, CAER_HOST_CONFIG_DATAEXCHANGE_BLOCKING}, 0},
      {{CAER_HOST_CONFIG_DATAEXCHANGE, CAER_HOST_CONFIG_DATAEXCHANGE_START_PRODUCERS}, 1},
      {{CAER_HOST_CONFIG_DATAEXCHANGE, CAER_HOST_CONFIG_DATAEXCHANGE_STOP_PRODUCERS}, 1},
      {{CAER_HOST_CONFIG_PACKETS, CAER_HOST_CONFIG_PACKETS_MAX_CONTAINER_PACKET_SIZE}, 0},
      {{CAER_HOST_CONFIG_PACKETS, CAER_HOST_CONFIG_PACKETS_MAX_CONTAINER_INTERVAL}, 10000},
      {{CAER_HOST_CONFIG_LOG, CAER_HOST_CONFIG_LOG_LEVEL}, static_cast<std::uint32_t>(log_level)},
  };
}

// What caerDeviceSendDefaultConfig() sets on a DAVIS (the subset evpipe cares about).
std::map<ConfigKey, std::uint32_t> device_defaults(const caer_davis_info& info) {
  std::map<ConfigKey, std::uint32_t> d = {
      {{DAVIS_CONFIG_MUX, DAVIS_CONFIG_MUX_TIMESTAMP_RESET}, 0},
      {{DAVIS_CONFIG_MUX, DAVIS_CONFIG_MUX_DROP_EXTINPUT_ON_TRANSFER_STALL}, 1},
      {{DAVIS_CONFIG_MUX, DAVIS_CONFIG_MUX_DROP_DVS_ON_TRANSFER_STALL}, 1},
      {{DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_WAIT_ON_TRANSFER_STALL}, 0},
      {{DAVIS_CONFIG_APS, DAVIS_CONFIG_APS_RUN}, 1},
      {{DAVIS_CONFIG_IMU, DAVIS_CONFIG_IMU_RUN_ACCELEROMETER}, 1},
      {{DAVIS_CONFIG_IMU, DAVIS_CONFIG_IMU_RUN_GYROSCOPE}, 1},
      {{DAVIS_CONFIG_IMU, DAVIS_CONFIG_IMU_RUN_TEMPERATURE}, 1},
  };
  if (info.dvsHasBackgroundActivityFilter) {
    d[{DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_BACKGROUND_ACTIVITY}] = 1;
    d[{DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_BACKGROUND_ACTIVITY_TIME}] = 8;  // 2 ms
    d[{DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_REFRACTORY_PERIOD}] = 0;
    d[{DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_REFRACTORY_PERIOD_TIME}] = 1;  // 250 µs
  }
  return d;
}

std::map<ConfigKey, std::uint64_t> statistics_defaults() {
  std::map<ConfigKey, std::uint64_t> s;
  for (std::uint8_t p : {DAVIS_CONFIG_MUX_STATISTICS_EXTINPUT_DROPPED, DAVIS_CONFIG_MUX_STATISTICS_DVS_DROPPED}) {
    s[{DAVIS_CONFIG_MUX, p}] = 0;
  }
  for (std::uint8_t p : {DAVIS_CONFIG_DVS_STATISTICS_EVENTS_ROW, DAVIS_CONFIG_DVS_STATISTICS_EVENTS_COLUMN,
                         DAVIS_CONFIG_DVS_STATISTICS_EVENTS_DROPPED, DAVIS_CONFIG_DVS_STATISTICS_FILTERED_PIXELS,
                         DAVIS_CONFIG_DVS_STATISTICS_FILTERED_BACKGROUND_ACTIVITY,
                         DAVIS_CONFIG_DVS_STATISTICS_FILTERED_REFRACTORY_PERIOD}) {
    s[{DAVIS_CONFIG_DVS, p}] = 0;
  }
  return s;
}

bool is_power_of_two(std::uint32_t v) { return v != 0 && (v & (v - 1)) == 0; }

}  // namespace

caer_davis_info davis346_info() {
  caer_davis_info info{};
  info.deviceID = 1;
  std::snprintf(info.deviceSerialNumber, sizeof info.deviceSerialNumber, "%s", "00000346");
  info.deviceUSBBusNumber = 1;
  info.deviceUSBDeviceAddress = 4;
  info.deviceString = nullptr;
  info.firmwareVersion = 6;
  info.logicVersion = 18;
  info.chipID = DAVIS_CHIP_DAVIS346B;
  info.deviceIsMaster = true;
  info.muxHasStatistics = true;
  info.dvsSizeX = 346;
  info.dvsSizeY = 260;
  info.dvsHasPixelFilter = true;
  info.dvsHasBackgroundActivityFilter = true;
  info.dvsHasROIFilter = true;
  info.dvsHasSkipFilter = true;
  info.dvsHasPolarityFilter = true;
  info.dvsHasStatistics = true;
  info.apsSizeX = 346;
  info.apsSizeY = 260;
  info.apsColorFilter = MONO;
  info.apsHasGlobalShutter = true;
  info.imuType = IMU_BOSCH_BMI_160;
  info.extInputHasGenerator = true;
  return info;
}

// Work done after the mutex is released: log lines and user callbacks may re-enter the fake.
struct Deferred {
  struct Log {
    enum caer_log_level level;
    std::string text;
  };
  std::vector<Log> logs;
  std::vector<std::function<void()>> calls;
  std::uint8_t device_log_level = CAER_LOG_ERROR;
  std::string subsystem = "DAVIS (fake)";

  ~Deferred() {
    for (const auto& l : logs) log_now(l.level, l.text);
    for (auto& c : calls) c();
  }
  Deferred() = default;
  Deferred(const Deferred&) = delete;
  Deferred& operator=(const Deferred&) = delete;

 private:
  void log_now(enum caer_log_level level, const std::string& text) const {
    log_helper(device_log_level, level, subsystem.c_str(), "%s", text.c_str());
  }
  static void log_helper(std::uint8_t system_level, enum caer_log_level level, const char* sub, const char* fmt,
                         ...) {
    va_list args;
    va_start(args, fmt);
    caerLogVAFull(system_level, level, sub, fmt, args);
    va_end(args);
  }
};

// One lock for the whole fake (a plain global so that reset() can rebuild the state under it).
std::mutex g_mu;

struct FakeDevice::State {
  caer_davis_info info = davis346_info();
  bool plugged = true;
  int fail_opens = 0;
  int fail_errno = CAER_ERROR_OPEN_ACCESS;
  bool fail_default_config = false;
  bool fail_data_start = false;

  std::uint64_t session = 1;  // the live handle's session; bumped when a handle goes stale
  bool open = false;
  bool running = false;
  std::int16_t device_id = 1;
  std::string device_string;
  std::uint8_t device_log_level = CAER_LOG_ERROR;

  std::map<ConfigKey, std::uint32_t> config;
  std::map<ConfigKey, std::uint64_t> statistics = statistics_defaults();
  std::vector<Call> calls;

  std::deque<Item> pending;
  std::deque<caerEventPacketContainer> ring;
  std::size_t ring_capacity = 64;
  std::int64_t commit_ts = -1;  // last µs of the current container's interval; -1 = start at next event
  std::int64_t epoch = 0;       // tsOverflow of the container being built

  void (*notify_increase)(void*) = nullptr;
  void (*notify_decrease)(void*) = nullptr;
  void* notify_ptr = nullptr;
  void (*shutdown_notify)(void*) = nullptr;
  void* shutdown_ptr = nullptr;

  FakeCounters counters;

  void clear_ring() {
    for (auto* c : ring) caerEventPacketContainerFree(c);
    ring.clear();
  }

  [[nodiscard]] bool live(const caer_device_handle* h) const {
    return h != nullptr && open && plugged && h->session == session;
  }

  [[nodiscard]] std::uint32_t cfg(std::int8_t module, std::uint8_t param, std::uint32_t fallback) const {
    const auto it = config.find({module, param});
    return it == config.end() ? fallback : it->second;
  }

  void prepare_deferred(Deferred& d) const {
    d.device_log_level = device_log_level;
    d.subsystem = device_string.empty() ? "DAVIS (fake)" : device_string;
  }

  caerEventPacketContainer make_container(const Building& b) const {
    caerEventPacketContainer c = caerEventPacketContainerAllocate(kDavisSlots);
    if (c == nullptr) return nullptr;
    const auto overflow = static_cast<std::int32_t>(epoch);
    if (!b.special.empty()) {
      auto* p = caerSpecialEventPacketAllocate(capacity_for(b.special.size()), device_id, overflow);
      if (p != nullptr) {
        std::int32_t i = 0;
        for (const auto& s : b.special) {
          caerSpecialEvent e = caerSpecialEventPacketGetEvent(p, i++);
          caerSpecialEventSetTimestamp(e, s.ts);
          caerSpecialEventSetType(e, s.type);
          caerSpecialEventSetData(e, s.data);
          caerSpecialEventValidate(e, p);
        }
        caerEventPacketHeaderSetEventNumber(&p->packetHeader, i);
        caerEventPacketContainerSetEventPacket(c, SPECIAL_EVENT, &p->packetHeader);
      }
    }
    if (!b.polarity.empty()) {
      auto* p = caerPolarityEventPacketAllocate(capacity_for(b.polarity.size()), device_id, overflow);
      if (p != nullptr) {
        std::int32_t i = 0;
        for (const auto& ev : b.polarity) {
          caerPolarityEvent e = caerPolarityEventPacketGetEvent(p, i++);
          caerPolarityEventSetTimestamp(e, static_cast<std::int32_t>(ev.t_us & kTsMask));
          caerPolarityEventSetX(e, ev.x);
          caerPolarityEventSetY(e, ev.y);
          caerPolarityEventSetPolarity(e, ev.polarity);
          if (ev.valid) caerPolarityEventValidate(e, p);
        }
        caerEventPacketHeaderSetEventNumber(&p->packetHeader, i);
        caerEventPacketContainerSetEventPacket(c, POLARITY_EVENT, &p->packetHeader);
      }
    }
    return c;
  }

  caerEventPacketContainer make_reset_container() const {
    caerEventPacketContainer c = caerEventPacketContainerAllocate(1);
    if (c == nullptr) return nullptr;
    auto* p = caerSpecialEventPacketAllocate(1, device_id, 0);
    if (p == nullptr) return c;
    caerSpecialEvent e = caerSpecialEventPacketGetEvent(p, 0);
    caerSpecialEventSetTimestamp(e, kTsMask);
    caerSpecialEventSetType(e, TIMESTAMP_RESET);
    caerSpecialEventValidate(e, p);
    caerEventPacketHeaderSetEventNumber(&p->packetHeader, 1);
    caerEventPacketContainerSetEventPacket(c, SPECIAL_EVENT, &p->packetHeader);
    return c;
  }

  struct Built {
    caerEventPacketContainer container = nullptr;
    bool forced = false;  // timestamp-reset containers are never dropped
  };

  // Cuts the next container(s) from the pending queue, following libcaer's commit rules.
  std::vector<Built> build_next() {
    std::vector<Built> out;
    Building cur;
    const auto interval = static_cast<std::int64_t>(
        std::max<std::uint32_t>(1, cfg(CAER_HOST_CONFIG_PACKETS, CAER_HOST_CONFIG_PACKETS_MAX_CONTAINER_INTERVAL,
                                       10000)));
    const std::size_t max_size =
        cfg(CAER_HOST_CONFIG_PACKETS, CAER_HOST_CONFIG_PACKETS_MAX_CONTAINER_PACKET_SIZE, 0);
    auto commit = [&] {
      if (!cur.empty()) out.push_back({make_container(cur), false});
      cur = Building{};
    };
    while (!pending.empty()) {
      const Item item = pending.front();
      if (item.kind == Item::Kind::reset) {
        pending.pop_front();
        commit();
        epoch = 0;
        commit_ts = -1;
        out.push_back({make_reset_container(), true});
        return out;
      }
      const std::int64_t t = item.event.t_us;
      const std::int64_t ep = t >> 31;
      if (ep != epoch) {
        // 31-bit wrap: the old epoch's last container ends with TIMESTAMP_WRAP, then the packet
        // tsOverflow changes (a backward change only commits).
        if (ep > epoch) cur.special.push_back({kTsMask, TIMESTAMP_WRAP, 0});
        commit();
        epoch = ep;
        if (!out.empty()) return out;
      }
      if (commit_ts < 0) commit_ts = t + interval - 1;
      if (t > commit_ts) {
        commit_ts += ((t - commit_ts + interval - 1) / interval) * interval;
        if (!cur.empty()) {
          commit();
          return out;
        }
      }
      pending.pop_front();
      if (item.kind == Item::Kind::polarity) {
        cur.polarity.push_back(item.event);
      } else {
        cur.special.push_back({static_cast<std::int32_t>(t & kTsMask), item.special_type, item.special_data});
      }
      if (max_size > 0 && (cur.polarity.size() >= max_size || cur.special.size() >= max_size)) {
        commit();
        return out;
      }
    }
    commit();  // queue ran dry: deliver the partial container now
    return out;
  }

  static std::uint64_t polarity_count(caerEventPacketContainerConst c) {
    const auto* p = caerEventPacketContainerFindEventPacketByTypeConst(c, POLARITY_EVENT);
    return p == nullptr ? 0 : static_cast<std::uint64_t>(caerEventPacketHeaderGetEventNumber(p));
  }

  void put(const Built& b, Deferred& d) {
    if (b.container == nullptr) return;
    if (!b.forced && ring.size() >= ring_capacity) {
      counters.containers_dropped++;
      counters.polarity_events_dropped += polarity_count(b.container);
      caerEventPacketContainerFree(b.container);
      d.logs.push_back({CAER_LOG_NOTICE,
                        "Dropped EventPacket Container because ring-buffer full! This means your processing loop "
                        "is not keeping up with new data ready to be read from caerDeviceDataGet()."});
      return;
    }
    ring.push_back(b.container);
    if (notify_increase != nullptr) {
      auto fn = notify_increase;
      auto ptr = notify_ptr;
      d.calls.emplace_back([fn, ptr] { fn(ptr); });
    }
  }

  void record(CallKind kind, std::int8_t module = 0, std::uint8_t param = 0, std::uint32_t value = 0) {
    calls.push_back({kind, module, param, value});
  }
};

FakeDevice::State& fake_state() { return *FakeDevice::instance().state_; }

FakeDevice& FakeDevice::instance() {
  static FakeDevice device;
  return device;
}

FakeDevice::FakeDevice() : state_(std::make_unique<State>()) {}
FakeDevice::~FakeDevice() { state_->clear_ring(); }

void FakeDevice::reset() {
  std::lock_guard lock(g_mu);
  state_->clear_ring();
  const std::uint64_t next_session = state_->session + 1;  // any handle still out there goes stale
  *state_ = State{};
  state_->session = next_session;
}

void FakeDevice::set_info(const caer_davis_info& info) {
  std::lock_guard lock(g_mu);
  state_->info = info;
  state_->info.deviceString = nullptr;
}

caer_davis_info FakeDevice::info() const {
  std::lock_guard lock(g_mu);
  return state_->info;
}

void FakeDevice::queue_events(std::span<const FakeEvent> events) {
  for (const auto& e : events) {
    if (e.t_us < 0 || e.t_us >= kMaxTimeUs) {
      throw std::invalid_argument("caer_stub::FakeDevice: event t_us " + std::to_string(e.t_us) +
                                  " is outside the device clock range [0, 2^62)");
    }
    if (e.x > POLARITY_X_ADDR_MASK || e.y > POLARITY_Y_ADDR_MASK) {
      throw std::invalid_argument("caer_stub::FakeDevice: event address (" + std::to_string(e.x) + ", " +
                                  std::to_string(e.y) + ") does not fit the 15-bit x / y fields");
    }
  }
  std::lock_guard lock(g_mu);
  for (const auto& e : events) state_->pending.push_back({Item::Kind::polarity, e, 0, 0});
}

void FakeDevice::queue_event(const FakeEvent& event) { queue_events(std::span<const FakeEvent>(&event, 1)); }

void FakeDevice::queue_timestamp_reset() {
  std::lock_guard lock(g_mu);
  state_->pending.push_back({Item::Kind::reset, {}, 0, 0});
}

void FakeDevice::queue_special(std::int64_t t_us, std::uint8_t type, std::uint32_t data) {
  if (t_us < 0 || t_us >= kMaxTimeUs) {
    throw std::invalid_argument("caer_stub::FakeDevice: special event t_us outside [0, 2^62)");
  }
  std::lock_guard lock(g_mu);
  Item item{Item::Kind::special, {}, type, data};
  item.event.t_us = t_us;
  state_->pending.push_back(item);
}

std::size_t FakeDevice::produce(std::size_t max_containers) {
  Deferred d;
  std::lock_guard lock(g_mu);
  State& s = *state_;
  s.prepare_deferred(d);
  if (!s.running || !s.plugged) return 0;
  std::size_t built = 0;
  while (built < max_containers && !s.pending.empty()) {
    for (const auto& b : s.build_next()) {
      s.put(b, d);
      ++built;
    }
  }
  return built;
}

void FakeDevice::fail_next_opens(int count, int error) {
  std::lock_guard lock(g_mu);
  state_->fail_opens = count;
  state_->fail_errno = error;
}

void FakeDevice::set_send_default_config_fails(bool fails) {
  std::lock_guard lock(g_mu);
  state_->fail_default_config = fails;
}

void FakeDevice::set_data_start_fails(bool fails) {
  std::lock_guard lock(g_mu);
  state_->fail_data_start = fails;
}

void FakeDevice::unplug() {
  Deferred d;
  std::lock_guard lock(g_mu);
  State& s = *state_;
  s.prepare_deferred(d);
  if (!s.plugged) return;
  std::uint64_t lost = 0;
  for (auto* c : s.ring) lost += State::polarity_count(c);
  for (const auto& item : s.pending) lost += item.kind == Item::Kind::polarity ? 1 : 0;
  s.counters.events_lost_on_unplug += lost;
  s.clear_ring();
  s.pending.clear();
  s.plugged = false;
  if (s.running && s.shutdown_notify != nullptr) {
    auto fn = s.shutdown_notify;
    auto ptr = s.shutdown_ptr;
    s.counters.shutdown_notifications++;
    d.calls.emplace_back([fn, ptr] { fn(ptr); });
  }
  s.running = false;
  if (s.open) {
    s.open = false;
    s.session++;  // the handle the application holds is dead now
  }
  d.logs.push_back({CAER_LOG_ERROR, "Device disconnected (fake unplug): data transfers stopped."});
}

void FakeDevice::replug() {
  std::lock_guard lock(g_mu);
  state_->plugged = true;
}

void FakeDevice::set_statistic64(std::int8_t module, std::uint8_t param, std::uint64_t value) {
  std::lock_guard lock(g_mu);
  state_->statistics[{module, param}] = value;
}

bool FakeDevice::plugged() const {
  std::lock_guard lock(g_mu);
  return state_->plugged;
}

bool FakeDevice::is_open() const {
  std::lock_guard lock(g_mu);
  return state_->open;
}

bool FakeDevice::running() const {
  std::lock_guard lock(g_mu);
  return state_->running;
}

std::vector<Call> FakeDevice::calls() const {
  std::lock_guard lock(g_mu);
  return state_->calls;
}

int FakeDevice::count(CallKind kind) const {
  std::lock_guard lock(g_mu);
  return static_cast<int>(std::count_if(state_->calls.begin(), state_->calls.end(),
                                        [kind](const Call& c) { return c.kind == kind; }));
}

std::vector<ConfigSetCall> FakeDevice::config_sets() const {
  std::lock_guard lock(g_mu);
  std::vector<ConfigSetCall> out;
  for (const auto& c : state_->calls) {
    if (c.kind == CallKind::config_set) out.push_back({c.module, c.param, c.value});
  }
  return out;
}

std::optional<std::uint32_t> FakeDevice::last_config_set(std::int8_t module, std::uint8_t param) const {
  std::lock_guard lock(g_mu);
  std::optional<std::uint32_t> v;
  for (const auto& c : state_->calls) {
    if (c.kind == CallKind::config_set && c.module == module && c.param == param) v = c.value;
  }
  return v;
}

std::optional<std::uint32_t> FakeDevice::config_value(std::int8_t module, std::uint8_t param) const {
  std::lock_guard lock(g_mu);
  const auto it = state_->config.find({module, param});
  if (it == state_->config.end()) return std::nullopt;
  return it->second;
}

std::size_t FakeDevice::pending_items() const {
  std::lock_guard lock(g_mu);
  return state_->pending.size();
}

std::size_t FakeDevice::ring_containers() const {
  std::lock_guard lock(g_mu);
  return state_->ring.size();
}

FakeCounters FakeDevice::counters() const {
  std::lock_guard lock(g_mu);
  return state_->counters;
}

}  // namespace caer_stub

// ---------------------------------------------------------------------------------------------------
// The C API.

using caer_stub::CallKind;
using caer_stub::Deferred;
using caer_stub::fake_state;
using caer_stub::g_mu;

caerDeviceHandle caerDeviceOpen(uint16_t deviceID, uint16_t deviceType, uint8_t busNumberRestrict,
                                uint8_t devAddressRestrict, const char* serialNumberRestrict) {
  Deferred d;
  auto& s = fake_state();
  std::lock_guard lock(g_mu);
  auto fail = [&](int error, const char* why) -> caerDeviceHandle {
    s.record(CallKind::open_failed);
    d.device_log_level = static_cast<std::uint8_t>(caerLogLevelGet());
    d.subsystem = "DAVIS";
    d.logs.push_back({CAER_LOG_CRITICAL, std::string("Failed to open device: ") + why});
    errno = error;
    return nullptr;
  };
  if (s.fail_opens > 0) {
    s.fail_opens--;
    return fail(s.fail_errno, "scripted failure.");
  }
  if (deviceType != CAER_DEVICE_DAVIS && deviceType != CAER_DEVICE_DAVIS_FX2 && deviceType != CAER_DEVICE_DAVIS_FX3) {
    return fail(CAER_ERROR_OPEN_ACCESS, "no device of the requested type.");
  }
  if (!s.plugged) return fail(CAER_ERROR_OPEN_ACCESS, "no DAVIS device found.");
  if (busNumberRestrict != 0 && busNumberRestrict != s.info.deviceUSBBusNumber) {
    return fail(CAER_ERROR_OPEN_ACCESS, "no DAVIS device on the requested USB bus.");
  }
  if (devAddressRestrict != 0 && devAddressRestrict != s.info.deviceUSBDeviceAddress) {
    return fail(CAER_ERROR_OPEN_ACCESS, "no DAVIS device at the requested USB address.");
  }
  if (serialNumberRestrict != nullptr && serialNumberRestrict[0] != '\0' &&
      std::strncmp(serialNumberRestrict, s.info.deviceSerialNumber, sizeof s.info.deviceSerialNumber) != 0) {
    return fail(CAER_ERROR_OPEN_ACCESS, "no DAVIS device with the requested serial number.");
  }
  if (s.open) return fail(CAER_ERROR_OPEN_ACCESS, "device already in use.");

  auto* h = new (std::nothrow) caer_device_handle{};
  if (h == nullptr) return fail(CAER_ERROR_MEMORY_ALLOCATION, "out of memory.");
  s.session++;
  h->session = s.session;
  h->device_id = static_cast<std::int16_t>(deviceID);
  h->device_string = "DAVIS346 (fake) ID-" + std::to_string(deviceID) + " SN-" + s.info.deviceSerialNumber +
                     " [" + std::to_string(s.info.deviceUSBBusNumber) + ":" +
                     std::to_string(s.info.deviceUSBDeviceAddress) + "]";
  s.open = true;
  s.running = false;
  s.device_id = h->device_id;
  s.device_string = h->device_string;
  s.device_log_level = static_cast<std::uint8_t>(caerLogLevelGet());
  s.config = caer_stub::host_defaults(s.device_log_level);
  s.commit_ts = -1;
  s.epoch = 0;
  s.record(CallKind::open);
  return h;
}

bool caerDeviceClose(caerDeviceHandle* handle) {
  if (handle == nullptr || *handle == nullptr) return false;
  auto& s = fake_state();
  {
    std::lock_guard lock(g_mu);
    if ((*handle)->session == s.session && s.open) {
      s.running = false;
      s.clear_ring();
      s.open = false;
      s.session++;
      s.record(CallKind::close);
    }
  }
  delete *handle;
  *handle = nullptr;
  return true;
}

bool caerDeviceSendDefaultConfig(caerDeviceHandle handle) {
  auto& s = fake_state();
  std::lock_guard lock(g_mu);
  if (!s.live(handle) || s.fail_default_config) return false;
  for (const auto& [key, value] : caer_stub::device_defaults(s.info)) s.config[key] = value;
  s.record(CallKind::send_default_config);
  return true;
}

bool caerDeviceConfigSet(caerDeviceHandle handle, int8_t modAddr, uint8_t paramAddr, uint32_t param) {
  auto& s = fake_state();
  std::lock_guard lock(g_mu);
  if (!s.live(handle)) return false;
  s.config[{modAddr, paramAddr}] = param;
  if (modAddr == CAER_HOST_CONFIG_LOG && paramAddr == CAER_HOST_CONFIG_LOG_LEVEL) {
    s.device_log_level = static_cast<std::uint8_t>(param);
  }
  s.record(CallKind::config_set, modAddr, paramAddr, param);
  return true;
}

bool caerDeviceConfigGet(caerDeviceHandle handle, int8_t modAddr, uint8_t paramAddr, uint32_t* param) {
  if (param == nullptr) return false;
  *param = 0;
  auto& s = fake_state();
  std::lock_guard lock(g_mu);
  if (!s.live(handle)) return false;
  const auto it = s.config.find({modAddr, paramAddr});
  if (it == s.config.end()) return false;
  *param = it->second;
  return true;
}

bool caerDeviceConfigGet64(caerDeviceHandle handle, int8_t modAddr, uint8_t paramAddr, uint64_t* param) {
  if (param == nullptr) return false;
  *param = 0;
  auto& s = fake_state();
  std::lock_guard lock(g_mu);
  if (!s.live(handle)) return false;
  const auto it = s.statistics.find({modAddr, paramAddr});
  if (it == s.statistics.end()) return false;
  *param = it->second;
  return true;
}

bool caerDeviceDataStart(caerDeviceHandle handle, void (*dataNotifyIncrease)(void* ptr),
                         void (*dataNotifyDecrease)(void* ptr), void* dataNotifyUserPtr,
                         void (*dataShutdownNotify)(void* ptr), void* dataShutdownUserPtr) {
  Deferred d;
  auto& s = fake_state();
  std::lock_guard lock(g_mu);
  s.prepare_deferred(d);
  if (!s.live(handle) || s.running || s.fail_data_start) return false;
  const std::uint32_t ring_size = s.cfg(CAER_HOST_CONFIG_DATAEXCHANGE, CAER_HOST_CONFIG_DATAEXCHANGE_BUFFER_SIZE, 64);
  if (!caer_stub::is_power_of_two(ring_size)) {
    d.logs.push_back({CAER_LOG_CRITICAL, "Failed to initialize data exchange buffer (size must be a power of two)."});
    return false;
  }
  s.ring_capacity = ring_size;
  s.notify_increase = dataNotifyIncrease;
  s.notify_decrease = dataNotifyDecrease;
  s.notify_ptr = dataNotifyUserPtr;
  s.shutdown_notify = dataShutdownNotify;
  s.shutdown_ptr = dataShutdownUserPtr;
  s.commit_ts = -1;
  s.running = true;
  s.record(CallKind::data_start);
  return true;
}

bool caerDeviceDataStop(caerDeviceHandle handle) {
  if (handle == nullptr) return false;
  auto& s = fake_state();
  std::lock_guard lock(g_mu);
  if (!s.live(handle)) return true;  // a dead device has nothing left to stop
  if (s.running) {
    s.running = false;
    s.clear_ring();
    s.record(CallKind::data_stop);
  }
  return true;
}

caerEventPacketContainer caerDeviceDataGet(caerDeviceHandle handle) {
  Deferred d;
  auto& s = fake_state();
  std::lock_guard lock(g_mu);
  s.prepare_deferred(d);
  if (!s.live(handle) || !s.running) return nullptr;
  if (s.ring.empty()) {
    for (const auto& b : s.build_next()) s.put(b, d);
  }
  if (s.ring.empty()) return nullptr;
  caerEventPacketContainer c = s.ring.front();
  s.ring.pop_front();
  s.counters.containers_delivered++;
  s.counters.polarity_events_delivered += caer_stub::FakeDevice::State::polarity_count(c);
  if (s.notify_decrease != nullptr) {
    auto fn = s.notify_decrease;
    auto ptr = s.notify_ptr;
    d.calls.emplace_back([fn, ptr] { fn(ptr); });
  }
  return c;
}

struct caer_davis_info caerDavisInfoGet(caerDeviceHandle handle) {
  auto& s = fake_state();
  std::lock_guard lock(g_mu);
  if (!s.live(handle)) return caer_davis_info{};
  caer_davis_info info = s.info;
  info.deviceID = handle->device_id;
  info.deviceString = handle->device_string.data();
  return info;
}
