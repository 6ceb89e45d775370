#include "summary.hpp"

#include "evpipe/core/json_quote.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace evpipe::app {

namespace {

std::string rate(double hz) {
  if (hz >= 1e6) return fmt::format("{:.2f} Mev/s", hz / 1e6);
  if (hz >= 1e3) return fmt::format("{:.1f} kev/s", hz / 1e3);
  return fmt::format("{:.0f} ev/s", hz);
}

double percentile(std::vector<double> v, double q) {
  if (v.empty()) return 0.0;
  const auto k = static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5);
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}

double share(std::uint64_t part, std::uint64_t whole) {
  return whole ? static_cast<double>(part) / static_cast<double>(whole) : 0.0;
}

// Pose updates per second of sensor time between the first and the last valid pose.
double update_rate_hz(const stages::PoseSummary& p) {
  const auto span_us = p.last_valid_t_us - p.first_valid_t_us;
  return p.valid_poses > 1 && span_us > 0 ? 1e6 * static_cast<double>(p.valid_poses - 1) / static_cast<double>(span_us)
                                          : 0.0;
}

}  // namespace

std::string format_text(const RunSummary& s) {
  const auto& st = *s.stream;
  std::string o;
  auto line = [&o](const char* k, const std::string& v) { o += fmt::format("  {:<18}{}\n", k, v); };
  o += s.error.empty() ? (s.interrupted ? "evpipe summary (interrupted)\n" : "evpipe summary\n")
                       : "evpipe summary (stopped on an error)\n";
  line("source", fmt::format("{} ({})", s.info.name, s.info.format));
  line("resolution", fmt::format("{} x {}{}", s.info.geometry.width, s.info.geometry.height,
                                 s.info.geometry_known ? "" : " (assumed: not stated by the source)"));
  line("events", fmt::format("{}", st.events()));
  if (st.first_t_us())
    line("duration", fmt::format("{:.6f} s  (t {} .. {} us)", static_cast<double>(st.duration_us()) / 1e6,
                                 *st.first_t_us(), *st.last_t_us()));
  else
    line("duration", "0 s (no events)");
  line("mean rate", rate(st.mean_rate_hz()));
  line("peak rate", fmt::format("{} (busiest {} ms)", rate(st.peak_rate_hz()), st.peak_bin_us() / 1000));
  line("ON share", fmt::format("{:.1f} %", 100.0 * st.on_share()));
  line("out-of-order", fmt::format("{}{}", s.source.out_of_order,
                                   s.source.out_of_order ? (s.out_of_order_dropped ? " (dropped)" : " (kept)") : ""));
  line("discontinuities", fmt::format("{}", s.source.discontinuities));
  line("skipped non-DVS", fmt::format("{}", s.source.skipped_non_dvs));
  if (s.source.invalid_events) line("invalid events", fmt::format("{}", s.source.invalid_events));
  line("corrupt packets", fmt::format("{}", s.source.corrupt_packets));
  if (s.source.truncated_bytes) line("truncated bytes", fmt::format("{}", s.source.truncated_bytes));
  if (s.source.dropped_packets || s.source.dropped_events)
    line("dropped", fmt::format("{} packets, {} events", s.source.dropped_packets, s.source.dropped_events));
  if (s.denoise_filter == "none")
    line("denoise", "none");
  else
    line("denoise",
         fmt::format("{}: kept {} of {} ({:.1f} %), decision latency {} ms", s.denoise_filter, s.denoise_kept,
                     s.denoise_in, s.denoise_in ? 100.0 * static_cast<double>(s.denoise_kept) / s.denoise_in : 0.0,
                     s.denoise_latency_us / 1000.0));
  if (!s.denoise_report.empty()) {
    std::string figures;
    for (const auto& [key, value] : s.denoise_report) {
      const bool whole = std::abs(value) < 1e15 && value == std::floor(value);
      figures += fmt::format("{}{} {}", figures.empty() ? "" : ", ", key,
                             whole ? fmt::format("{:.0f}", value) : fmt::format("{:.3f}", value));
    }
    line("denoise figures", figures);
  }
  line("windows", fmt::format("{} of {} ms, hop {} ms ({} events)", s.windows, s.window_us / 1000.0, s.hop_us / 1000.0,
                              s.window_events));
  if (s.pose.enabled) {
    const auto& p = s.pose;
    line("poses", fmt::format("{} valid of {} windows ({:.1f} Hz of sensor time), each stamped at its window's middle "
                              "(t_us = window start + {} ms)",
                              p.valid_poses, p.windows, update_rate_hz(p), s.window_us / 2000.0));
    line("pose status",
         fmt::format("initialising {:.1f} %, tracking {:.1f} %, holding {:.1f} %, lost {:.1f} %",
                     100 * share(p.windows_by_status[0], p.windows), 100 * share(p.windows_by_status[1], p.windows),
                     100 * share(p.windows_by_status[3], p.windows), 100 * share(p.windows_by_status[2], p.windows)));
    if (p.holds > 0) {
      line("standstill", fmt::format("{} holds (the target still, its last measured pose repeated), {} resumed "
                                     "tracking from the held pose",
                                     p.holds, p.hold_resumes));
    }
    line("initialisation",
         fmt::format("{} of {} attempts succeeded, {} losses; first took {:.1f} ms ({})", p.init_successes,
                     p.init_attempts, p.losses, p.first_init_ms, p.init_worker ? "on a worker thread" : "in line"));
    line("pose update", fmt::format("p50 {:.3f} ms, p99 {:.3f} ms compute per window", percentile(p.update_ms, 0.5),
                                    percentile(p.update_ms, 0.99)));
    if (p.valid_poses == 0 && !p.last_note.empty()) line("no pose", p.last_note);
    if (!p.poses_out.empty()) line("poses written", p.poses_out);
  }
  std::string drops;
  for (const auto& [name, n] : s.queue_drops) drops += fmt::format("{}{} {}", drops.empty() ? "" : ", ", name, n);
  if (!drops.empty()) line("queue drops", drops);
  if (s.pose.enabled)
    line("latency",
         fmt::format("event → LCM p50 {:.2f} ms, p99 {:.2f} ms; window end → LCM p50 {:.3f} ms, p99 {:.3f} ms, "
                     "max {:.3f} ms",
                     s.latency_event_ms_p50, s.latency_event_ms_p99, s.latency_window_ms_p50, s.latency_window_ms_p99,
                     s.latency_window_ms_max));
  if (!s.lcm_url.empty())
    line("LCM", fmt::format("{} pose and {} statistics messages on {}{}", s.lcm_poses, s.lcm_stats, s.lcm_url,
                            s.lcm_failures ? fmt::format(" ({} not sent)", s.lcm_failures) : ""));
  if (s.ground_truth_given) {
    if (s.ate_poses)
      line("ATE", fmt::format("RMSE {:.2f} mm, mean {:.2f}, median {:.2f}, std {:.2f}, max {:.2f} mm; rotation RMSE "
                              "{:.3f} deg ({} poses)",
                              s.ate_mm.rmse, s.ate_mm.mean, s.ate_mm.median, s.ate_mm.std, s.ate_mm.max,
                              s.rotation_deg.rmse, s.ate_poses));
    else
      line("ATE", "no valid pose inside the ground truth's time span");
  }
  line("wall time",
       fmt::format("{:.3f} s ({})", s.wall_s, rate(s.wall_s > 0 ? static_cast<double>(st.events()) / s.wall_s : 0.0)));
  if (!s.error.empty()) line("error", s.error);
  return o;
}

namespace {
std::string pose_json(const stages::PoseSummary& p) {
  if (!p.enabled) return ",\"pose_enabled\":false";
  return fmt::format(
      ",\"pose_enabled\":true,\"pose_windows\":{},\"pose_updates\":{},\"pose_rate_hz\":{:.3f},"
      "\"pose_initialising_share\":{:.6f},\"pose_tracking_share\":{:.6f},\"pose_holding_share\":{:.6f},"
      "\"pose_lost_share\":{:.6f},\"pose_holds\":{},\"pose_hold_resumes\":{},"
      "\"pose_init_attempts\":{},\"pose_init_successes\":{},\"pose_losses\":{},\"pose_init_ms\":{:.3f},"
      "\"pose_init_worker\":{},"
      "\"pose_update_ms_p50\":{:.4f},\"pose_update_ms_p99\":{:.4f},\"pose_update_ms_max\":{:.4f},\"pose_note\":{}",
      p.windows, p.valid_poses, update_rate_hz(p), share(p.windows_by_status[0], p.windows),
      share(p.windows_by_status[1], p.windows), share(p.windows_by_status[3], p.windows),
      share(p.windows_by_status[2], p.windows), p.holds, p.hold_resumes, p.init_attempts, p.init_successes, p.losses,
      p.first_init_ms, p.init_worker, percentile(p.update_ms, 0.5), percentile(p.update_ms, 0.99),
      percentile(p.update_ms, 1.0), json_quote(p.last_note));
}
}  // namespace

namespace {
std::string pipeline_json(const RunSummary& s) {
  std::string o = ",\"denoise_figures\":{";
  for (std::size_t i = 0; i < s.denoise_report.size(); ++i) {
    const double v = s.denoise_report[i].second;
    o += fmt::format("{}{}:{}", i ? "," : "", json_quote(s.denoise_report[i].first),
                     std::isfinite(v) ? fmt::format("{}", v) : std::string("null"));
  }
  o += "},\"queue_drops\":{";
  for (std::size_t i = 0; i < s.queue_drops.size(); ++i)
    o += fmt::format("{}{}:{}", i ? "," : "", json_quote(s.queue_drops[i].first), s.queue_drops[i].second);
  o += fmt::format(
      "}},\"latency_event_ms_p50\":{:.4f},\"latency_event_ms_p99\":{:.4f},\"latency_window_ms_p50\":{:.4f},"
      "\"latency_window_ms_p99\":{:.4f},\"latency_window_ms_max\":{:.4f},\"lcm_url\":{},\"lcm_poses\":{},"
      "\"lcm_stats\":{},\"lcm_failures\":{}",
      s.latency_event_ms_p50, s.latency_event_ms_p99, s.latency_window_ms_p50, s.latency_window_ms_p99,
      s.latency_window_ms_max, json_quote(s.lcm_url), s.lcm_poses, s.lcm_stats, s.lcm_failures);
  if (s.ground_truth_given && s.ate_poses)
    o += fmt::format(
        ",\"ate_poses\":{},\"ate_rmse_mm\":{:.4f},\"ate_mean_mm\":{:.4f},\"ate_median_mm\":{:.4f},"
        "\"ate_std_mm\":{:.4f},\"ate_max_mm\":{:.4f},\"rotation_rmse_deg\":{:.5f},\"rotation_max_deg\":{:.5f}",
        s.ate_poses, s.ate_mm.rmse, s.ate_mm.mean, s.ate_mm.median, s.ate_mm.std, s.ate_mm.max, s.rotation_deg.rmse,
        s.rotation_deg.max);
  else if (s.ground_truth_given)
    o += ",\"ate_poses\":0";
  return o;
}
}  // namespace

std::string format_json(const RunSummary& s) {
  const auto& st = *s.stream;
  return fmt::format(
      "{{\"source\":{},\"format\":\"{}\",\"width\":{},\"height\":{},\"geometry_known\":{},"
      "\"events\":{},\"on_events\":{},\"first_t_us\":{},\"last_t_us\":{},\"duration_us\":{},"
      "\"mean_rate_hz\":{:.3f},\"peak_rate_hz\":{:.3f},\"peak_bin_us\":{},\"on_share\":{:.6f},"
      "\"out_of_order\":{},\"out_of_order_dropped\":{},\"discontinuities\":{},\"skipped_non_dvs\":{},"
      "\"invalid_events\":{},\"corrupt_packets\":{},\"truncated_bytes\":{},\"dropped_packets\":{},"
      "\"dropped_events\":{},\"denoise_filter\":{},\"denoise_in\":{},\"denoise_kept\":{},"
      "\"denoise_latency_us\":{},\"windows\":{},\"window_events\":{},\"window_us\":{},\"hop_us\":{},"
      "\"wall_s\":{:.6f},\"interrupted\":{},\"error\":{}{}}}\n",
      json_quote(s.info.name), s.info.format, s.info.geometry.width, s.info.geometry.height, s.info.geometry_known,
      st.events(), st.on_events(), st.first_t_us() ? fmt::format("{}", *st.first_t_us()) : "null",
      st.last_t_us() ? fmt::format("{}", *st.last_t_us()) : "null", st.duration_us(), st.mean_rate_hz(),
      st.peak_rate_hz(), st.peak_bin_us(), st.on_share(), s.source.out_of_order, s.out_of_order_dropped,
      s.source.discontinuities, s.source.skipped_non_dvs, s.source.invalid_events, s.source.corrupt_packets,
      s.source.truncated_bytes, s.source.dropped_packets, s.source.dropped_events, json_quote(s.denoise_filter),
      s.denoise_in, s.denoise_kept, s.denoise_latency_us, s.windows, s.window_events, s.window_us, s.hop_us, s.wall_s,
      s.interrupted, json_quote(s.error), pose_json(s.pose) + pipeline_json(s));
}

}  // namespace evpipe::app
