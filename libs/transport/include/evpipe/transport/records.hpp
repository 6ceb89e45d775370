#pragma once
// Plain records the application fills from the pipeline's results and hands to the LCM publisher. They mirror
// the LCM types in libs/transport/lcmtypes (package evpipe) field by field, with units in the names; the codec
// (codec.hpp) is the only place that knows the wire layout. No LCM headers here.

#include "evpipe/camera/pose.hpp"

#include <array>
#include <chrono>
#include <cstdint>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace evpipe::transport {

inline constexpr std::string_view kDefaultPoseChannel = "EVPIPE_POSE";
inline constexpr std::string_view kDefaultStatsChannel = "EVPIPE_STATS";

/// Tracking status on the wire (pose_t.STATUS_*); the values equal pose::TrackStatus's.
enum class TrackingStatus : std::int8_t { initialising = 0, tracking = 1, lost = 2, holding = 3 };

[[nodiscard]] std::string_view to_string(TrackingStatus s) noexcept;

/// One published pose, T_cam_model (interfaces.md: p_cam = R * p_model + t).
struct PoseRecord {
  std::int64_t seq{-1};  ///< publication number; -1 = assigned by the publisher (0, 1, 2, ...)
  std::int64_t t_us{0};  ///< sensor time the pose refers to (the window's middle), device clock
  /// Sensor time of the last window that measured the pose (= t_us while tracking, older while holding).
  std::int64_t t_last_update_us{0};
  std::int64_t utime_us{0};  ///< host wall clock at publication, us since the epoch; 0 = set when published
  std::string camera_frame{"cam"};
  std::string model_frame{"model"};
  TrackingStatus status{TrackingStatus::initialising};
  bool pose_valid{false};    ///< true tracking / holding; false: T_cam_model is the last good pose or the prior
  camera::Pose T_cam_model;  ///< written as position_m + wire quaternion (camera::to_wire, qw >= 0)
  bool covariance_known{false};
  /// Row-major 6x6, order rx ry rz (rad, left-multiplied small rotation about the camera axes) then tx ty tz
  /// (m), as pose::Covariance6. Ignored (written as zeros) when !covariance_known.
  std::array<double, 36> covariance{};
  std::int32_t window_events{0};
  std::int32_t inliers{0};
  double sigma_px{0.0};  ///< robust scale of the residuals, pixels
  /// Newest event used -> publication, host time (us). When newest_event_arrival is set, the publisher
  /// overwrites this with (now - newest_event_arrival) immediately before sending, so it includes the send.
  std::int64_t latency_us{0};
  std::chrono::steady_clock::time_point newest_event_arrival{};  ///< host time the newest event arrived; {} = unset
  bool source_connected{true};
};

/// Counters of one stage. Counts cumulative since start; processing times over the last interval.
struct StageStatsRecord {
  std::string name;
  std::int64_t events_in{0};
  std::int64_t events_kept{0};
  std::int64_t events_dropped{0};
  std::int64_t packets_in{0};
  std::int64_t busy_us{0};
  double proc_p50_us{0.0};
  double proc_p99_us{0.0};
  double proc_max_us{0.0};
};

/// A bounded queue between two stages.
struct QueueStatsRecord {
  std::string name;
  std::int32_t capacity{0};
  std::int32_t fill{0};
  std::int32_t fill_max{0};  ///< highest fill since the start
  std::int64_t pushed{0};
  std::int64_t dropped{0};
  std::int64_t events_budget{0};  ///< bound on the events queued; 0 = none
  std::int64_t events{0};         ///< events queued (0 without a bound)
  std::int64_t events_max{0};     ///< most events queued at once since the start (0 without a bound)
};

/// Pipeline statistics, published at least once a second.
struct StatsRecord {
  std::int64_t seq{-1};      ///< -1 = assigned by the publisher
  std::int64_t utime_us{0};  ///< 0 = set when published
  std::int64_t interval_us{0};
  std::int64_t t_us{0};  ///< newest sensor time seen
  std::int64_t uptime_us{0};
  std::string source{"replay"};  ///< "live" or "replay"
  bool source_connected{true};
  std::int64_t source_reconnects{0};
  TrackingStatus status{TrackingStatus::initialising};
  /// Pose messages published / messages not sent. A negative value (the default) means "fill in from the
  /// publisher's own counters".
  std::int64_t poses_published{-1};
  std::int64_t publish_failures{-1};
  double latency_p50_us{0.0};
  double latency_p99_us{0.0};
  std::vector<StageStatsRecord> stages;
  std::vector<QueueStatsRecord> queues;
  /// The denoising filter's own figures (name, value), e.g. noise_rate_hz, density_threshold_used.
  std::vector<std::pair<std::string, double>> denoise_figures;
};

/// Host wall clock now, us since the Unix epoch (the utime of LCM messages).
[[nodiscard]] std::int64_t wall_clock_utime_us();

}  // namespace evpipe::transport
