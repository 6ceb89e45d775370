#pragma once
// One-line JSON renderings of the records, for evpipe-lcm-echo and logs. Keys are the LCM field names.

#include "evpipe/transport/records.hpp"

#include <string>
#include <string_view>

namespace evpipe::transport {

[[nodiscard]] std::string to_json(const PoseRecord& r, std::string_view channel);
[[nodiscard]] std::string to_json(const StatsRecord& r, std::string_view channel);

}  // namespace evpipe::transport
