#include "evpipe/transport/records.hpp"

#include <chrono>

namespace evpipe::transport {

std::int64_t wall_clock_utime_us() {
  return std::chrono::duration_cast<std::chrono::microseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

}  // namespace evpipe::transport
