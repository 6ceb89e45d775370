#include "evpipe/transport/text.hpp"

#include "evpipe/core/json_quote.hpp"

#include <fmt/format.h>

#include <cmath>
#include <cstddef>
#include <iterator>
#include <string>
#include <type_traits>
#include <vector>

namespace evpipe::transport {

namespace {

void put_str(std::string& out, std::string_view s) {
  out += json_quote(s);
}

void put_num(std::string& out, double v) {
  if (std::isfinite(v)) {
    fmt::format_to(std::back_inserter(out), "{}", v);
  } else {
    out += "null";  // JSON has no NaN / inf
  }
}

template <typename T>
void put_int(std::string& out, T v) {
  fmt::format_to(std::back_inserter(out), "{}", v);
}

const char* boolean(bool b) {
  return b ? "true" : "false";
}

void put_key(std::string& out, std::string_view name) {
  out += ",\"";
  out += name;
  out += "\":";
}

// A record member as JSON, by its type (wire_field.hpp).
template <typename T>
void put_value(std::string& out, const T& v) {
  if constexpr (std::is_same_v<T, bool>) {
    out += boolean(v);
  } else if constexpr (std::is_same_v<T, std::string>) {
    put_str(out, v);
  } else if constexpr (std::is_same_v<T, TrackStatus>) {
    put_str(out, to_string(v));
  } else if constexpr (std::is_floating_point_v<T>) {
    put_num(out, v);
  } else if constexpr (std::is_integral_v<T>) {
    put_int(out, v);
  } else {
    static_assert(kIsStdArray<T>, "no JSON rendering for this member type");
    out += '[';
    for (std::size_t i = 0; i < v.size(); ++i) {
      if (i) out += ',';
      put_value(out, v[i]);
    }
    out += ']';
  }
}

template <typename Record, typename Message, typename R, typename W>
void put_field(std::string& out, const WireField<Record, Message, R, W>& f, const Record& r) {
  put_key(out, f.name);
  put_value(out, r.*f.record);
}

// pose_t's own descriptors (records.hpp).
void put_field(std::string& out, PosePositionField f, const PoseRecord& r) {
  put_key(out, f.name);
  out += '[';
  for (int i = 0; i < 3; ++i) {
    if (i) out += ',';
    put_num(out, r.T_cam_model.t_cam_model_m[i]);
  }
  out += ']';
}

void put_field(std::string& out, PoseOrientationField f, const PoseRecord& r) {
  const camera::WireQuaternion q = camera::to_wire(r.T_cam_model.q_cam_model);
  put_key(out, f.name);
  out += '[';
  put_num(out, q.qw);
  out += ',';
  put_num(out, q.qx);
  out += ',';
  put_num(out, q.qy);
  out += ',';
  put_num(out, q.qz);
  out += ']';
}

void put_field(std::string& out, PoseCovarianceField f, const PoseRecord& r) {
  put_key(out, f.name);
  if (r.covariance_known) {
    put_value(out, r.covariance);
  } else {
    out += "null";  // rather than 36 zeros that look like certainty
  }
}

// stats_t's lists (records.hpp).
template <typename Table, typename Record>
void put_object(std::string& out, const Table& table, const Record& r) {
  std::string fields;
  for_each_field(table, [&](const auto& f) { put_field(fields, f, r); });
  if (fields.empty()) {
    out += "{}";
    return;
  }
  fields.front() = '{';  // the first field's ','
  out += fields;
  out += '}';
}

template <typename Table, typename Record>
void put_list(std::string& out, std::string_view name, const Table& table, const std::vector<Record>& items) {
  put_key(out, name);
  out += '[';
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (i) out += ',';
    put_object(out, table, items[i]);
  }
  out += ']';
}

void put_field(std::string& out, StatsStagesField f, const StatsRecord& r) {
  put_list(out, f.name, kStageStatsFields, r.stages);
}

void put_field(std::string& out, StatsQueuesField f, const StatsRecord& r) {
  put_list(out, f.name, kQueueStatsFields, r.queues);
}

void put_field(std::string& out, StatsDenoiseFiguresField f, const StatsRecord& r) {
  put_key(out, f.name);
  out += '{';
  for (std::size_t i = 0; i < r.denoise_figures.size(); ++i) {
    if (i) out += ',';
    put_str(out, r.denoise_figures[i].first);
    out += ':';
    put_num(out, r.denoise_figures[i].second);
  }
  out += '}';
}

}  // namespace

std::string to_json(const PoseRecord& r, std::string_view channel) {
  std::string o = "{\"channel\":";
  put_str(o, channel);
  o += ",\"type\":\"evpipe.pose_t\"";
  for_each_field(kPoseFields, [&](const auto& f) { put_field(o, f, r); });
  o += '}';
  return o;
}

std::string to_json(const StatsRecord& r, std::string_view channel) {
  std::string o = "{\"channel\":";
  put_str(o, channel);
  o += ",\"type\":\"evpipe.stats_t\"";
  for_each_field(kStatsFields, [&](const auto& f) { put_field(o, f, r); });
  o += '}';
  return o;
}

std::string to_text(const PoseRecord& r, std::string_view channel) {
  const camera::WireQuaternion q = camera::to_wire(r.T_cam_model.q_cam_model);
  const Eigen::Vector3d& t = r.T_cam_model.t_cam_model_m;
  return fmt::format(
      "{} #{} t={:.6f} s {}{} t_m=[{:.4f} {:.4f} {:.4f}] q=[{:.5f} {:.5f} {:.5f} {:.5f}] measured_t={:.6f} s "
      "inliers={}/{} sigma={:.3f} px cov={} latency={} us{}",
      channel, r.seq, static_cast<double>(r.t_us) * 1e-6, to_string(r.status), r.pose_valid ? "" : " (invalid)", t.x(),
      t.y(), t.z(), q.qw, q.qx, q.qy, q.qz, static_cast<double>(r.t_last_update_us) * 1e-6, r.inliers, r.window_events,
      r.sigma_px, r.covariance_known ? "known" : "unknown", r.latency_us,
      r.source_connected ? "" : " SOURCE DISCONNECTED");
}

std::string to_text(const StatsRecord& r, std::string_view channel) {
  std::string o =
      fmt::format("{} #{} {} {} t={:.3f} s poses={} failures={} latency p50/p99={:.0f}/{:.0f} us", channel, r.seq,
                  r.source, r.source_connected ? "connected" : "DISCONNECTED", static_cast<double>(r.t_us) * 1e-6,
                  r.poses_published, r.publish_failures, r.latency_p50_us, r.latency_p99_us);
  for (const StageStatsRecord& s : r.stages) {
    fmt::format_to(std::back_inserter(o), " | {} in={} kept={} dropped={} p99={:.0f} us", s.name, s.events_in,
                   s.events_kept, s.events_dropped, s.proc_p99_us);
  }
  for (const QueueStatsRecord& q : r.queues) {
    fmt::format_to(std::back_inserter(o), " | {} {}/{} dropped={}", q.name, q.fill, q.capacity, q.dropped);
    if (q.events_budget > 0) fmt::format_to(std::back_inserter(o), " events={}/{}", q.events, q.events_budget);
  }
  for (const auto& [name, value] : r.denoise_figures) {
    if (name.ends_with("noise_rate_hz")) fmt::format_to(std::back_inserter(o), " | {}={:.3f}", name, value);
    if (name.ends_with("density_threshold_used")) fmt::format_to(std::back_inserter(o), " {}={:.0f}", name, value);
  }
  return o;
}

}  // namespace evpipe::transport
