#pragma once
#include <memory>

#include "evpipe/config/run_config.hpp"
#include "evpipe/core/source.hpp"

namespace evpipe::app {
/// Opens the first DAVIS346 (or the configured serial) over USB with the run configuration's device
/// settings. Throws evpipe::SourceError with the reason when no camera can be opened.
std::unique_ptr<EventSource> open_live_source(const config::DeviceConfig& device);
/// True when built against the real libcaer (false: the stub, no camera can be opened).
bool live_camera_supported();
}  // namespace evpipe::app
