#pragma once
// The scripted fake DAVIS behind evpipe's libcaer stub (tests only; absent when building against the
// real libcaer, check LIBCAER_IS_STUB).
//
// There is one fake camera per process (FakeDevice::instance()). caerDeviceOpen() opens it,
// caerDeviceConfigSet() is recorded, and caerDeviceDataGet() delivers the events a test queued, cut into
// packet containers the way libcaer cuts them:
//   * a container covers at most CAER_HOST_CONFIG_PACKETS_MAX_CONTAINER_INTERVAL µs (default 10 000) on a
//     fixed grid that starts at the first event, and is cut early when a packet reaches
//     ..._MAX_CONTAINER_PACKET_SIZE events (0 = off);
//   * timestamps are 31-bit with the high part in the packet's tsOverflow (t_us >> 31): events of two
//     overflow epochs never share a container, and crossing into the next epoch appends a TIMESTAMP_WRAP
//     special event (timestamp INT32_MAX) to the last container of the old epoch;
//   * queue_timestamp_reset() commits the current container, then delivers a container holding only a
//     TIMESTAMP_RESET special event (timestamp INT32_MAX, tsOverflow 0); events queued after it carry
//     device time since the reset;
//   * slots: 0 special, 1 polarity, 2 frame, 3 IMU6 (unused slots are NULL); packets have spare capacity
//     (eventCapacity > eventNumber), as libcaer's do.
// Containers are built on demand: caerDeviceDataGet() builds the next one when the ring is empty, so no
// thread is involved and a test is deterministic. When the queue runs dry the partial container is
// delivered at once (a real device would wait for the interval to end). produce() instead fills the ring
// ahead of the consumer, like libcaer's USB thread, and drops the newest container when the ring
// (CAER_HOST_CONFIG_DATAEXCHANGE_BUFFER_SIZE, default 64) is full, with libcaer's NOTICE log line.

#include <libcaer/devices/davis.h>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace caer_stub {

/// One polarity event as the fake camera will deliver it.
struct FakeEvent {
  std::int64_t t_us = 0;  ///< device time since the last timestamp reset, 0 <= t_us < 2^62
  std::uint16_t x = 0;    ///< 0..32767 (15-bit field)
  std::uint16_t y = 0;    ///< 0..32767
  bool polarity = false;  ///< true = ON
  bool valid = true;      ///< false: delivered with the valid bit cleared
};

enum class CallKind { open, open_failed, send_default_config, config_set, data_start, data_stop, close };

/// One API call the fake received (config_set carries module / param / value).
struct Call {
  CallKind kind = CallKind::open;
  std::int8_t module = 0;
  std::uint8_t param = 0;
  std::uint32_t value = 0;
};

struct ConfigSetCall {
  std::int8_t module = 0;
  std::uint8_t param = 0;
  std::uint32_t value = 0;
  friend bool operator==(const ConfigSetCall&, const ConfigSetCall&) = default;
};

struct FakeCounters {
  std::uint64_t containers_delivered = 0;   ///< returned by caerDeviceDataGet()
  std::uint64_t polarity_events_delivered = 0;  ///< polarity events in those (valid or not)
  std::uint64_t containers_dropped = 0;     ///< ring full in produce()
  std::uint64_t polarity_events_dropped = 0;
  std::uint64_t events_lost_on_unplug = 0;  ///< queued or ringed events discarded by unplug()
  std::uint64_t shutdown_notifications = 0; ///< dataShutdownNotify calls
};

/// The default identity: a DAVIS346B, 346x260, serial "00000346", firmware 6 / logic 18, BA filter and
/// statistics present, IMU Bosch BMI160.
caer_davis_info davis346_info();

class FakeDevice {
 public:
  static FakeDevice& instance();

  /// Back to a freshly plugged DAVIS346 with nothing queued, nothing recorded and defaults restored.
  /// A handle still open from before becomes stale (its calls fail; caerDeviceClose() frees it).
  void reset();

  // ---- identity ----
  void set_info(const caer_davis_info& info);  ///< deviceString and deviceID are ignored
  [[nodiscard]] caer_davis_info info() const;

  // ---- the event stream ----
  /// Throws std::invalid_argument for t_us outside [0, 2^62) or x / y above 32767.
  void queue_events(std::span<const FakeEvent> events);
  void queue_event(const FakeEvent& event);
  /// The device timestamp is reset here (see the header comment).
  void queue_timestamp_reset();
  /// Any other special event (e.g. EXTERNAL_INPUT_RISING_EDGE), delivered in the special packet.
  void queue_special(std::int64_t t_us, std::uint8_t type, std::uint32_t data = 0);
  /// Builds up to max_containers containers into the ring now (data must be started); returns how many
  /// were built, dropped ones included.
  std::size_t produce(std::size_t max_containers = std::numeric_limits<std::size_t>::max());

  // ---- failures ----
  /// The next `count` caerDeviceOpen() calls fail with errno = error.
  void fail_next_opens(int count, int error = CAER_ERROR_OPEN_ACCESS);
  void set_send_default_config_fails(bool fails);
  void set_data_start_fails(bool fails);
  /// Cable pulled: queued and ringed data are lost, data transfers stop, dataShutdownNotify fires (on the
  /// calling thread), the open handle goes stale (DataGet returns NULL, config calls fail), and
  /// caerDeviceOpen() fails with CAER_ERROR_OPEN_ACCESS until replug().
  void unplug();
  void replug();
  /// Value returned by caerDeviceConfigGet64() (e.g. DAVIS_CONFIG_MUX_STATISTICS_DVS_DROPPED).
  void set_statistic64(std::int8_t module, std::uint8_t param, std::uint64_t value);

  // ---- inspection ----
  [[nodiscard]] bool plugged() const;
  [[nodiscard]] bool is_open() const;
  [[nodiscard]] bool running() const;
  [[nodiscard]] std::vector<Call> calls() const;
  [[nodiscard]] int count(CallKind kind) const;
  /// caerDeviceConfigSet() calls accepted since reset(), in order (all sessions).
  [[nodiscard]] std::vector<ConfigSetCall> config_sets() const;
  /// The last value set for (module, param) since reset(), if any.
  [[nodiscard]] std::optional<std::uint32_t> last_config_set(std::int8_t module, std::uint8_t param) const;
  /// The device's current value (host defaults after open, device defaults after
  /// caerDeviceSendDefaultConfig(), then every set), if known.
  [[nodiscard]] std::optional<std::uint32_t> config_value(std::int8_t module, std::uint8_t param) const;
  [[nodiscard]] std::size_t pending_items() const;  ///< queued events / markers not yet in a container
  [[nodiscard]] std::size_t ring_containers() const;
  [[nodiscard]] FakeCounters counters() const;

  struct State;  // implementation (libcaer_stub.cpp)

 private:
  FakeDevice();
  ~FakeDevice();
  std::unique_ptr<State> state_;
  friend State& fake_state();
};

}  // namespace caer_stub
