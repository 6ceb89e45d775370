#include "evpipe/metrics/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace evpipe::metrics {
namespace {

bool sorted_by_time(std::span<const camera::StampedPose> poses) {
  return std::is_sorted(poses.begin(), poses.end(),
                        [](const camera::StampedPose& a, const camera::StampedPose& b) { return a.t_us < b.t_us; });
}

}  // namespace

std::optional<ErrorStats> error_stats(std::span<const double> values) {
  if (values.empty()) return std::nullopt;
  ErrorStats s;
  s.count = values.size();
  const double n = static_cast<double>(values.size());
  double sum = 0.0;
  double sum_sq = 0.0;
  for (const double v : values) {
    sum += v;
    sum_sq += v * v;
  }
  s.mean = sum / n;
  s.rmse = std::sqrt(sum_sq / n);
  // Two-pass variance: sum_sq/n - mean^2 cancels badly when the errors are nearly constant.
  double var = 0.0;
  for (const double v : values) var += (v - s.mean) * (v - s.mean);
  s.std = std::sqrt(var / n);
  std::vector<double> sorted(values.begin(), values.end());
  std::sort(sorted.begin(), sorted.end());
  const std::size_t mid = sorted.size() / 2;
  s.median = sorted.size() % 2 == 1 ? sorted[mid] : 0.5 * (sorted[mid - 1] + sorted[mid]);
  s.max = sorted.back();
  return s;
}

std::optional<camera::Pose> truth_at(std::span<const camera::StampedPose> truth, std::int64_t t_us) {
  if (truth.empty() || t_us < truth.front().t_us || t_us > truth.back().t_us) return std::nullopt;
  // First row strictly after t_us; the one before it is at or before t_us (as camera::interpolate on a vector).
  const auto after = std::upper_bound(truth.begin(), truth.end(), t_us,
                                      [](std::int64_t t, const camera::StampedPose& sp) { return t < sp.t_us; });
  const camera::StampedPose& before = *(after - 1);
  if (before.t_us == t_us || after == truth.end()) return before.pose;
  return camera::interpolate(before, *after, t_us);
}

TrajectoryEval evaluate_trajectory(std::span<const camera::StampedPose> estimate,
                                   std::span<const camera::StampedPose> truth, const TrajectoryEvalOptions& options,
                                   std::span<const std::string> status) {
  if (!sorted_by_time(estimate)) throw std::invalid_argument("evaluate_trajectory: estimate not sorted by t_us");
  if (!sorted_by_time(truth)) throw std::invalid_argument("evaluate_trajectory: truth not sorted by t_us");
  if (!status.empty() && status.size() != estimate.size()) {
    throw std::invalid_argument("evaluate_trajectory: " + std::to_string(status.size()) + " statuses for " +
                                std::to_string(estimate.size()) + " poses");
  }
  if (options.only_tracking && status.empty() && !estimate.empty()) {
    throw std::invalid_argument("evaluate_trajectory: only_tracking needs a status per pose");
  }
  if (options.max_gap_us < 0) throw std::invalid_argument("evaluate_trajectory: max_gap_us < 0");

  TrajectoryEval r;
  r.poses_in = estimate.size();
  if (!status.empty()) {
    r.poses_tracking = static_cast<std::size_t>(std::count(status.begin(), status.end(), std::string("tracking")));
  }
  std::vector<double> ate;
  std::vector<double> rot;
  std::vector<double> axis_abs[3];
  double axis_sum[3] = {0.0, 0.0, 0.0};
  for (std::size_t i = 0; i < estimate.size(); ++i) {
    if (options.only_tracking && status[i] != "tracking") {
      ++r.poses_not_tracking;
      continue;
    }
    const camera::StampedPose& e = estimate[i];
    if (truth.empty() || e.t_us < truth.front().t_us) {
      ++r.poses_before_truth;
      continue;
    }
    if (e.t_us > truth.back().t_us) {
      ++r.poses_after_truth;
      continue;
    }
    const camera::Pose g = *truth_at(truth, e.t_us);
    PoseError pe;
    pe.t_us = e.t_us;
    pe.t_est_m = e.pose.t_cam_model_m;
    pe.t_truth_m = g.t_cam_model_m;
    pe.error_mm = (pe.t_est_m - pe.t_truth_m) * 1000.0;
    pe.rotation_error_deg = camera::rotation_angle_deg(g, e.pose);
    ate.push_back(pe.error_mm.norm());
    rot.push_back(pe.rotation_error_deg);
    for (int a = 0; a < 3; ++a) {
      axis_abs[a].push_back(std::abs(pe.error_mm[a]));
      axis_sum[a] += pe.error_mm[a];
    }
    r.samples.push_back(pe);
  }
  r.poses_evaluated = r.samples.size();

  const std::size_t considered = r.poses_evaluated + r.poses_before_truth + r.poses_after_truth;
  if (considered > 0) r.matched_fraction = static_cast<double>(r.poses_evaluated) / static_cast<double>(considered);
  if (!truth.empty() && truth.back().t_us > truth.front().t_us) {
    std::int64_t covered_us = 0;
    for (std::size_t i = 1; i < r.samples.size(); ++i) {
      const std::int64_t gap_us = r.samples[i].t_us - r.samples[i - 1].t_us;
      if (gap_us <= options.max_gap_us) covered_us += gap_us;
    }
    r.time_coverage = static_cast<double>(covered_us) / static_cast<double>(truth.back().t_us - truth.front().t_us);
  }
  if (!r.samples.empty()) {
    r.first_pose_delay_ms = static_cast<double>(r.samples.front().t_us - truth.front().t_us) / 1000.0;
    r.ate_mm = error_stats(ate);
    r.rotation_deg = error_stats(rot);
    for (int a = 0; a < 3; ++a) {
      r.axis_mm[a] = AxisStats{axis_sum[a] / static_cast<double>(r.samples.size()), *error_stats(axis_abs[a])};
    }
  }
  return r;
}

}  // namespace evpipe::metrics
