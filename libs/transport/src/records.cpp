#include "evpipe/transport/records.hpp"

#include <chrono>

namespace evpipe::transport {

std::string_view to_string(TrackingStatus s) noexcept {
  switch (s) {
    case TrackingStatus::initialising:
      return "initialising";
    case TrackingStatus::tracking:
      return "tracking";
    case TrackingStatus::lost:
      return "lost";
    case TrackingStatus::holding:
      return "holding";
  }
  return "?";
}

std::int64_t wall_clock_utime_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace evpipe::transport
