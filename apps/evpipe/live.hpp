#pragma once
#include <memory>
#include <string>

#include "evpipe/config/run_config.hpp"
#include "evpipe/core/source.hpp"

namespace evpipe::app {
/// Opens the first DAVIS346 (or the configured serial) over USB with the run configuration's device
/// settings. Throws evpipe::SourceError with the reason when no camera can be opened.
/// `log_level` (the run configuration's log.level, e.g. from --log-level) also sets libcaer's level for the camera.
std::unique_ptr<EventSource> open_live_source(const config::DeviceConfig& device, const std::string& log_level);
/// True when built against the real libcaer (false: the stub, no camera can be opened).
bool live_camera_supported();
/// The libcaer of this build for --version: "libcaer: 3.3.15" or "libcaer: stub: no camera support".
std::string libcaer_version_line();
/// libcaer's process-wide log level from the application's (log.level / --log-level): debug for trace and
/// debug, warning for warn, ... (device::log_level_from_name).
void set_libcaer_log_level(const std::string& log_level);
}  // namespace evpipe::app
