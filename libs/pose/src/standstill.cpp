#include "evpipe/pose/standstill.hpp"

#include "pose_spread.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

namespace evpipe::pose {

double poisson_upper_tail(std::uint64_t n, double mu) noexcept {
  if (n == 0) return 1.0;
  if (!(mu > 0.0)) return 0.0;
  const double nd = static_cast<double>(n);
  if (nd <= mu) return 1.0;
  // sum_{k >= n} e^-mu mu^k / k!: the terms fall from k = n on (n > mu).
  double term = std::exp(-mu + nd * std::log(mu) - std::lgamma(nd + 1.0));
  double sum = 0.0;
  for (double k = nd; k < nd + 100000.0; k += 1.0) {
    sum += term;
    term *= mu / (k + 1.0);
    if (term <= sum * 1e-12) break;
  }
  return std::min(sum, 1.0);
}

PoseChangePerPx pose_change_per_px(const camera::CameraModel& camera, const camera::LineModel& model,
                                   const camera::Pose& T) {
  // H = mean over the edge pixels of g g^T, g the change of a point's distance across its edge (pixels) per left
  // increment of the pose [dtheta, dt] (types.hpp); a pose change delta moves the edges by delta^T H delta px^2
  // (mean square); the largest rotation (translation) with delta^T H delta = 1 is the pose spread of H.
  using Vector6d = Eigen::Matrix<double, 6, 1>;
  const double f = 0.5 * (camera.fx + camera.fy);
  const Eigen::Matrix3d R = T.rotation();
  const std::vector<ProjectedSegment> segs = project_model(camera, model, T);
  Covariance6 H = Covariance6::Zero();
  double n_points = 0.0, depth = 0.0;
  for (const ProjectedSegment& s : segs) {
    const Eigen::Vector2d d = s.b_n - s.a_n;
    if (!(d.norm() > 0.0)) continue;
    const Eigen::Vector2d normal(-d.y() / d.norm(), d.x() / d.norm());
    const int n = std::max(2, static_cast<int>(std::ceil(s.length_px)));
    for (int i = 0; i < n; ++i) {
      const double a = (static_cast<double>(i) + 0.5) / static_cast<double>(n);
      const Eigen::Vector3d Q = R * (s.a_m + a * (s.b_m - s.a_m));
      const Eigen::Vector3d P = Q + T.t_cam_model_m;
      if (!(P.z() > 0.0)) continue;
      Eigen::Matrix<double, 2, 3> Jp;
      Jp << 1.0 / P.z(), 0.0, -P.x() / (P.z() * P.z()), 0.0, 1.0 / P.z(), -P.y() / (P.z() * P.z());
      Eigen::Matrix<double, 3, 6> dP;
      dP.leftCols<3>() << 0.0, Q.z(), -Q.y(), -Q.z(), 0.0, Q.x(), Q.y(), -Q.x(), 0.0;  // -[Q]x
      dP.rightCols<3>() = Eigen::Matrix3d::Identity();
      const Vector6d g = f * (normal.transpose() * Jp * dP).transpose();
      H.noalias() += g * g.transpose();
      n_points += 1.0;
      depth += P.z();
    }
  }
  if (n_points < 1.0) return {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
  const detail::PoseSpread spread = detail::pose_spread(H / n_points, depth / n_points);
  return {spread.rotation_deg, spread.translation_m};
}

void StandstillMonitor::stop() noexcept {
  cls_.clear();
  acc_near_ = acc_ring_ = acc_far_ = acc_exposure_s_ = 0.0;
}

bool StandstillMonitor::start(const camera::CameraModel& camera, const UndistortMap& map,
                              const camera::LineModel& model, const camera::Pose& T_cam_model,
                              const StandstillOptions& options) {
  stop();
  o_ = options;
  width_ = camera.width;
  height_ = camera.height;
  (void)map;
  const std::vector<ProjectedSegment> segs = project_model(camera, model, T_cam_model);
  if (segs.empty() || width_ <= 0 || height_ <= 0) return false;
  // The projected edges drawn as polylines through the distorted image of each visible part, then the distance
  // of every pixel to the nearest drawn edge pixel.
  cv::Mat edges(height_, width_, CV_8U, cv::Scalar(255));
  length_px_ = 0.0;
  for (const ProjectedSegment& s : segs) {
    length_px_ += s.length_px;
    const int n = std::max(2, static_cast<int>(std::ceil(s.length_px)));
    cv::Point prev;
    for (int i = 0; i <= n; ++i) {
      const Eigen::Vector2d px = camera.normalised_to_pixel(s.a_n + (s.b_n - s.a_n) * (double(i) / n));
      const cv::Point p(static_cast<int>(std::lround(px.x())), static_cast<int>(std::lround(px.y())));
      if (i > 0) cv::line(edges, prev, p, cv::Scalar(0));
      prev = p;
    }
  }
  cv::Mat dist;
  cv::distanceTransform(edges, dist, cv::DIST_L2, cv::DIST_MASK_PRECISE);
  const auto n_px = static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_);
  cls_.assign(n_px, 0);
  stamp_.assign(n_px, 0);
  cells_x_ = (width_ + o_.cell_px - 1) / o_.cell_px;
  cells_y_ = (height_ + o_.cell_px - 1) / o_.cell_px;
  cell_far_area_.assign(static_cast<std::size_t>(cells_x_ * cells_y_), 0);
  cell_count_.assign(cell_far_area_.size(), 0);
  cell_band_area_.assign(cell_far_area_.size(), 0);
  cell_band_count_.assign(cell_far_area_.size(), 0);
  area_near_ = area_ring_ = area_far_ = 0.0;
  for (int y = 0; y < height_; ++y) {
    for (int x = 0; x < width_; ++x) {
      const float d = dist.at<float>(y, x);
      std::uint8_t c = 3;
      if (d <= o_.band_px) {
        c = 1;
        area_near_ += 1.0;
      } else if (d <= o_.gate_px) {
        c = 2;
        area_ring_ += 1.0;
      } else if (d > o_.far_px) {
        c = d <= o_.background_px ? 4 : 0;
        const auto cell = static_cast<std::size_t>((y / o_.cell_px) * cells_x_ + x / o_.cell_px);
        if (c == 4) {
          area_far_ += 1.0;
          ++cell_band_area_[cell];
        }
        ++cell_far_area_[cell];
      }
      cls_[static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) + static_cast<std::size_t>(x)] = c;
    }
  }
  window_id_ = 0;
  return length_px_ > 0.0;
}

double StandstillMonitor::background_rate(double window_s) const {
  // Poisson noise is uniform: a band cell far above the rate the others give holds structure (clutter, a hot pixel,
  // flicker), not noise. Leave out such cells (Bonferroni over the cells) and re-estimate until none is left out;
  // the rate only falls, so the loop ends.
  const double alpha = o_.significance / static_cast<double>(std::max<std::size_t>(cell_band_area_.size(), 1));
  std::vector<bool> out(cell_band_area_.size(), false);
  double rate = 0.0;
  for (bool changed = true; changed;) {
    double n = 0.0, area = 0.0;
    for (std::size_t c = 0; c < cell_band_area_.size(); ++c) {
      if (out[c]) continue;
      n += cell_band_count_[c];
      area += cell_band_area_[c];
    }
    // One pseudo-event, as the hold's rate: no event still means a finite rate.
    rate = (n + 1.0) / (std::max(area, 1.0) * window_s);
    changed = false;
    for (std::size_t c = 0; c < cell_band_area_.size(); ++c) {
      if (out[c] || cell_band_count_[c] < 2) continue;
      if (poisson_upper_tail(cell_band_count_[c], rate * cell_band_area_[c] * window_s) < alpha) {
        out[c] = true;
        changed = true;
      }
    }
  }
  return rate;
}

StandstillEvidence StandstillMonitor::observe(EventSpan window, std::int64_t window_us, std::int64_t fresh_from_us,
                                              std::int64_t fresh_us) {
  StandstillEvidence ev;
  if (!active()) return ev;
  if (++window_id_ == 0) {  // wrapped: clear the stamps
    std::fill(stamp_.begin(), stamp_.end(), 0);
    window_id_ = 1;
  }
  std::fill(cell_count_.begin(), cell_count_.end(), 0);
  std::fill(cell_band_count_.begin(), cell_band_count_.end(), 0);
  std::size_t fresh_near = 0, fresh_ring = 0, fresh_far = 0;
  for (const Event& e : window) {
    if (e.x >= width_ || e.y >= height_) continue;
    const std::size_t i = static_cast<std::size_t>(e.y) * static_cast<std::size_t>(width_) + e.x;
    const bool fresh = e.t_us >= fresh_from_us;
    const auto cell = static_cast<std::size_t>((e.y / o_.cell_px) * cells_x_ + e.x / o_.cell_px);
    switch (cls_[i]) {
      case 4:
        ++ev.far;
        fresh_far += fresh;
        ++cell_band_count_[cell];
        [[fallthrough]];
      case 0:
        if (stamp_[i] != window_id_) {
          stamp_[i] = window_id_;
          ++cell_count_[cell];
        }
        break;
      case 1:
        ++ev.near;
        fresh_near += fresh;
        break;
      case 2:
        ++ev.ring;
        fresh_ring += fresh;
        break;
      default:
        break;
    }
  }
  const double keep = std::exp(-1e-6 * static_cast<double>(std::max<std::int64_t>(fresh_us, 0)) / o_.memory_s);
  acc_near_ *= keep;
  acc_ring_ *= keep;
  acc_far_ *= keep;
  acc_exposure_s_ *= keep;
  acc_near_ += static_cast<double>(fresh_near);
  acc_ring_ += static_cast<double>(fresh_ring);
  acc_far_ += static_cast<double>(fresh_far);
  acc_exposure_s_ += 1e-6 * static_cast<double>(std::max<std::int64_t>(fresh_us, 0));
  const double window_s = 1e-6 * static_cast<double>(std::max<std::int64_t>(window_us, 1));
  // The noise rate over the hold so far (one pseudo-event: no event at all still means a finite rate).
  const double exposure_s = std::max(acc_exposure_s_, window_s);
  ev.noise_rate_hz = (acc_far_ + 1.0) / (std::max(area_far_, 1.0) * exposure_s);
  ev.background_rate_hz = background_rate(window_s);
  ev.expected_near = ev.noise_rate_hz * area_near_ * window_s;
  ev.expected_ring = ev.noise_rate_hz * area_ring_ * window_s;
  const auto moving = [&](double n_near, double n_ring, double t_s, double& implied) {
    const double mu_near = ev.noise_rate_hz * area_near_ * t_s, mu_ring = ev.noise_rate_hz * area_ring_ * t_s;
    implied = std::max(0.0, n_near - mu_near + n_ring - mu_ring) / std::max(length_px_, 1.0);
    const bool significant =
        poisson_upper_tail(static_cast<std::uint64_t>(n_near), mu_near) < o_.significance ||
        poisson_upper_tail(static_cast<std::uint64_t>(n_ring), mu_ring) < o_.significance ||
        poisson_upper_tail(static_cast<std::uint64_t>(n_near + n_ring), mu_near + mu_ring) < o_.significance;
    return significant && implied > o_.max_motion_px;
  };
  // Motion along an edge makes no events, so the length bound can miss the motion of a target whose moving edges
  // are few: a window's significant excess of min_motion_events or more is worth a measurement in any case.
  const double excess_window = static_cast<double>(ev.near + ev.ring) - ev.expected_near - ev.expected_ring;
  ev.signal = poisson_upper_tail(ev.near, ev.expected_near) < o_.significance;
  double implied_window = 0.0, implied_hold = 0.0;
  const bool moving_window =
      moving(static_cast<double>(ev.near), static_cast<double>(ev.ring), window_s, implied_window) ||
      (excess_window >= o_.min_motion_events &&
       poisson_upper_tail(ev.near + ev.ring, ev.expected_near + ev.expected_ring) < o_.significance);
  const bool moving_hold = moving(acc_near_, acc_ring_, exposure_s, implied_hold);
  ev.implied_motion_px = std::max(implied_window, implied_hold);
  ev.moving = moving_window || moving_hold;
  // Activity elsewhere: distinct active far pixels per cell against 1 - exp(-rate t) per pixel.
  const double p_active = 1.0 - std::exp(-ev.noise_rate_hz * window_s);
  const double alpha = o_.significance / static_cast<double>(std::max<std::size_t>(cell_count_.size(), 1));
  for (std::size_t c = 0; c < cell_count_.size() && !ev.unexplained; ++c) {
    if (cell_count_[c] < 2) continue;
    ev.unexplained = poisson_upper_tail(cell_count_[c], p_active * cell_far_area_[c]) < alpha;
  }
  return ev;
}

}  // namespace evpipe::pose
