#include "evpipe/transport/codec.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <exception>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>

#include "wire_walker.hpp"

namespace evpipe::transport {

namespace {

using detail::WireWalker;

std::int32_t count_i32(std::size_t n, const char* field) {
  if (n > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
    throw std::length_error(fmt::format("stats_t.{}: {} entries do not fit an int32 count", field, n));
  }
  return static_cast<std::int32_t>(n);
}

// One status type (libs/core) whose values are the wire's.
static_assert(static_cast<std::int8_t>(TrackStatus::initialising) == evpipe::pose_t::STATUS_INITIALISING);
static_assert(static_cast<std::int8_t>(TrackStatus::tracking) == evpipe::pose_t::STATUS_TRACKING);
static_assert(static_cast<std::int8_t>(TrackStatus::lost) == evpipe::pose_t::STATUS_LOST);
static_assert(static_cast<std::int8_t>(TrackStatus::holding) == evpipe::pose_t::STATUS_HOLDING);
static_assert(kTrackStatuses.size() == 4,
              "a new TrackStatus needs its pose_t.STATUS_* constant (and the asserts here)");

TrackStatus status_from_wire(std::int8_t v, std::string_view type, std::string_view field) {
  if (const std::optional<TrackStatus> s = track_status_from_value(v)) {
    return *s;
  }
  throw DecodeError(fmt::format("{}.{}: {} is not one of STATUS_INITIALISING/TRACKING/LOST/HOLDING (0/1/2/3)", type,
                                field, static_cast<int>(v)));
}

// Table lines (wire_field.hpp): record -> message and back, by the member types.
template <typename Record, typename Message, typename R, typename W>
void field_to_wire(const WireField<Record, Message, R, W>& f, const Record& r, Message& m) {
  const R& v = r.*f.record;
  W& w = m.*f.wire;
  if constexpr (std::is_same_v<R, TrackStatus>) {
    w = static_cast<W>(v);
  } else if constexpr (kIsStdArray<R>) {
    std::copy(v.begin(), v.end(), std::begin(w));
  } else {
    w = v;  // bool -> int8_t: 0 / 1
  }
}

template <typename Record, typename Message, typename R, typename W>
void field_from_wire(const WireField<Record, Message, R, W>& f, const Message& m, Record& r, std::string_view type) {
  const W& w = m.*f.wire;
  R& v = r.*f.record;
  if constexpr (std::is_same_v<R, bool>) {
    v = w != 0;
  } else if constexpr (std::is_same_v<R, TrackStatus>) {
    v = status_from_wire(w, type, f.name);
  } else if constexpr (kIsStdArray<R>) {
    std::copy(std::begin(w), std::end(w), v.begin());
  } else {
    v = w;
  }
}

// pose_t's own descriptors (records.hpp).
void field_to_wire(PosePositionField /*f*/, const PoseRecord& r, evpipe::pose_t& m) {
  for (int i = 0; i < 3; ++i) {
    m.position_m[i] = r.T_cam_model.t_cam_model_m[i];
  }
}

void field_from_wire(PosePositionField /*f*/, const evpipe::pose_t& m, PoseRecord& r, std::string_view type) {
  for (int i = 0; i < 3; ++i) {
    if (!std::isfinite(m.position_m[i])) {
      throw DecodeError(fmt::format("{}.position_m[{}]: not finite", type, i));
    }
    r.T_cam_model.t_cam_model_m[i] = m.position_m[i];
  }
}

void field_to_wire(PoseOrientationField /*f*/, const PoseRecord& r, evpipe::pose_t& m) {
  const camera::WireQuaternion q = camera::to_wire(r.T_cam_model.q_cam_model);
  m.orientation[0] = q.qw;
  m.orientation[1] = q.qx;
  m.orientation[2] = q.qy;
  m.orientation[3] = q.qz;
}

void field_from_wire(PoseOrientationField /*f*/, const evpipe::pose_t& m, PoseRecord& r, std::string_view type) {
  try {
    r.T_cam_model.q_cam_model =
        camera::from_wire(m.orientation[0], m.orientation[1], m.orientation[2], m.orientation[3]);
  } catch (const std::invalid_argument& e) {
    throw DecodeError(fmt::format("{}.orientation (qw qx qy qz = {} {} {} {}): {}", type, m.orientation[0],
                                  m.orientation[1], m.orientation[2], m.orientation[3], e.what()));
  }
}

// The flag covariance_known decides (a field of its own).
void field_to_wire(PoseCovarianceField /*f*/, const PoseRecord& r, evpipe::pose_t& m) {
  for (std::size_t i = 0; i < 36; ++i) {
    m.covariance[i] = r.covariance_known ? r.covariance[i] : 0.0;
  }
}

void field_from_wire(PoseCovarianceField /*f*/, const evpipe::pose_t& m, PoseRecord& r, std::string_view /*type*/) {
  for (std::size_t i = 0; i < 36; ++i) {
    r.covariance[i] = m.covariance_known != 0 ? m.covariance[i] : 0.0;
  }
}

template <typename Msg>
std::vector<std::uint8_t> encode_msg(const Msg& m) {
  const int n = m.getEncodedSize();
  std::vector<std::uint8_t> out(static_cast<std::size_t>(n));
  if (m.encode(out.data(), 0, n) != n) {
    throw std::runtime_error("LCM encode failed");  // only on a size mismatch, i.e. a bug here
  }
  return out;
}

// The wire layout of pose_t and stats_t (lcmtypes/*.lcm in LCM's encoding: big-endian numbers, a string = an
// int32 length counting its NUL, then the bytes), walked before the generated decode() runs: that code resizes an
// array to the count it has just read before checking that the bytes are there, so a 153-byte stats_t claiming
// 2^28 queues allocated ~15 GB. The walk allocates nothing and bounds every length and count by the bytes left.
// The codec round trips (tests/transport) keep it in step with the .lcm files: a field added there and not here
// makes every message of that type fail to decode.

// pose_t.lcm, field by field (only strings vary in size).
void walk(WireWalker& w, const evpipe::pose_t* /*type*/) {
  w.fixed("utime", 8);
  w.fixed("t_us", 8);
  w.fixed("seq", 8);
  w.string("camera_frame");
  w.string("model_frame");
  w.fixed("status", 1);
  w.fixed("pose_valid", 1);
  w.fixed("position_m", 3 * 8);
  w.fixed("orientation", 4 * 8);
  w.fixed("covariance_known", 1);
  w.fixed("covariance", 36 * 8);
  w.fixed("window_events", 4);
  w.fixed("inliers", 4);
  w.fixed("sigma_px", 8);
  w.fixed("latency_us", 8);
  w.fixed("source_connected", 1);
  w.fixed("t_last_update_us", 8);
}

// stats_t.lcm with stage_stats_t.lcm and queue_stats_t.lcm. An element's smallest size is its fixed bytes plus 5
// per string (length + NUL).
constexpr std::size_t kStageFixedBytes = 5 * 8 + 3 * 8;
constexpr std::size_t kQueueFixedBytes = 3 * 4 + 5 * 8;

void walk(WireWalker& w, const evpipe::stats_t* /*type*/) {
  w.fixed("utime", 8);
  w.fixed("seq", 8);
  w.fixed("interval_us", 8);
  w.fixed("t_us", 8);
  w.fixed("uptime_us", 8);
  w.string("source");
  w.fixed("source_connected", 1);
  w.fixed("source_reconnects", 8);
  w.fixed("status", 1);
  w.fixed("poses_published", 8);
  w.fixed("publish_failures", 8);
  w.fixed("latency_p50_us", 8);
  w.fixed("latency_p99_us", 8);
  const std::int32_t stages = w.count("num_stages", 5 + kStageFixedBytes);
  for (std::int32_t i = 0; i < stages; ++i) {
    w.string("stages", i, ".name");
    w.fixed("stages", kStageFixedBytes, i);
  }
  const std::int32_t queues = w.count("num_queues", 5 + kQueueFixedBytes);
  for (std::int32_t i = 0; i < queues; ++i) {
    w.string("queues", i, ".name");
    w.fixed("queues", kQueueFixedBytes, i);
  }
  const std::int32_t figures = w.count("num_denoise_figures", 5 + 8);
  for (std::int32_t i = 0; i < figures; ++i) {
    w.string("denoise_figure_names", i);
  }
  w.fixed("denoise_figures", static_cast<std::size_t>(figures) * 8);
}

template <typename Msg>
constexpr std::string_view kTypeName = std::is_same_v<Msg, evpipe::pose_t> ? "pose_t" : "stats_t";

/// nullopt: `data` is a whole Msg, or carries another fingerprint. Else why it is not (type.field at byte N).
template <typename Msg>
std::optional<std::string> wire_error_of(const void* data, std::size_t size) {
  return detail::walk_error(kTypeName<Msg>, Msg::getHash(), data, size,
                            [](WireWalker& w) { walk(w, static_cast<const Msg*>(nullptr)); });
}

template <typename Msg>
std::optional<Msg> decode_msg(const void* data, std::size_t size) {
  if (data == nullptr || size < 8 || size > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
    return std::nullopt;
  }
  if (wire_error_of<Msg>(data, size)) {
    return std::nullopt;  // truncated, or a length / count beyond the bytes: walked before decode() allocates
  }
  Msg m;
  // decode() checks the 8-byte fingerprint first and fails (< 0) on another type or truncated data; the walk above
  // has refused negative or absurd array lengths already, the catch is a second line.
  try {
    if (m.decode(data, 0, static_cast<int>(size)) < 0) {
      return std::nullopt;
    }
  } catch (const std::exception&) {
    return std::nullopt;
  }
  return m;
}

// stats_t's lists (records.hpp); from_lcm(stats_t) has checked the counts against the arrays.
template <typename Record, typename Message, typename Table>
Message element_to_wire(const Table& table, const Record& r) {
  Message m;
  for_each_field(table, [&](const auto& f) { field_to_wire(f, r, m); });
  return m;
}

template <typename Record, typename Message, typename Table>
Record element_from_wire(const Table& table, const Message& m, std::string_view type) {
  Record r;
  for_each_field(table, [&](const auto& f) { field_from_wire(f, m, r, type); });
  return r;
}

void field_to_wire(StatsStagesField /*f*/, const StatsRecord& r, evpipe::stats_t& m) {
  m.num_stages = count_i32(r.stages.size(), "stages");
  m.stages.reserve(r.stages.size());
  for (const StageStatsRecord& s : r.stages) {
    m.stages.push_back(element_to_wire<StageStatsRecord, evpipe::stage_stats_t>(kStageStatsFields, s));
  }
}

void field_from_wire(StatsStagesField /*f*/, const evpipe::stats_t& m, StatsRecord& r, std::string_view /*type*/) {
  for (const evpipe::stage_stats_t& w : m.stages) {
    r.stages.push_back(element_from_wire<StageStatsRecord>(kStageStatsFields, w, "stage_stats_t"));
  }
}

void field_to_wire(StatsQueuesField /*f*/, const StatsRecord& r, evpipe::stats_t& m) {
  m.num_queues = count_i32(r.queues.size(), "queues");
  m.queues.reserve(r.queues.size());
  for (const QueueStatsRecord& q : r.queues) {
    m.queues.push_back(element_to_wire<QueueStatsRecord, evpipe::queue_stats_t>(kQueueStatsFields, q));
  }
}

void field_from_wire(StatsQueuesField /*f*/, const evpipe::stats_t& m, StatsRecord& r, std::string_view /*type*/) {
  for (const evpipe::queue_stats_t& w : m.queues) {
    r.queues.push_back(element_from_wire<QueueStatsRecord>(kQueueStatsFields, w, "queue_stats_t"));
  }
}

void field_to_wire(StatsDenoiseFiguresField /*f*/, const StatsRecord& r, evpipe::stats_t& m) {
  m.num_denoise_figures = count_i32(r.denoise_figures.size(), "denoise_figures");
  for (const auto& [name, value] : r.denoise_figures) {
    m.denoise_figure_names.push_back(name);
    m.denoise_figures.push_back(value);
  }
}

void field_from_wire(StatsDenoiseFiguresField /*f*/, const evpipe::stats_t& m, StatsRecord& r,
                     std::string_view /*type*/) {
  for (std::size_t i = 0; i < m.denoise_figures.size(); ++i) {
    r.denoise_figures.emplace_back(m.denoise_figure_names[i], m.denoise_figures[i]);
  }
}

}  // namespace

evpipe::pose_t to_lcm(const PoseRecord& r) {
  evpipe::pose_t m;
  for_each_field(kPoseFields, [&](const auto& f) { field_to_wire(f, r, m); });
  return m;
}

PoseRecord from_lcm(const evpipe::pose_t& m) {
  PoseRecord r;
  for_each_field(kPoseFields, [&](const auto& f) { field_from_wire(f, m, r, "pose_t"); });
  return r;
}

evpipe::stats_t to_lcm(const StatsRecord& r) {
  evpipe::stats_t m;
  for_each_field(kStatsFields, [&](const auto& f) { field_to_wire(f, r, m); });
  return m;
}

StatsRecord from_lcm(const evpipe::stats_t& m) {
  if (m.num_stages < 0 || static_cast<std::size_t>(m.num_stages) != m.stages.size()) {
    throw DecodeError(fmt::format("stats_t.num_stages: {} but {} stages", m.num_stages, m.stages.size()));
  }
  if (m.num_queues < 0 || static_cast<std::size_t>(m.num_queues) != m.queues.size()) {
    throw DecodeError(fmt::format("stats_t.num_queues: {} but {} queues", m.num_queues, m.queues.size()));
  }
  if (m.num_denoise_figures < 0 || static_cast<std::size_t>(m.num_denoise_figures) != m.denoise_figures.size() ||
      m.denoise_figure_names.size() != m.denoise_figures.size()) {
    throw DecodeError(fmt::format("stats_t.num_denoise_figures: {} but {} names and {} values", m.num_denoise_figures,
                                  m.denoise_figure_names.size(), m.denoise_figures.size()));
  }
  StatsRecord r;
  for_each_field(kStatsFields, [&](const auto& f) { field_from_wire(f, m, r, "stats_t"); });
  return r;
}

std::vector<std::uint8_t> encode(const PoseRecord& r) {
  return encode_msg(to_lcm(r));
}

std::vector<std::uint8_t> encode(const StatsRecord& r) {
  return encode_msg(to_lcm(r));
}

std::optional<PoseRecord> decode_pose(const void* data, std::size_t size) {
  auto m = decode_msg<evpipe::pose_t>(data, size);
  if (!m) {
    return std::nullopt;
  }
  return from_lcm(*m);
}

std::optional<StatsRecord> decode_stats(const void* data, std::size_t size) {
  auto m = decode_msg<evpipe::stats_t>(data, size);
  if (!m) {
    return std::nullopt;
  }
  return from_lcm(*m);
}

std::optional<std::string> wire_error(const void* data, std::size_t size) {
  if (auto why = wire_error_of<evpipe::pose_t>(data, size)) {
    return why;
  }
  return wire_error_of<evpipe::stats_t>(data, size);
}

}  // namespace evpipe::transport
