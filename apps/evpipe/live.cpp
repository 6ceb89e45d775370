// placeholder until the device library lands
#include "live.hpp"
#include "evpipe/core/error.hpp"
namespace evpipe::app {
std::unique_ptr<EventSource> open_live_source(const config::DeviceConfig&) {
  throw SourceError("live camera support is not built yet");
}
bool live_camera_supported() { return false; }
}  // namespace evpipe::app
