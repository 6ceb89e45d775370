#pragma once
// One-line renderings of the records for evpipe-lcm-echo and logs: JSON (keys are the LCM field names, generated
// from the records' field tables in records.hpp, in table order) and text (chosen fields, written by hand).

#include "evpipe/transport/records.hpp"

#include <string>
#include <string_view>

namespace evpipe::transport {

[[nodiscard]] std::string to_json(const PoseRecord& r, std::string_view channel);
[[nodiscard]] std::string to_json(const StatsRecord& r, std::string_view channel);

/// Short human-readable one-liners (units in the text) for operators at a terminal.
[[nodiscard]] std::string to_text(const PoseRecord& r, std::string_view channel);
[[nodiscard]] std::string to_text(const StatsRecord& r, std::string_view channel);

}  // namespace evpipe::transport
