#pragma once
// The end-of-run summary evpipe prints (text for people, JSON for scripts and tests).

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "evpipe/core/source.hpp"
#include "evpipe/core/stream_stats.hpp"
#include "evpipe/metrics/trajectory.hpp"
#include "evpipe/stages/pose_processor.hpp"

namespace evpipe::app {

struct RunSummary {
  SourceInfo info;
  SourceStats source;
  const StreamStats* stream = nullptr;
  std::string denoise_filter = "none";  ///< filter or chain of the denoise stage
  std::uint64_t denoise_in = 0;         ///< events into the denoise stage
  std::uint64_t denoise_kept = 0;       ///< events it kept
  std::int64_t denoise_latency_us = 0;  ///< its look-ahead (sensor time an event waits for its decision)
  /// The filter's own figures at the end (denoise::Filter::report(); curvature: noise_rate_hz,
  /// density_threshold_used, ...).
  std::vector<std::pair<std::string, double>> denoise_report;
  std::uint64_t windows = 0;        ///< windows of kept events
  std::uint64_t window_events = 0;  ///< events counted in those windows
  std::int64_t window_us = 0;
  std::int64_t hop_us = 0;
  double wall_s = 0;
  bool interrupted = false;
  std::string error;  ///< non-empty when the run stopped on an error
  bool out_of_order_dropped = true;
  stages::PoseSummary pose;
  std::vector<std::pair<std::string, std::uint64_t>> queue_drops;  ///< per queue: items dropped (live policy)
  double latency_event_ms_p50 = 0, latency_event_ms_p99 = 0;       ///< newest event read → pose published
  double latency_window_ms_p50 = 0, latency_window_ms_p99 = 0;     ///< window complete → pose published
  double latency_window_ms_max = 0;                                ///< the slowest window
  std::string lcm_url;                                             ///< empty: LCM off
  std::uint64_t lcm_poses = 0, lcm_stats = 0, lcm_failures = 0;
  bool ground_truth_given = false;
  std::size_t ate_poses = 0;
  metrics::ErrorStats ate_mm;        ///< translation error of the valid poses, mm
  metrics::ErrorStats rotation_deg;  ///< rotation error, degrees
};

std::string format_text(const RunSummary& s);
std::string format_json(const RunSummary& s);

}  // namespace evpipe::app
