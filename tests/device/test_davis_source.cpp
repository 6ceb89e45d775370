// DavisSource driven by the libcaer stub's scripted fake camera (libcaer_stub/fake_device.h).

#include <gtest/gtest.h>
#include <libcaer/devices/davis.h>
#include <libcaer_stub/fake_device.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <mutex>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "evpipe/device/davis_source.hpp"
#include "evpipe/io/reader.hpp"
#include "evpipe_test_data.hpp"

static_assert(LIBCAER_IS_STUB == 1, "these tests need the libcaer stub's fake camera");

namespace evpipe::device {
namespace {

using caer_stub::CallKind;
using caer_stub::FakeDevice;
using caer_stub::FakeEvent;
using namespace std::chrono_literals;

constexpr std::int64_t kWrapUs = std::int64_t{1} << 31;  // libcaer's 31-bit timestamp range

// ---- libcaer log lines, captured process-wide ----
struct LogLine {
  LogLevel level;
  std::string text;
};
std::mutex g_log_mu;
std::vector<LogLine> g_log;

void capture_log(LogLevel level, std::string_view text) {
  std::lock_guard lock(g_log_mu);
  g_log.push_back({level, std::string(text)});
}

std::vector<LogLine> logged() {
  std::lock_guard lock(g_log_mu);
  return g_log;
}

// ---- event helpers ----
std::vector<FakeEvent> random_events(std::size_t n, std::int64_t t0_us, std::int64_t max_step_us, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> dx(0, 345);
  std::uniform_int_distribution<int> dy(0, 259);
  std::uniform_int_distribution<std::int64_t> step(0, max_step_us);  // 0: several events share a timestamp
  std::bernoulli_distribution on(0.5);
  std::vector<FakeEvent> out;
  out.reserve(n);
  std::int64_t t = t0_us;
  for (std::size_t i = 0; i < n; ++i) {
    if (i > 0) t += step(rng);
    out.push_back({t, static_cast<std::uint16_t>(dx(rng)), static_cast<std::uint16_t>(dy(rng)), on(rng), true});
  }
  return out;
}

std::vector<Event> expected_events(const std::vector<FakeEvent>& in) {
  std::vector<Event> out;
  for (const auto& e : in) {
    if (e.valid) out.push_back(Event{e.t_us, e.x, e.y, e.polarity});
  }
  return out;
}

std::vector<Event> concat(const std::vector<EventBatchPtr>& batches) {
  std::vector<Event> out;
  for (const auto& b : batches) out.insert(out.end(), b->events.begin(), b->events.end());
  return out;
}

// First mismatch as text (gtest would print 100k-element vectors otherwise).
std::string first_difference(const std::vector<Event>& got, const std::vector<Event>& want) {
  if (got.size() != want.size()) return "size " + std::to_string(got.size()) + " != " + std::to_string(want.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    if (!(got[i] == want[i])) {
      return "event " + std::to_string(i) + ": got (" + std::to_string(got[i].t_us) + ", " + std::to_string(got[i].x) +
             ", " + std::to_string(got[i].y) + ", " + std::to_string(got[i].polarity) + ") want (" +
             std::to_string(want[i].t_us) + ", " + std::to_string(want[i].x) + ", " + std::to_string(want[i].y) + ", " +
             std::to_string(want[i].polarity) + ")";
    }
  }
  return {};
}

class DavisSourceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    fake().reset();
    {
      std::lock_guard lock(g_log_mu);
      g_log.clear();
    }
    set_libcaer_log_handler(&capture_log, LogLevel::debug);
  }
  void TearDown() override { fake().reset(); }

  static FakeDevice& fake() { return FakeDevice::instance(); }

  DavisOptions options() {
    DavisOptions o;
    o.on_warning = [this](const Warning& w) { warnings.push_back(w.what); };
    o.clock = [this] { return now; };
    return o;
  }

  [[nodiscard]] bool warned(const std::string& needle) const {
    return std::any_of(warnings.begin(), warnings.end(),
                       [&](const std::string& w) { return w.find(needle) != std::string::npos; });
  }

  // Everything the camera has to give, batch by batch.
  static std::vector<EventBatchPtr> drain(DavisSource& source) {
    std::vector<EventBatchPtr> out;
    int idle = 0;  // bounded: a broken source must fail the test, not hang it
    while (idle < 1000) {
      auto batch = source.next();
      if (batch) {
        out.push_back(batch);
        idle = 0;
      } else if (fake().pending_items() == 0 && fake().ring_containers() == 0) {
        break;
      } else {
        ++idle;
      }
    }
    return out;
  }

  std::vector<std::string> warnings;
  std::chrono::steady_clock::time_point now{};
};

// ---- opening and configuration ----

TEST_F(DavisSourceTest, OpenSendsDefaultConfigThenTheOptions) {
  EXPECT_FALSE(using_real_libcaer());
  DavisSource source(options());
  EXPECT_EQ(source.state(), DeviceState::connected);
  EXPECT_FALSE(source.finished());

  const auto calls = fake().calls();
  ASSERT_GE(calls.size(), 4u);
  EXPECT_EQ(calls.front().kind, CallKind::open);
  EXPECT_EQ(calls[1].kind, CallKind::send_default_config);  // defaults first, our settings on top
  EXPECT_EQ(calls.back().kind, CallKind::data_start);
  for (std::size_t i = 2; i + 1 < calls.size(); ++i) EXPECT_EQ(calls[i].kind, CallKind::config_set) << i;

  EXPECT_EQ(fake().last_config_set(DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_BACKGROUND_ACTIVITY), 1u);
  EXPECT_EQ(fake().last_config_set(DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_BACKGROUND_ACTIVITY_TIME), 8u);  // 2000 µs
  EXPECT_EQ(fake().last_config_set(DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_REFRACTORY_PERIOD), 0u);
  EXPECT_EQ(fake().last_config_set(DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_REFRACTORY_PERIOD_TIME), 1u);  // 250 µs
  EXPECT_EQ(fake().last_config_set(DAVIS_CONFIG_APS, DAVIS_CONFIG_APS_RUN), 0u);
  EXPECT_EQ(fake().last_config_set(DAVIS_CONFIG_IMU, DAVIS_CONFIG_IMU_RUN_ACCELEROMETER), 0u);
  EXPECT_EQ(fake().last_config_set(DAVIS_CONFIG_IMU, DAVIS_CONFIG_IMU_RUN_GYROSCOPE), 0u);
  EXPECT_EQ(fake().last_config_set(DAVIS_CONFIG_IMU, DAVIS_CONFIG_IMU_RUN_TEMPERATURE), 0u);
  EXPECT_EQ(fake().last_config_set(CAER_HOST_CONFIG_PACKETS, CAER_HOST_CONFIG_PACKETS_MAX_CONTAINER_INTERVAL), 5000u);
  EXPECT_EQ(fake().last_config_set(CAER_HOST_CONFIG_PACKETS, CAER_HOST_CONFIG_PACKETS_MAX_CONTAINER_PACKET_SIZE), 0u);
  EXPECT_EQ(fake().last_config_set(CAER_HOST_CONFIG_DATAEXCHANGE, CAER_HOST_CONFIG_DATAEXCHANGE_BUFFER_SIZE), 64u);
  EXPECT_EQ(fake().last_config_set(CAER_HOST_CONFIG_DATAEXCHANGE, CAER_HOST_CONFIG_DATAEXCHANGE_BLOCKING), 0u);
  EXPECT_EQ(fake().last_config_set(CAER_HOST_CONFIG_LOG, CAER_HOST_CONFIG_LOG_LEVEL),
            static_cast<std::uint32_t>(CAER_LOG_NOTICE));
  // The device ends up with APS off although the defaults turned it on.
  EXPECT_EQ(fake().config_value(DAVIS_CONFIG_APS, DAVIS_CONFIG_APS_RUN), 0u);

  EXPECT_EQ(source.info().format, "davis-live");
  EXPECT_EQ(source.info().name, "00000346");
  EXPECT_EQ(source.info().geometry, kDavis346);
  EXPECT_TRUE(source.info().geometry_known);
  EXPECT_TRUE(source.device_info().is_davis346);
  EXPECT_EQ(source.device_info().chip_id, DAVIS_CHIP_DAVIS346B);
  EXPECT_TRUE(warnings.empty());
}

TEST_F(DavisSourceTest, FilterAndContainerOptionsAreSentInDeviceUnits) {
  auto o = options();
  o.ba_filter_enabled = false;
  o.ba_filter_time_us = 10'000;
  o.refractory_enabled = true;
  o.refractory_time_us = 1000;
  o.container_interval_us = 1000;
  o.container_max_events = 4096;
  o.data_exchange_buffer = 128;
  o.aps_enabled = true;
  DavisSource source(o);
  EXPECT_EQ(fake().last_config_set(DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_BACKGROUND_ACTIVITY), 0u);
  EXPECT_EQ(fake().last_config_set(DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_BACKGROUND_ACTIVITY_TIME), 40u);
  EXPECT_EQ(fake().last_config_set(DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_REFRACTORY_PERIOD), 1u);
  EXPECT_EQ(fake().last_config_set(DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_REFRACTORY_PERIOD_TIME), 4u);
  EXPECT_EQ(fake().last_config_set(CAER_HOST_CONFIG_PACKETS, CAER_HOST_CONFIG_PACKETS_MAX_CONTAINER_INTERVAL), 1000u);
  EXPECT_EQ(fake().last_config_set(CAER_HOST_CONFIG_PACKETS, CAER_HOST_CONFIG_PACKETS_MAX_CONTAINER_PACKET_SIZE),
            4096u);
  EXPECT_EQ(fake().last_config_set(CAER_HOST_CONFIG_DATAEXCHANGE, CAER_HOST_CONFIG_DATAEXCHANGE_BUFFER_SIZE), 128u);
  EXPECT_EQ(fake().last_config_set(DAVIS_CONFIG_APS, DAVIS_CONFIG_APS_RUN), 1u);
}

TEST_F(DavisSourceTest, BadOptionsAreRejectedBeforeTheCameraIsTouched) {
  auto o = options();
  o.ba_filter_time_us = 2100;
  try {
    DavisSource source(o);
    FAIL() << "accepted ba_filter_time_us = 2100";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("ba_filter_time_us"), std::string::npos) << e.what();
  }
  auto r = options();
  r.data_exchange_buffer = 48;
  EXPECT_THROW(DavisSource{r}, std::invalid_argument);
  EXPECT_EQ(fake().count(CallKind::open), 0);
  EXPECT_EQ(fake().count(CallKind::open_failed), 0);
}

TEST_F(DavisSourceTest, OtherCameraModelIsAcceptedWithWarnings) {
  auto info = caer_stub::davis346_info();
  info.chipID = DAVIS_CHIP_DAVIS240C;
  info.dvsSizeX = 240;
  info.dvsSizeY = 180;
  info.dvsHasBackgroundActivityFilter = false;
  fake().set_info(info);
  DavisSource source(options());
  EXPECT_EQ(source.info().geometry, kDavis240);
  EXPECT_FALSE(source.device_info().is_davis346);
  EXPECT_TRUE(warned("not a DAVIS346")) << ::testing::PrintToString(warnings);
  EXPECT_TRUE(warned("no hardware background-activity")) << ::testing::PrintToString(warnings);
  // Filter registers the chip does not have are left alone.
  EXPECT_FALSE(fake().last_config_set(DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_BACKGROUND_ACTIVITY).has_value());
  EXPECT_FALSE(fake().last_config_set(DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_BACKGROUND_ACTIVITY_TIME).has_value());
  // ...and events outside its 240x180 array are not pixels.
  fake().queue_events(
      std::vector<FakeEvent>{{10, 239, 179, true, true}, {20, 240, 10, true, true}, {30, 5, 180, false, true}});
  const auto got = concat(drain(source));
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0], (Event{10, 239, 179, true}));
  EXPECT_EQ(source.stats().invalid_events, 2u);
}

// ---- open failures ----

TEST_F(DavisSourceTest, OpenFailureThrowsSourceErrorWithTheCause) {
  fake().fail_next_opens(1, CAER_ERROR_OPEN_ACCESS);
  try {
    DavisSource source(options());
    FAIL() << "opened although the camera could not be opened";
  } catch (const SourceError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("no DAVIS camera found or access denied"), std::string::npos) << m;
    EXPECT_NE(m.find("CAER_ERROR_OPEN_ACCESS"), std::string::npos) << m;
    EXPECT_NE(m.find("udev"), std::string::npos) << m;
  }
  EXPECT_EQ(fake().count(CallKind::open_failed), 1);
  // The failure was one-off: the next attempt opens.
  DavisSource ok(options());
  EXPECT_EQ(ok.state(), DeviceState::connected);
}

TEST_F(DavisSourceTest, OpenFailureReasonsAreSpecific) {
  fake().fail_next_opens(1, CAER_ERROR_FW_VERSION);
  try {
    DavisSource source(options());
    FAIL();
  } catch (const SourceError& e) {
    EXPECT_NE(std::string(e.what()).find("firmware"), std::string::npos) << e.what();
  }
  auto o = options();
  o.serial_number = "12345678";
  try {
    DavisSource source(o);
    FAIL();
  } catch (const SourceError& e) {
    EXPECT_NE(std::string(e.what()).find("serial number 12345678"), std::string::npos) << e.what();
  }
  fake().unplug();
  EXPECT_THROW(DavisSource{options()}, SourceError);
}

TEST_F(DavisSourceTest, ConfigurationFailuresCloseTheCamera) {
  fake().set_send_default_config_fails(true);
  try {
    DavisSource source(options());
    FAIL();
  } catch (const SourceError& e) {
    EXPECT_NE(std::string(e.what()).find("default configuration"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fake().is_open());
  fake().set_send_default_config_fails(false);
  fake().set_data_start_fails(true);
  try {
    DavisSource source(options());
    FAIL();
  } catch (const SourceError& e) {
    EXPECT_NE(std::string(e.what()).find("starting the data transfer"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fake().is_open());
}

// ---- the event stream ----

TEST_F(DavisSourceTest, DeliversTheQueuedEventsExactly) {
  const auto queued = random_events(10'000, 1'000, 20, 7);  // ~100 ms
  fake().queue_events(queued);
  DavisSource source(options());
  const auto batches = drain(source);
  EXPECT_EQ(first_difference(concat(batches), expected_events(queued)), "");
  // One batch per 5 ms container on a grid starting at the first event.
  std::set<std::int64_t> bins;
  for (const auto& e : queued) bins.insert((e.t_us - queued.front().t_us) / 5000);
  EXPECT_EQ(batches.size(), bins.size());
  for (const auto& b : batches) {
    EXPECT_FALSE(b->discontinuity_before);
    EXPECT_LT(b->events.back().t_us - b->events.front().t_us, 5000);
  }
  EXPECT_EQ(source.stats().events, 10'000u);
  EXPECT_EQ(source.stats().batches, batches.size());
  EXPECT_EQ(source.stats().discontinuities, 0u);
  EXPECT_EQ(source.stats().invalid_events, 0u);
  EXPECT_GT(source.stats().bytes_read, 10'000u * 8u);
  EXPECT_EQ(source.next(), nullptr);  // nothing new: not an error, not finished
  EXPECT_FALSE(source.finished());
}

TEST_F(DavisSourceTest, TimestampsSurviveThe31BitOverflow) {
  std::vector<FakeEvent> queued;
  for (int i = 0; i < 2000; ++i) {
    queued.push_back({kWrapUs - 10'000 + i * 10, static_cast<std::uint16_t>(i % 346),
                      static_cast<std::uint16_t>(i % 260), i % 3 == 0, true});
  }
  for (int i = 0; i < 10; ++i) queued.push_back({3 * kWrapUs + i, 1, 2, true, true});  // jump two epochs
  queued.push_back({5 * kWrapUs + 12345, 345, 259, false, true});
  fake().queue_events(queued);
  DavisSource source(options());
  const auto batches = drain(source);
  EXPECT_EQ(first_difference(concat(batches), expected_events(queued)), "");
  for (const auto& b : batches) {  // a packet has one tsOverflow
    EXPECT_EQ(b->events.front().t_us >> 31, b->events.back().t_us >> 31);
  }
  EXPECT_EQ(source.stats().skipped_non_dvs, 3u);  // one TIMESTAMP_WRAP per forward epoch change
  EXPECT_EQ(source.stats().discontinuities, 0u);
}

TEST_F(DavisSourceTest, RecordingLongerThan2To31Microseconds) {
  std::vector<FakeEvent> queued;
  for (int i = 0; i < 2400; ++i) {  // one event a second for 40 min > 2^31 µs (35.8 min)
    queued.push_back({std::int64_t{i} * 1'000'000, static_cast<std::uint16_t>(i % 346), 7, i % 2 == 0, true});
  }
  fake().queue_events(queued);
  DavisSource source(options());
  const auto batches = drain(source);
  EXPECT_EQ(batches.size(), 2400u);
  EXPECT_EQ(first_difference(concat(batches), expected_events(queued)), "");
  EXPECT_EQ(source.stats().skipped_non_dvs, 1u);
}

TEST_F(DavisSourceTest, InvalidEventsAreSkippedAndCounted) {
  auto queued = random_events(700, 0, 30, 11);
  std::uint64_t invalid = 0;
  for (std::size_t i = 0; i < queued.size(); i += 7) {
    queued[i].valid = false;
    ++invalid;
  }
  fake().queue_events(queued);
  DavisSource source(options());
  EXPECT_EQ(first_difference(concat(drain(source)), expected_events(queued)), "");
  EXPECT_EQ(source.stats().invalid_events, invalid);
  EXPECT_EQ(source.stats().events, queued.size() - invalid);
}

TEST_F(DavisSourceTest, TimestampResetFlagsTheNextBatch) {
  const auto before = random_events(100, 1'000, 500, 1);  // ~50 ms
  const auto after = random_events(50, 100, 300, 2);      // device time restarted
  fake().queue_events(before);
  fake().queue_timestamp_reset();
  fake().queue_events(after);
  DavisSource source(options());
  const auto batches = drain(source);

  auto want = expected_events(before);
  const auto want_after = expected_events(after);
  want.insert(want.end(), want_after.begin(), want_after.end());
  EXPECT_EQ(first_difference(concat(batches), want), "");

  int flagged = 0;
  for (const auto& b : batches) {
    if (b->discontinuity_before) {
      ++flagged;
      EXPECT_EQ(b->events.front(), want_after.front());  // the flag applies from the first event after the reset
    }
  }
  EXPECT_EQ(flagged, 1);
  EXPECT_EQ(source.stats().discontinuities, 1u);
  EXPECT_EQ(source.stats().skipped_non_dvs, 1u);  // the TIMESTAMP_RESET special event
  EXPECT_EQ(source.stats().out_of_order, 0u);
}

TEST_F(DavisSourceTest, BackwardTimeWithoutResetIsDisorderOrDiscontinuity) {
  // Small step back: dropped and counted. Large jump back (> discontinuity_us, here 1 s): new time base,
  // and the batch is split so the flag applies from the jump on.
  fake().queue_events(std::vector<FakeEvent>{{3'000'000, 1, 1, true, true},
                                             {3'000'100, 2, 1, true, true},
                                             {3'000'090, 3, 1, true, true},  // 10 µs back: out of order
                                             {3'000'200, 4, 1, true, true},
                                             {50, 5, 1, true, true},  // 3 s back
                                             {60, 6, 1, true, true}});
  DavisSource source(options());
  const auto batches = drain(source);
  ASSERT_EQ(batches.size(), 2u);
  EXPECT_FALSE(batches[0]->discontinuity_before);
  ASSERT_EQ(batches[0]->size(), 3u);
  EXPECT_EQ(batches[0]->events[2].x, 4);
  EXPECT_TRUE(batches[1]->discontinuity_before);
  ASSERT_EQ(batches[1]->size(), 2u);
  EXPECT_EQ(batches[1]->events[0], (Event{50, 5, 1, true}));
  EXPECT_EQ(source.stats().out_of_order, 1u);
  EXPECT_EQ(source.stats().discontinuities, 1u);
}

TEST_F(DavisSourceTest, SpecialEventsAreSkipped) {
  fake().queue_events(std::vector<FakeEvent>{{100, 1, 1, true, true}});
  fake().queue_special(150, EXTERNAL_INPUT_RISING_EDGE, 3);
  fake().queue_events(std::vector<FakeEvent>{{200, 2, 2, false, true}});
  DavisSource source(options());
  const auto got = concat(drain(source));
  ASSERT_EQ(got.size(), 2u);
  EXPECT_EQ(got[1], (Event{200, 2, 2, false}));
  EXPECT_EQ(source.stats().skipped_non_dvs, 1u);
  EXPECT_EQ(source.stats().discontinuities, 0u);
}

TEST_F(DavisSourceTest, ContainerSizeLimitCutsBatches) {
  auto o = options();
  o.container_max_events = 100;
  std::vector<FakeEvent> queued;
  for (int i = 0; i < 1000; ++i) queued.push_back({i / 2, static_cast<std::uint16_t>(i % 346), 0, true, true});
  fake().queue_events(queued);
  DavisSource source(o);
  const auto batches = drain(source);
  ASSERT_EQ(batches.size(), 10u);
  for (const auto& b : batches) EXPECT_EQ(b->size(), 100u);
  EXPECT_EQ(first_difference(concat(batches), expected_events(queued)), "");
}

TEST_F(DavisSourceTest, RecordingLikeStreamIsDeliveredIntact) {
  const auto queued = random_events(100'000, 5'000'000, 40, 2024);  // ~2 s at 50 k ev/s
  ASSERT_GT(queued.back().t_us - queued.front().t_us, 1'900'000);
  fake().queue_events(queued);
  DavisSource source(options());
  const auto batches = drain(source);
  EXPECT_EQ(first_difference(concat(batches), expected_events(queued)), "");
  EXPECT_EQ(source.stats().events, 100'000u);
  EXPECT_GE(batches.size(), 380u);  // ~2 s / 5 ms
  EXPECT_LE(batches.size(), 420u);
}

// ---- drops and statistics ----

TEST_F(DavisSourceTest, CameraDropCounterIsReadPeriodically) {
  fake().set_statistic64(DAVIS_CONFIG_MUX, DAVIS_CONFIG_MUX_STATISTICS_DVS_DROPPED, 10);  // before we opened
  DavisSource source(options());
  fake().set_statistic64(DAVIS_CONFIG_MUX, DAVIS_CONFIG_MUX_STATISTICS_DVS_DROPPED, 110);
  EXPECT_EQ(source.next(), nullptr);
  EXPECT_EQ(source.stats().dropped_events, 0u);  // not due yet (statistics_interval_ms = 1000)
  now += 1000ms;
  EXPECT_EQ(source.next(), nullptr);
  EXPECT_EQ(source.stats().dropped_events, 100u);
}

TEST_F(DavisSourceTest, RingOverflowDropsNewestContainersAndIsCounted) {
  auto o = options();
  o.data_exchange_buffer = 4;
  o.container_interval_us = 1000;
  std::vector<FakeEvent> queued;
  for (int i = 0; i < 20; ++i) queued.push_back({i * 2000, static_cast<std::uint16_t>(i), 3, true, true});
  fake().queue_events(queued);
  DavisSource source(o);
  EXPECT_EQ(fake().produce(), 20u);  // the consumer fell behind: 20 containers for a ring of 4
  EXPECT_EQ(fake().ring_containers(), 4u);
  const auto batches = drain(source);
  ASSERT_EQ(batches.size(), 4u);
  EXPECT_EQ(batches.back()->events.front().t_us, 3 * 2000);  // the oldest four survive
  EXPECT_EQ(fake().counters().containers_dropped, 16u);
  EXPECT_EQ(source.stats().dropped_packets, 16u);
  const auto lines = logged();
  EXPECT_TRUE(std::any_of(lines.begin(), lines.end(), [](const LogLine& l) {
    return l.level == LogLevel::notice && l.text.find("ring-buffer full") != std::string::npos;
  }));
}

TEST_F(DavisSourceTest, LogLinesAreRoutedWithTheirLevel) {
  DavisSource source(options());
  fake().unplug();  // the fake logs an ERROR about the lost device
  (void)source.next();
  const auto lines = logged();
  const auto it = std::find_if(lines.begin(), lines.end(),
                               [](const LogLine& l) { return l.text.find("disconnected") != std::string::npos; });
  ASSERT_NE(it, lines.end());
  EXPECT_EQ(it->level, LogLevel::error);
  EXPECT_EQ(it->text.find("(TZ"), std::string::npos) << it->text;  // time prefix stripped
  EXPECT_NE(it->text.back(), '\n');
  EXPECT_NE(it->text.find("SN-00000346"), std::string::npos) << it->text;  // subsystem kept

  // Lines above the handler's level are not forwarded.
  set_libcaer_log_handler(&capture_log, LogLevel::critical);
  {
    std::lock_guard lock(g_log_mu);
    g_log.clear();
  }
  caerLog(CAER_LOG_WARNING, "test", "not forwarded %d", 1);
  caerLog(CAER_LOG_CRITICAL, "test", "forwarded %d", 2);
  const auto filtered = logged();
  ASSERT_EQ(filtered.size(), 1u);
  EXPECT_EQ(filtered[0].level, LogLevel::critical);
  EXPECT_EQ(filtered[0].text, "test: forwarded 2");
}

// set_libcaer_log_level (evpipe's --log-level) sets libcaer's global level and the handler's filter.
TEST_F(DavisSourceTest, SetLogLevelReachesLibcaer) {
  set_libcaer_log_handler(&capture_log, LogLevel::notice);
  set_libcaer_log_level(LogLevel::debug);
  EXPECT_EQ(caerLogLevelGet(), CAER_LOG_DEBUG);
  {
    std::lock_guard lock(g_log_mu);
    g_log.clear();
  }
  caerLog(CAER_LOG_DEBUG, "test", "debug line");
  ASSERT_EQ(logged().size(), 1u);
  EXPECT_EQ(logged()[0].level, LogLevel::debug);

  set_libcaer_log_level(LogLevel::warning);
  EXPECT_EQ(caerLogLevelGet(), CAER_LOG_WARNING);
  caerLog(CAER_LOG_INFO, "test", "info line, filtered");
  EXPECT_EQ(logged().size(), 1u);
  set_libcaer_log_level(LogLevel::notice);
}

// ---- unplug / replug ----

TEST_F(DavisSourceTest, UnplugDisconnectsWithoutCrashing) {
  fake().queue_events(random_events(200, 0, 100, 3));  // ~4 containers
  DavisSource source(options());
  ASSERT_NE(source.next(), nullptr);
  fake().unplug();
  EXPECT_EQ(fake().counters().shutdown_notifications, 1u);  // libcaer's dataShutdownNotify fired

  EXPECT_EQ(source.next(), nullptr);
  EXPECT_EQ(source.state(), DeviceState::disconnected);
  EXPECT_FALSE(source.finished());
  EXPECT_TRUE(warned("disconnected")) << ::testing::PrintToString(warnings);
  for (int i = 0; i < 10; ++i) EXPECT_EQ(source.next(), nullptr);
  EXPECT_EQ(fake().count(CallKind::open_failed), 0);  // no retry before reconnect_interval_ms

  EXPECT_FALSE(source.try_reconnect());  // still unplugged
  EXPECT_EQ(fake().count(CallKind::open_failed), 1);
  EXPECT_EQ(source.state(), DeviceState::disconnected);
  EXPECT_TRUE(warned("still retrying every 1000 ms")) << ::testing::PrintToString(warnings);
  EXPECT_EQ(source.reconnects(), 0u);
}

TEST_F(DavisSourceTest, ReplugReconnectsAndFlagsTheDiscontinuity) {
  const auto first = random_events(300, 0, 50, 4);
  fake().queue_events(first);
  DavisSource source(options());
  const auto before = drain(source);
  EXPECT_EQ(first_difference(concat(before), expected_events(first)), "");

  fake().unplug();
  EXPECT_EQ(source.next(), nullptr);
  EXPECT_EQ(source.state(), DeviceState::disconnected);
  fake().replug();
  const auto second = random_events(300, 0, 50, 5);  // device time starts again near 0
  fake().queue_events(second);

  EXPECT_TRUE(source.try_reconnect());
  EXPECT_EQ(source.state(), DeviceState::connected);
  EXPECT_EQ(source.reconnects(), 1u);
  EXPECT_EQ(fake().count(CallKind::send_default_config), 2);  // fully configured again
  EXPECT_EQ(fake().count(CallKind::data_start), 2);
  EXPECT_EQ(fake().last_config_set(DAVIS_CONFIG_DVS, DAVIS_CONFIG_DVS_FILTER_BACKGROUND_ACTIVITY_TIME), 8u);

  const auto after = drain(source);
  ASSERT_FALSE(after.empty());
  EXPECT_TRUE(after.front()->discontinuity_before);
  for (std::size_t i = 1; i < after.size(); ++i) EXPECT_FALSE(after[i]->discontinuity_before);
  EXPECT_EQ(first_difference(concat(after), expected_events(second)), "");
  EXPECT_EQ(source.stats().discontinuities, 1u);
  EXPECT_EQ(source.stats().events, 600u);
}

TEST_F(DavisSourceTest, ReconnectIsAttemptedAtMostEveryInterval) {
  DavisSource source(options());
  fake().unplug();
  EXPECT_EQ(source.next(), nullptr);  // notices the loss at t = 0
  fake().replug();
  fake().queue_events(std::vector<FakeEvent>{{10, 1, 2, true, true}});
  now += 500ms;
  EXPECT_EQ(source.next(), nullptr);
  EXPECT_EQ(fake().count(CallKind::open), 1);  // not yet
  now += 500ms;
  const auto batch = source.next();  // reopens and delivers at once
  ASSERT_NE(batch, nullptr);
  EXPECT_TRUE(batch->discontinuity_before);
  EXPECT_EQ(batch->events.at(0), (Event{10, 1, 2, true}));
  EXPECT_EQ(fake().count(CallKind::open), 2);
  EXPECT_EQ(source.state(), DeviceState::connected);
}

TEST_F(DavisSourceTest, ReconnectRefusesACameraWithAnotherGeometry) {
  DavisSource source(options());
  fake().unplug();
  (void)source.next();
  auto info = caer_stub::davis346_info();
  info.chipID = DAVIS_CHIP_DAVIS240C;
  info.dvsSizeX = 240;
  info.dvsSizeY = 180;
  fake().set_info(info);
  fake().replug();
  EXPECT_FALSE(source.try_reconnect());
  EXPECT_EQ(source.state(), DeviceState::disconnected);
  EXPECT_FALSE(fake().is_open());
  EXPECT_TRUE(warned("240x180")) << ::testing::PrintToString(warnings);
}

// ---- closing ----

TEST_F(DavisSourceTest, CloseStopsAndClosesOnce) {
  fake().queue_events(random_events(100, 0, 100, 6));
  DavisSource source(options());
  source.close();
  EXPECT_TRUE(source.finished());
  EXPECT_EQ(source.state(), DeviceState::closed);
  EXPECT_EQ(source.next(), nullptr);
  EXPECT_FALSE(source.try_reconnect());
  source.close();
  EXPECT_EQ(fake().count(CallKind::data_stop), 1);
  EXPECT_EQ(fake().count(CallKind::close), 1);
  EXPECT_FALSE(fake().is_open());
}

TEST_F(DavisSourceTest, DestructorClosesTheCamera) {
  {
    DavisSource source(options());
    EXPECT_TRUE(fake().is_open());
    EXPECT_TRUE(fake().running());
  }
  EXPECT_FALSE(fake().is_open());
  EXPECT_EQ(fake().count(CallKind::data_stop), 1);
  EXPECT_EQ(fake().count(CallKind::close), 1);
  DavisSource again(options());  // the camera is free again
  EXPECT_EQ(again.state(), DeviceState::connected);
}

// ---- a real recording through the fake camera ----

// Needs the AEDAT 4.0 reader (libs/io) and ../shared/data/real; skips when the recording is absent.
TEST_F(DavisSourceTest, RealRecordingDavis346FaeryThroughTheFakeCamera) {
  EVPIPE_REQUIRE_REAL(path, "davis346-faery/davis346.aedat4");
  io::ReaderOptions ro;
  ro.out_of_order = io::OutOfOrderPolicy::keep;  // feed the camera exactly what was recorded
  const EventBatch recording = io::read_all(path, ro);
  ASSERT_EQ(recording.size(), 78'830u) << "formats.md §10.1";
  std::vector<FakeEvent> queued;
  queued.reserve(recording.size());
  for (const auto& e : recording.events) queued.push_back({e.t_us, e.x, e.y, e.polarity, true});
  fake().queue_events(queued);

  DavisSource source(options());
  const auto batches = drain(source);
  EXPECT_EQ(first_difference(concat(batches), recording.events), "");
  EXPECT_EQ(source.stats().events, 78'830u);
  EXPECT_EQ(source.stats().discontinuities, 0u);
  // Unix-µs timestamps: tsOverflow ~740 000, so every packet went through the 62-bit path.
  EXPECT_GT(recording.events.front().t_us >> 31, 700'000);
}

}  // namespace
}  // namespace evpipe::device
