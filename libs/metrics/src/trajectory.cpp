#include "evpipe/metrics/trajectory.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <Eigen/Cholesky>
#include <stdexcept>
#include <string>

namespace evpipe::metrics {
namespace {

bool sorted_by_time(std::span<const camera::StampedPose> poses) {
  return std::is_sorted(poses.begin(), poses.end(),
                        [](const camera::StampedPose& a, const camera::StampedPose& b) { return a.t_us < b.t_us; });
}

}  // namespace

bool is_confident_status(const std::string& status) {
  return status == "tracking" || status == "holding";
}

Eigen::Matrix<double, 6, 1> pose_error_vector(const camera::Pose& estimate, const camera::Pose& truth) {
  const Eigen::AngleAxisd aa(truth.q_cam_model * estimate.q_cam_model.conjugate());
  Eigen::Vector3d d = aa.angle() * aa.axis();
  if (aa.angle() > std::numbers::pi) d = (aa.angle() - 2.0 * std::numbers::pi) * aa.axis();
  Eigen::Matrix<double, 6, 1> e;
  e.head<3>() = d;
  e.tail<3>() = truth.t_cam_model_m - estimate.t_cam_model_m;
  return e;
}

std::optional<double> nees(const Eigen::Matrix<double, 6, 1>& e, const Eigen::Matrix<double, 6, 6>& P) {
  if (!P.allFinite() || !e.allFinite()) return std::nullopt;
  if ((P - P.transpose()).cwiseAbs().maxCoeff() > 1e-9 * std::max(1e-300, P.cwiseAbs().maxCoeff())) {
    return std::nullopt;
  }
  const Eigen::LLT<Eigen::Matrix<double, 6, 6>> llt(0.5 * (P + P.transpose()));
  if (llt.info() != Eigen::Success) return std::nullopt;
  const double v = e.dot(llt.solve(e));
  if (!std::isfinite(v) || v < 0) return std::nullopt;
  return v;
}

std::vector<camera::Pose> planar_rect_symmetries(const std::vector<Eigen::Vector3d>& points) {
  if (points.empty()) throw std::invalid_argument("planar_rect_symmetries: no model points");
  Eigen::Vector3d lo = points.front(), hi = points.front();
  for (const auto& p : points) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  if (hi.z() - lo.z() > 1e-9 * std::max(1.0, (hi - lo).norm())) {
    throw std::invalid_argument("planar_rect_symmetries: the model is not planar in z = const");
  }
  const Eigen::Vector3d c = 0.5 * (lo + hi);
  std::vector<camera::Pose> out;
  for (const Eigen::Vector3d& axis :
       {Eigen::Vector3d(Eigen::Vector3d::UnitZ()), Eigen::Vector3d(Eigen::Vector3d::UnitX()),
        Eigen::Vector3d(Eigen::Vector3d::UnitY())}) {
    camera::Pose S;  // p' = R (p - c) + c
    S.q_cam_model = Eigen::Quaterniond(Eigen::AngleAxisd(std::numbers::pi, axis));
    S.t_cam_model_m = c - S.q_cam_model * c;
    out.push_back(S);
  }
  return out;
}

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
                                   std::span<const std::string> status,
                                   std::span<const std::optional<Eigen::Matrix<double, 6, 6>>> covariance) {
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
  if (!covariance.empty() && covariance.size() != estimate.size()) {
    throw std::invalid_argument("evaluate_trajectory: " + std::to_string(covariance.size()) + " covariances for " +
                                std::to_string(estimate.size()) + " poses");
  }
  if (!(options.wrong_max_mm > 0) || !(options.wrong_max_deg > 0)) {
    throw std::invalid_argument("evaluate_trajectory: wrong_max_mm and wrong_max_deg must be > 0");
  }
  std::vector<camera::Pose> candidates{camera::Pose{}};
  candidates.insert(candidates.end(), options.symmetries.begin(), options.symmetries.end());

  TrajectoryEval r;
  r.poses_in = estimate.size();
  if (!status.empty()) {
    r.poses_tracking = static_cast<std::size_t>(std::count(status.begin(), status.end(), std::string("tracking")));
    r.poses_holding = static_cast<std::size_t>(std::count(status.begin(), status.end(), std::string("holding")));
  }
  std::vector<double> nees_values;
  std::vector<double> ate;
  std::vector<double> rot;
  std::vector<double> axis_abs[3];
  double axis_sum[3] = {0.0, 0.0, 0.0};
  for (std::size_t i = 0; i < estimate.size(); ++i) {
    if (options.only_tracking && !is_confident_status(status[i])) {
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
    const camera::Pose g0 = *truth_at(truth, e.t_us);
    // The equivalent truth closest to the estimate (relative to the wrong-pose thresholds).
    camera::Pose g = g0;
    std::size_t best_index = 0;
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < candidates.size(); ++k) {
      const camera::Pose gk = k == 0 ? g0 : g0 * candidates[k];
      const double score = std::max(camera::translation_distance_m(gk, e.pose) * 1000.0 / options.wrong_max_mm,
                                    camera::rotation_angle_deg(gk, e.pose) / options.wrong_max_deg);
      if (score < best) {
        best = score;
        g = gk;
        best_index = k;
      }
    }
    PoseError pe;
    pe.t_us = e.t_us;
    pe.t_est_m = e.pose.t_cam_model_m;
    pe.t_truth_m = g.t_cam_model_m;
    pe.error_mm = (pe.t_est_m - pe.t_truth_m) * 1000.0;
    pe.rotation_error_deg = camera::rotation_angle_deg(g, e.pose);
    pe.symmetry_index = best_index;
    pe.status = status.empty() ? std::string() : status[i];
    pe.confident = status.empty() || is_confident_status(status[i]);
    pe.wrong =
        pe.confident && (pe.error_mm.norm() > options.wrong_max_mm || pe.rotation_error_deg > options.wrong_max_deg);
    if (pe.confident) ++r.confident_evaluated;
    if (pe.wrong) ++r.wrong_confident;
    if (!covariance.empty() && covariance[i] && (status.empty() || status[i] == "tracking")) {
      pe.nees = nees(pose_error_vector(e.pose, g), *covariance[i]);
      if (pe.nees) {
        nees_values.push_back(*pe.nees);
      } else {
        ++r.nees_invalid;
      }
    }
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
  if (r.confident_evaluated > 0) {
    r.wrong_confident_share = static_cast<double>(r.wrong_confident) / static_cast<double>(r.confident_evaluated);
  }
  if (const auto ns = error_stats(nees_values)) {
    r.nees_count = ns->count;
    r.nees_mean = ns->mean;
    r.nees_median = ns->median;
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
