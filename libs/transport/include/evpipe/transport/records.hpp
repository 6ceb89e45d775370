#pragma once
// Plain records the application fills from the pipeline's results and hands to the LCM publisher. They mirror
// the LCM types in libs/transport/lcmtypes (package evpipe), with units in the names. Each record's field table
// (kPoseFields, kStatsFields, ... below) says which message field each member travels in; the codec (codec.cpp)
// and the JSON printer (text.cpp) are generated from the tables.

#include "evpipe/camera/pose.hpp"
#include "evpipe/core/track_status.hpp"
#include "evpipe/pose_t.hpp"
#include "evpipe/queue_stats_t.hpp"
#include "evpipe/stage_stats_t.hpp"
#include "evpipe/stats_t.hpp"
#include "evpipe/transport/wire_field.hpp"

#include <array>
#include <chrono>
#include <cstdint>
#include <string>
#include <string_view>
#include <tuple>
#include <utility>
#include <vector>

namespace evpipe::transport {

inline constexpr std::string_view kDefaultPoseChannel = "EVPIPE_POSE";
inline constexpr std::string_view kDefaultStatsChannel = "EVPIPE_STATS";

/// Tracking status on the wire (pose_t.STATUS_*): the one status type of libs/core, = pose::TrackStatus.
using TrackingStatus = evpipe::TrackStatus;
using evpipe::to_string;

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

/// pose_t fields that are more than a copy of one member (codec.cpp and text.cpp implement them).
struct PosePositionField {  ///< T_cam_model.t_cam_model_m <-> position_m[3]; decoding refuses non-finite values
  static constexpr std::string_view name{"position_m"};
};
struct PoseOrientationField {  ///< T_cam_model.q_cam_model <-> orientation[4] = camera::to_wire (qw qx qy qz)
  static constexpr std::string_view name{"orientation"};
};
struct PoseCovarianceField {  ///< covariance <-> covariance[36]; zeros (JSON null) unless covariance_known
  static constexpr std::string_view name{"covariance"};
};

/// PoseRecord <-> pose_t: one line per field of pose_t.lcm, in the order of the JSON line (evpipe-lcm-echo);
/// the wire order is pose_t.lcm's. The codec (to_lcm / from_lcm, hence encode / decode_pose) and to_json are
/// generated from this table (tests/transport/test_record_fields.cpp checks it against pose_t.lcm).
///
/// Adding a field to pose_t touches three code files (and its row in docs/operations.md's pose_t table):
///   1. libs/transport/lcmtypes/pose_t.lcm: the field, with its unit in the name or the comment (last, so that
///      the order of the others is kept; the type's fingerprint changes: say so in docs/operations.md);
///   2. this file: the PoseRecord member (defaulted) and its line below, e.g.
///        wire_field("range_m", &PoseRecord::range_m, &evpipe::pose_t::range_m),
///      (same type both sides; bool for an LCM boolean; std::array<T, N> for T name[N]; anything else needs a
///      descriptor of its own like PosePositionField);
///   3. the mapping estimate -> PoseRecord (`to_record`, the one place the pipeline's result becomes a record):
///        r.range_m = e.range_m;
/// evpipe-lcm-echo's JSON and the round trip then carry it; the --text line (to_text) lists chosen fields only.
inline constexpr std::tuple kPoseFields{
    wire_field("utime", &PoseRecord::utime_us, &evpipe::pose_t::utime),
    wire_field("t_us", &PoseRecord::t_us, &evpipe::pose_t::t_us),
    wire_field("t_last_update_us", &PoseRecord::t_last_update_us, &evpipe::pose_t::t_last_update_us),
    wire_field("seq", &PoseRecord::seq, &evpipe::pose_t::seq),
    wire_field("camera_frame", &PoseRecord::camera_frame, &evpipe::pose_t::camera_frame),
    wire_field("model_frame", &PoseRecord::model_frame, &evpipe::pose_t::model_frame),
    wire_field("status", &PoseRecord::status, &evpipe::pose_t::status),
    wire_field("pose_valid", &PoseRecord::pose_valid, &evpipe::pose_t::pose_valid),
    PosePositionField{},
    PoseOrientationField{},
    wire_field("covariance_known", &PoseRecord::covariance_known, &evpipe::pose_t::covariance_known),
    PoseCovarianceField{},
    wire_field("window_events", &PoseRecord::window_events, &evpipe::pose_t::window_events),
    wire_field("inliers", &PoseRecord::inliers, &evpipe::pose_t::inliers),
    wire_field("sigma_px", &PoseRecord::sigma_px, &evpipe::pose_t::sigma_px),
    wire_field("latency_us", &PoseRecord::latency_us, &evpipe::pose_t::latency_us),
    wire_field("source_connected", &PoseRecord::source_connected, &evpipe::pose_t::source_connected),
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

/// StageStatsRecord <-> stage_stats_t, QueueStatsRecord <-> queue_stats_t and StatsRecord <-> stats_t, as
/// kPoseFields: one line per field of the .lcm file, in JSON order; a new scalar statistic is one line here.
inline constexpr std::tuple kStageStatsFields{
    wire_field("name", &StageStatsRecord::name, &evpipe::stage_stats_t::name),
    wire_field("events_in", &StageStatsRecord::events_in, &evpipe::stage_stats_t::events_in),
    wire_field("events_kept", &StageStatsRecord::events_kept, &evpipe::stage_stats_t::events_kept),
    wire_field("events_dropped", &StageStatsRecord::events_dropped, &evpipe::stage_stats_t::events_dropped),
    wire_field("packets_in", &StageStatsRecord::packets_in, &evpipe::stage_stats_t::packets_in),
    wire_field("busy_us", &StageStatsRecord::busy_us, &evpipe::stage_stats_t::busy_us),
    wire_field("proc_p50_us", &StageStatsRecord::proc_p50_us, &evpipe::stage_stats_t::proc_p50_us),
    wire_field("proc_p99_us", &StageStatsRecord::proc_p99_us, &evpipe::stage_stats_t::proc_p99_us),
    wire_field("proc_max_us", &StageStatsRecord::proc_max_us, &evpipe::stage_stats_t::proc_max_us),
};

inline constexpr std::tuple kQueueStatsFields{
    wire_field("name", &QueueStatsRecord::name, &evpipe::queue_stats_t::name),
    wire_field("capacity", &QueueStatsRecord::capacity, &evpipe::queue_stats_t::capacity),
    wire_field("fill", &QueueStatsRecord::fill, &evpipe::queue_stats_t::fill),
    wire_field("fill_max", &QueueStatsRecord::fill_max, &evpipe::queue_stats_t::fill_max),
    wire_field("pushed", &QueueStatsRecord::pushed, &evpipe::queue_stats_t::pushed),
    wire_field("dropped", &QueueStatsRecord::dropped, &evpipe::queue_stats_t::dropped),
    wire_field("events_budget", &QueueStatsRecord::events_budget, &evpipe::queue_stats_t::events_budget),
    wire_field("events", &QueueStatsRecord::events, &evpipe::queue_stats_t::events),
    wire_field("events_max", &QueueStatsRecord::events_max, &evpipe::queue_stats_t::events_max),
};

/// stats_t's lists: a count field and its array(s) together (codec.cpp and text.cpp implement them).
struct StatsStagesField {  ///< stages <-> num_stages + stages[] (kStageStatsFields); JSON a list of objects
  static constexpr std::string_view name{"stages"};
  static constexpr std::array<std::string_view, 2> wire_names{"num_stages", "stages"};
};
struct StatsQueuesField {  ///< queues <-> num_queues + queues[] (kQueueStatsFields); JSON a list of objects
  static constexpr std::string_view name{"queues"};
  static constexpr std::array<std::string_view, 2> wire_names{"num_queues", "queues"};
};
struct StatsDenoiseFiguresField {  ///< (name, value) pairs <-> two parallel arrays; JSON an object name: value
  static constexpr std::string_view name{"denoise_figures"};
  static constexpr std::array<std::string_view, 3> wire_names{"num_denoise_figures", "denoise_figure_names",
                                                              "denoise_figures"};
};

inline constexpr std::tuple kStatsFields{
    wire_field("utime", &StatsRecord::utime_us, &evpipe::stats_t::utime),
    wire_field("seq", &StatsRecord::seq, &evpipe::stats_t::seq),
    wire_field("interval_us", &StatsRecord::interval_us, &evpipe::stats_t::interval_us),
    wire_field("t_us", &StatsRecord::t_us, &evpipe::stats_t::t_us),
    wire_field("uptime_us", &StatsRecord::uptime_us, &evpipe::stats_t::uptime_us),
    wire_field("source", &StatsRecord::source, &evpipe::stats_t::source),
    wire_field("source_connected", &StatsRecord::source_connected, &evpipe::stats_t::source_connected),
    wire_field("source_reconnects", &StatsRecord::source_reconnects, &evpipe::stats_t::source_reconnects),
    wire_field("status", &StatsRecord::status, &evpipe::stats_t::status),
    wire_field("poses_published", &StatsRecord::poses_published, &evpipe::stats_t::poses_published),
    wire_field("publish_failures", &StatsRecord::publish_failures, &evpipe::stats_t::publish_failures),
    wire_field("latency_p50_us", &StatsRecord::latency_p50_us, &evpipe::stats_t::latency_p50_us),
    wire_field("latency_p99_us", &StatsRecord::latency_p99_us, &evpipe::stats_t::latency_p99_us),
    StatsStagesField{},
    StatsQueuesField{},
    StatsDenoiseFiguresField{},
};

/// Host wall clock now, us since the Unix epoch (the utime of LCM messages).
[[nodiscard]] std::int64_t wall_clock_utime_us();

}  // namespace evpipe::transport
