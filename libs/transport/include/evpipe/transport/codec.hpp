#pragma once
// Records <-> the lcm-gen types (package evpipe, generated at build time) <-> bytes. The only code that knows the
// wire layout; quaternions go through camera::to_wire / camera::from_wire.

#include "evpipe/pose_t.hpp"
#include "evpipe/stats_t.hpp"
#include "evpipe/transport/records.hpp"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace evpipe::transport {

/// A message of the right type whose content is invalid (zero quaternion, unknown status, NaN...). The message
/// names the field.
class DecodeError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Record -> message. seq/utime are copied as they are (the publisher assigns them before calling this); an
/// unset latency is written as latency_us. Non-finite numbers are written as they are (the publisher's caller
/// keeps them finite).
[[nodiscard]] evpipe::pose_t to_lcm(const PoseRecord& r);
[[nodiscard]] evpipe::stats_t to_lcm(const StatsRecord& r);

/// Message -> record. Throws DecodeError naming the field for a zero / non-finite quaternion, a status outside
/// STATUS_*, or array counts that do not match.
[[nodiscard]] PoseRecord from_lcm(const evpipe::pose_t& m);
[[nodiscard]] StatsRecord from_lcm(const evpipe::stats_t& m);

[[nodiscard]] std::vector<std::uint8_t> encode(const PoseRecord& r);
[[nodiscard]] std::vector<std::uint8_t> encode(const StatsRecord& r);

/// Bytes -> record. nullopt when the bytes are not this type (the LCM fingerprint differs) or are truncated, or a
/// string length or array count goes beyond the bytes (checked before anything is allocated: a count that cannot
/// fit is never allocated); DecodeError when they are this type with invalid content.
[[nodiscard]] std::optional<PoseRecord> decode_pose(const void* data, std::size_t size);
[[nodiscard]] std::optional<StatsRecord> decode_stats(const void* data, std::size_t size);

/// Why bytes carrying the pose_t or stats_t fingerprint are not a whole message of that type (the cases where
/// decode_pose / decode_stats return nullopt for them), naming the field and its byte offset, e.g.
/// "stats_t.num_queues at byte 93 of 153: count 268435456 needs at least ... bytes". nullopt when the bytes are
/// a whole message, or carry another fingerprint.
[[nodiscard]] std::optional<std::string> wire_error(const void* data, std::size_t size);

}  // namespace evpipe::transport
