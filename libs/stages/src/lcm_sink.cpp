#include "evpipe/stages/lcm_sink.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "evpipe/stages/pose_processor.hpp"

namespace evpipe::stages {

LcmSink::LcmSink(transport::LcmPublisher* publisher, PoseProcessor* processor, bool live, bool keep_for_ate)
    : publisher_(publisher), processor_(processor), live_(live), keep_for_ate_(keep_for_ate) {}

transport::PoseRecord to_record(const pose::PoseEstimate& e, bool connected) {
  transport::PoseRecord r;
  r.t_us = e.t_us;
  r.t_last_update_us = e.t_last_update_us;
  r.status = e.status;
  r.pose_valid = e.pose_valid;
  r.T_cam_model = e.T_cam_model;
  r.covariance_known = e.covariance_known && e.pose_valid;
  if (r.covariance_known)
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j) r.covariance[static_cast<std::size_t>(6 * i + j)] = e.covariance(i, j);
  r.window_events = static_cast<std::int32_t>(e.window_events);
  r.inliers = static_cast<std::int32_t>(e.inliers);
  r.sigma_px = e.sigma_px;
  r.source_connected = connected;
  return r;
}

void LcmSink::publish_pose(const PoseSample& sample) {
  if (!processor_) return;  // nothing to say about poses without a pose stage; statistics still go out
  const auto& e = sample.estimate;
  last_t_us_ = e.t_us;
  processor_->write(e);
  if (e.pose_valid) {
    last_good_ = e.T_cam_model;
    if (keep_for_ate_) valid_poses_.push_back({e.t_us, e.T_cam_model});
  }
  if (publisher_) {
    auto r = to_record(e, true);
    r.newest_event_arrival = sample.newest_event_read;
    publisher_->publish_pose(r);
  }
  if (observer_)
    observer_->on_published(
        std::chrono::duration_cast<std::chrono::nanoseconds>(Clock::now() - sample.window_ready).count());
  ++poses_;
  const std::lock_guard lock(mutex_);
  latest_status_ = e.status;
}

void LcmSink::publish_stats(const PipelineStats& stats) {
  const auto state = stats.source.state;
  if (state != last_source_state_) {
    if (state == SourceState::lost) {
      spdlog::warn("camera lost (unplugged?); retrying; pose status LOST until it returns");
      // The controller must learn at once, not only when windows resume: a LOST pose message now.
      if (processor_ && publisher_) {
        pose::PoseEstimate lost;
        lost.status = pose::TrackStatus::lost;
        lost.t_us = last_t_us_;  // the last published pose's time; the device clock restarts on reconnect
        if (last_good_) lost.T_cam_model = *last_good_;
        lost.note = "camera lost";
        publisher_->publish_pose(to_record(lost, false));
      }
      const std::lock_guard lock(mutex_);
      latest_status_ = pose::TrackStatus::lost;
    } else if (state == SourceState::running && last_source_state_ == SourceState::lost) {
      spdlog::info("camera back (reconnect {}); re-initialising the pose", stats.source.reconnects);
    }
    last_source_state_ = state;
  }
  if (publisher_) {
    transport::StatsRecord r;
    r.uptime_us = static_cast<std::int64_t>(stats.elapsed_s * 1e6);
    r.source = live_ ? "live" : "replay";
    r.source_connected = state != SourceState::lost;
    r.source_reconnects = static_cast<std::int64_t>(stats.source.reconnects);
    {
      const std::lock_guard lock(mutex_);
      r.status = latest_status_;
    }
    r.latency_p50_us = static_cast<double>(stats.latency_event_to_publish_ns.p50) / 1e3;
    r.latency_p99_us = static_cast<double>(stats.latency_event_to_publish_ns.p99) / 1e3;
    for (const auto& s : stats.stages) {
      transport::StageStatsRecord st;
      st.name = s.name;
      st.events_in = static_cast<std::int64_t>(s.events_in);
      st.events_kept = static_cast<std::int64_t>(s.events_out);
      st.events_dropped = static_cast<std::int64_t>(s.events_dropped);
      st.packets_in = static_cast<std::int64_t>(s.items_in);
      st.busy_us = static_cast<std::int64_t>(s.step_ns.mean * static_cast<double>(s.step_ns.count) / 1e3);
      st.proc_p50_us = static_cast<double>(s.step_ns.p50) / 1e3;
      st.proc_p99_us = static_cast<double>(s.step_ns.p99) / 1e3;
      st.proc_max_us = static_cast<double>(s.step_ns.max) / 1e3;
      r.stages.push_back(std::move(st));
    }
    for (const auto& q : stats.queues) {
      transport::QueueStatsRecord qr;
      qr.name = q.name;
      qr.capacity = static_cast<std::int32_t>(q.capacity);
      qr.fill = static_cast<std::int32_t>(q.fill);
      qr.fill_max = static_cast<std::int32_t>(q.high_water);
      qr.pushed = static_cast<std::int64_t>(q.pushed);
      qr.dropped = static_cast<std::int64_t>(q.dropped);
      if (q.weight_budget > 0) {
        qr.events_budget = static_cast<std::int64_t>(q.weight_budget);
        qr.events = static_cast<std::int64_t>(q.weight_fill);
        qr.events_max = static_cast<std::int64_t>(q.weight_high_water);
      }
      r.queues.push_back(std::move(qr));
    }
    for (const auto& item : stats.denoise_report) r.denoise_figures.emplace_back(item.key, item.value);
    publisher_->publish_stats(r);
  }
  const std::lock_guard lock(mutex_);
  latest_stats_ = stats;
}

std::optional<PipelineStats> LcmSink::latest_stats() const {
  const std::lock_guard lock(mutex_);
  return latest_stats_;
}

pose::TrackStatus LcmSink::latest_status() const {
  const std::lock_guard lock(mutex_);
  return latest_status_;
}

std::string status_line(const PipelineStats& s, pose::TrackStatus status, bool pose_on) {
  std::uint64_t dropped = 0;
  for (const auto& q : s.queues) dropped += q.dropped;
  std::string line = fmt::format("source {}, {} ev in, {} kept, {} dropped packets/windows", state_name(s.source.state),
                                 s.denoise_events_in, s.denoise_events_kept, dropped);
  if (pose_on) line += fmt::format(", pose {} ({} published)", pose::to_string(status), s.poses_published);
  return line;
}

}  // namespace evpipe::stages
