// DavisOptions checks: need no camera (built against the real libcaer too).

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>

#include "evpipe/device/davis_source.hpp"

namespace evpipe::device {
namespace {

// Expects validate() to throw std::invalid_argument whose message names `field`.
void expect_rejected(const DavisOptions& o, const std::string& field) {
  try {
    validate(o);
    ADD_FAILURE() << "options with a bad " << field << " were accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(field), std::string::npos) << e.what();
  }
}

TEST(DavisOptions, DefaultsAreValid) {
  const DavisOptions o;
  EXPECT_NO_THROW(validate(o));
  EXPECT_TRUE(o.ba_filter_enabled);
  EXPECT_EQ(o.ba_filter_time_us, 2000);
  EXPECT_FALSE(o.refractory_enabled);
  EXPECT_EQ(o.refractory_time_us, 250);
  EXPECT_EQ(o.container_interval_us, 5000);
  EXPECT_EQ(o.data_exchange_buffer, 64);
  EXPECT_EQ(o.reconnect_interval_ms, 1000);
  EXPECT_FALSE(o.aps_enabled);
  EXPECT_FALSE(o.imu_enabled);
}

TEST(DavisOptions, FilterTimesConvertTo250usUnits) {
  EXPECT_EQ(filter_time_units(0, "ba_filter_time_us"), 0u);
  EXPECT_EQ(filter_time_units(250, "ba_filter_time_us"), 1u);
  EXPECT_EQ(filter_time_units(2000, "ba_filter_time_us"), 8u);
  EXPECT_EQ(filter_time_units(4095 * 250, "ba_filter_time_us"), 4095u);
}

TEST(DavisOptions, BadFilterTimesNameTheField) {
  DavisOptions o;
  o.ba_filter_time_us = 2100;  // not a multiple of 250
  expect_rejected(o, "ba_filter_time_us");
  o.ba_filter_time_us = -250;
  expect_rejected(o, "ba_filter_time_us");
  o.ba_filter_time_us = 4096 * 250;
  expect_rejected(o, "ba_filter_time_us");

  DavisOptions r;
  r.refractory_time_us = 100;
  expect_rejected(r, "refractory_time_us");
  r.refractory_time_us = 5'000'000;
  expect_rejected(r, "refractory_time_us");
}

TEST(DavisOptions, NonMultipleMessageSuggestsNeighbours) {
  try {
    (void)filter_time_units(2100, "ba_filter_time_us");
    FAIL() << "2100 µs accepted";
  } catch (const std::invalid_argument& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("2000"), std::string::npos) << m;
    EXPECT_NE(m.find("2250"), std::string::npos) << m;
  }
}

TEST(DavisOptions, OtherRangesNameTheField) {
  {
    DavisOptions o;
    o.container_interval_us = 0;
    expect_rejected(o, "container_interval_us");
    o.container_interval_us = 2'000'000;
    expect_rejected(o, "container_interval_us");
  }
  {
    DavisOptions o;
    o.container_max_events = -1;
    expect_rejected(o, "container_max_events");
  }
  {
    DavisOptions o;
    o.data_exchange_buffer = 100;  // libcaer's ring needs a power of two
    expect_rejected(o, "data_exchange_buffer");
    o.data_exchange_buffer = 0;
    expect_rejected(o, "data_exchange_buffer");
    o.data_exchange_buffer = 131072;
    expect_rejected(o, "data_exchange_buffer");
  }
  {
    DavisOptions o;
    o.reconnect_interval_ms = -1;
    expect_rejected(o, "reconnect_interval_ms");
  }
  {
    DavisOptions o;
    o.statistics_interval_ms = -5;
    expect_rejected(o, "statistics_interval_ms");
  }
  {
    DavisOptions o;
    o.discontinuity_us = 0;
    expect_rejected(o, "discontinuity_us");
  }
  {
    DavisOptions o;
    o.serial_number = "123456789";  // 9 characters
    expect_rejected(o, "serial_number");
  }
  {
    DavisOptions o;
    o.libcaer_log_level = static_cast<LogLevel>(9);
    expect_rejected(o, "libcaer_log_level");
  }
}

TEST(DavisOptions, Names) {
  EXPECT_EQ(state_name(DeviceState::connected), "connected");
  EXPECT_EQ(state_name(DeviceState::disconnected), "disconnected");
  EXPECT_EQ(state_name(DeviceState::closed), "closed");
  EXPECT_EQ(log_level_name(LogLevel::notice), "notice");
  EXPECT_EQ(log_level_name(LogLevel::error), "error");
}

// --log-level / log.level names (spdlog's) map onto libcaer's syslog levels.
TEST(DavisOptions, LogLevelFromTheApplicationsName) {
  EXPECT_EQ(log_level_from_name("trace"), LogLevel::debug);
  EXPECT_EQ(log_level_from_name("debug"), LogLevel::debug);
  EXPECT_EQ(log_level_from_name("info"), LogLevel::info);
  EXPECT_EQ(log_level_from_name("warn"), LogLevel::warning);
  EXPECT_EQ(log_level_from_name("warning"), LogLevel::warning);
  EXPECT_EQ(log_level_from_name("error"), LogLevel::error);
  EXPECT_EQ(log_level_from_name("err"), LogLevel::error);
  EXPECT_EQ(log_level_from_name("critical"), LogLevel::critical);
  EXPECT_EQ(log_level_from_name("off"), LogLevel::emergency);
  EXPECT_EQ(log_level_from_name("bogus"), LogLevel::notice);
}

// evpipe --version's libcaer line: the compiled-against version, or the stub's statement.
TEST(DavisOptions, LibcaerVersionSaysWhichLibcaer) {
  const std::string v(libcaer_version());
  if (using_real_libcaer()) {
    EXPECT_TRUE(!v.empty() && v.find_first_not_of("0123456789.") == std::string::npos) << v;
  } else {
    EXPECT_EQ(v, "stub: no camera support");
  }
}

}  // namespace
}  // namespace evpipe::device
