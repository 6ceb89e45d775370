#pragma once
// The tracking status of the pose: the one definition used by the estimator (pose::TrackStatus), the records
// published on LCM (transport::TrackingStatus) and the application. The numeric values are the wire values of
// the LCM pose message (pose_t.STATUS_*; libs/transport/src/codec.cpp static_asserts that they agree).

#include <array>
#include <cstdint>
#include <optional>
#include <string_view>

namespace evpipe {

/// What each promises (interfaces.md): tracking = measured in this window and verified; holding = the target is
/// still (the window shows no motion near the model beyond the noise), the last measured pose is repeated;
/// initialising and lost = no valid pose.
enum class TrackStatus : std::int8_t { initialising = 0, tracking = 1, lost = 2, holding = 3 };

/// Every status, in value order (index = value).
inline constexpr std::array<TrackStatus, 4> kTrackStatuses{TrackStatus::initialising, TrackStatus::tracking,
                                                           TrackStatus::lost, TrackStatus::holding};

[[nodiscard]] constexpr std::string_view to_string(TrackStatus s) noexcept {
  switch (s) {
    case TrackStatus::initialising:
      return "initialising";
    case TrackStatus::tracking:
      return "tracking";
    case TrackStatus::lost:
      return "lost";
    case TrackStatus::holding:
      return "holding";
  }
  return "?";
}

/// The status whose numeric value is `v`; nullopt for any other value.
[[nodiscard]] constexpr std::optional<TrackStatus> track_status_from_value(int v) noexcept {
  for (const TrackStatus s : kTrackStatuses) {
    if (static_cast<int>(s) == v) return s;
  }
  return std::nullopt;
}

}  // namespace evpipe
