#pragma once
// One line of a record's field table: a member of the record and the field of the LCM message (lcm-gen type) it
// travels in. The codec (codec.cpp: record <-> message) and the JSON printer (text.cpp) are generated from these
// tables (records.hpp), so that a new field is one table line. What is done with a field follows from the two
// member types (checked at compile time):
//   the same type (integers, double, std::string)  copied as it is
//   bool <-> int8_t (an LCM boolean)               copied; decoded as != 0; JSON true / false
//   TrackStatus <-> int8_t                         the status value; decoding refuses values outside STATUS_*;
//                                                  JSON the status name
//   std::array<T, N> <-> T[N] (fixed-size array)   element by element; JSON [..]
// Fields that need more than a copy (a pose as position + wire quaternion, a covariance that depends on a flag)
// have their own descriptor types beside their table.

#include "evpipe/core/track_status.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <tuple>
#include <type_traits>

namespace evpipe::transport {

template <typename T>
inline constexpr bool kIsStdArray = false;
template <typename T, std::size_t N>
inline constexpr bool kIsStdArray<std::array<T, N>> = true;

/// Whether a record member of type R can travel in a message field of type W (see the list above).
template <typename R, typename W>
inline constexpr bool kWireCompatible = (std::is_same_v<R, W> &&
                                         (std::is_arithmetic_v<R> || std::is_same_v<R, std::string>)) ||
                                        (std::is_same_v<R, bool> && std::is_same_v<W, std::int8_t>) ||
                                        (std::is_same_v<R, TrackStatus> && std::is_same_v<W, std::int8_t>);
template <typename T, std::size_t N, typename W>
inline constexpr bool kWireCompatible<std::array<T, N>, W> =
    std::is_array_v<W>&& std::extent_v<W> == N&& std::rank_v<W> == 1 &&
    std::is_same_v<T, std::remove_extent_t<W>>&& std::is_arithmetic_v<T>;

template <typename Record, typename Message, typename R, typename W>
struct WireField {
  std::string_view name;  ///< the message's field name (as in the .lcm file), also the JSON key
  R Record::*record;
  W Message::*wire;
};

/// A table line: `wire_field("sigma_px", &PoseRecord::sigma_px, &evpipe::pose_t::sigma_px)`.
template <typename Record, typename Message, typename R, typename W>
constexpr WireField<Record, Message, R, W> wire_field(std::string_view name, R Record::*record,
                                                      W Message::*wire) noexcept {
  static_assert(kWireCompatible<R, W>,
                "record member and message field types do not match (same type, bool <-> boolean, "
                "TrackStatus <-> int8_t, std::array<T, N> <-> T[N]); a conversion needs its own descriptor");
  return {name, record, wire};
}

/// Calls fn(field) for every line of a table, in table order.
template <typename Table, typename Fn>
constexpr void for_each_field(const Table& table, Fn&& fn) {
  std::apply([&fn](const auto&... field) { (fn(field), ...); }, table);
}

}  // namespace evpipe::transport
