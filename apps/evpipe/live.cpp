#include "live.hpp"

#include <spdlog/spdlog.h>

#include "evpipe/device/davis_source.hpp"

namespace evpipe::app {

bool live_camera_supported() {
  return device::using_real_libcaer();
}

std::string libcaer_version_line() {
  return "libcaer: " + std::string(device::libcaer_version());
}

void set_libcaer_log_level(const std::string& log_level) {
  device::set_libcaer_log_level(device::log_level_from_name(log_level));
}

std::unique_ptr<EventSource> open_live_source(const config::DeviceConfig& cfg, const std::string& log_level) {
  if (!device::using_real_libcaer())
    throw SourceError(
        "this evpipe was built without libcaer (against the stub in third_party_stubs/), so it cannot open a "
        "camera: install libcaer and rebuild, or use --replay FILE");
  device::DavisOptions o;
  o.serial_number = cfg.serial;
  o.ba_filter_enabled = cfg.ba_filter;
  o.ba_filter_time_us = cfg.ba_filter_time_us;
  o.refractory_enabled = cfg.refractory;
  o.refractory_time_us = cfg.refractory_time_us;
  o.container_interval_us = cfg.container_interval_us;
  o.reconnect_interval_ms = cfg.reconnect_interval_ms;
  o.libcaer_log_level = device::log_level_from_name(log_level);
  o.on_log = [](device::LogLevel level, std::string_view msg) {
    const auto lvl = level <= device::LogLevel::error     ? spdlog::level::err
                     : level <= device::LogLevel::warning ? spdlog::level::warn
                     : level <= device::LogLevel::info    ? spdlog::level::info
                                                          : spdlog::level::debug;
    spdlog::log(lvl, "libcaer: {}", msg);
  };
  o.on_warning = [](const Warning& w) { spdlog::warn("{}", w.message()); };
  try {
    return std::make_unique<device::DavisSource>(std::move(o));
  } catch (const std::invalid_argument& e) {
    throw SourceError(std::string("device configuration: ") + e.what());
  }
}

}  // namespace evpipe::app
