// ELOPET-style tracking (paper §3.3, eqs. 37-45; docs/algorithms.md "Tracking"): rounds of
// associate -> S-scale -> IRLS Levenberg-Marquardt with Tukey 4.685 weights at the fixed S-scale, then the
// covariance and the health of the result.

#include "evpipe/pose/tracker.hpp"

#include "evpipe/pose/mm_estimator.hpp"
#include "evpipe/pose/robust_loss.hpp"
#include "pose_spread.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include <fmt/format.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <numbers>
#include <vector>

namespace evpipe::pose {

namespace {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;
using Matrix36d = Eigen::Matrix<double, 3, 6>;

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

// The pose moved by a left increment: R <- exp([dθ]x) R, t <- t + dt (types.hpp's covariance convention).
camera::Pose apply_increment(const camera::Pose& T, const Vector6d& delta) {
  const Eigen::Vector3d dtheta = delta.head<3>();
  const double angle = dtheta.norm();
  camera::Pose out = T;
  if (angle > 0.0) {
    out.q_cam_model = (Eigen::Quaterniond(Eigen::AngleAxisd(angle, dtheta / angle)) * T.q_cam_model).normalized();
  }
  out.t_cam_model_m = T.t_cam_model_m + delta.tail<3>();
  return out;
}

// The image line of one visible segment at a pose: n = P_a x P_b (the normal of the plane through the camera
// centre and the segment) is the homogeneous line in normalised coordinates. With inv_m = 1 / |n_xy| the
// signed event-to-line distance is r = n·(x, y, 1) inv_m (paper eq. 38, normalised units). M = dn/d(dθ, dt).
struct LineGeometry {
  Eigen::Vector3d n{Eigen::Vector3d::Zero()};
  double inv_m{0.0};
  Matrix36d M{Matrix36d::Zero()};
};

bool line_geometry(const ProjectedSegment& s, const Eigen::Matrix3d& R, const Eigen::Vector3d& t, double near_m,
                   bool with_jacobian, LineGeometry& out) {
  const Eigen::Vector3d Qa = R * s.a_m, Qb = R * s.b_m;
  const Eigen::Vector3d Pa = Qa + t, Pb = Qb + t;
  // Both ends must stay in front, or the sign of n (and of every residual) flips.
  if (!(Pa.z() > near_m) || !(Pb.z() > near_m)) return false;
  out.n = Pa.cross(Pb);
  const double m = out.n.head<2>().norm();
  if (!(m > 1e-15)) return false;
  out.inv_m = 1.0 / m;
  if (with_jacobian) {
    // dP = -[Q]x dθ + dt;  dn = dPa x Pb + Pa x dPb = -[Pb]x dPa + [Pa]x dPb.
    out.M.leftCols<3>() = skew(Pb) * skew(Qa) - skew(Pa) * skew(Qb);
    out.M.rightCols<3>() = skew(Pa - Pb);
  }
  return true;
}

// Each segment's own motion over the window (TrackerOptions::segment_motion): an edge moving at normal speed
// beta_k puts its events at distance beta_k tau from its line at the pose's time (tau = t_event - t_ref), so the
// residuals are r_j = J_j delta + beta_k tau_j + noise. beta_k is a nuisance parameter of segment k: fitted by
// weighted least squares at every evaluation (the variable-projection residuals below) and eliminated from the
// pose's normal equations by its Schur complement.
struct SegmentMotion {
  std::int64_t t_ref_us{0};   // the pose's time
  std::vector<double> tau_s;  // per association: its event's time - t_ref (below), seconds
  std::vector<double> beta;   // per segment: normal speed fitted at the last evaluation (normalised units / s)
  const std::vector<double>* weights{nullptr};  // of the previous evaluation (nullptr: every association 1)
};

// Residuals (normalised units) of every association at pose T; false when a segment degenerates there. With a
// segment motion, each segment's fitted normal motion beta_k tau is taken out of its residuals.
bool residuals(const camera::Pose& T, const std::vector<ProjectedSegment>& segs, const std::vector<Association>& assoc,
               double near_m, bool with_jacobian, std::vector<LineGeometry>& geom, std::vector<double>& r,
               SegmentMotion* motion = nullptr) {
  const Eigen::Matrix3d R = T.rotation();
  geom.resize(segs.size());
  for (std::size_t k = 0; k < segs.size(); ++k) {
    if (!line_geometry(segs[k], R, T.t_cam_model_m, near_m, with_jacobian, geom[k])) return false;
  }
  r.resize(assoc.size());
  for (std::size_t j = 0; j < assoc.size(); ++j) {
    const LineGeometry& g = geom[assoc[j].segment];
    const Eigen::Vector2d& p = assoc[j].p_n;
    r[j] = (g.n.x() * p.x() + g.n.y() * p.y() + g.n.z()) * g.inv_m;
  }
  if (motion != nullptr) {
    std::vector<double> str(segs.size(), 0.0), stt(segs.size(), 0.0);
    const std::vector<double>* w = motion->weights;
    for (std::size_t j = 0; j < assoc.size(); ++j) {
      const double wj = w != nullptr && w->size() == assoc.size() ? (*w)[j] : 1.0;
      const double tau = motion->tau_s[j];
      str[assoc[j].segment] += wj * tau * r[j];
      stt[assoc[j].segment] += wj * tau * tau;
    }
    motion->beta.assign(segs.size(), 0.0);
    for (std::size_t k = 0; k < segs.size(); ++k) {
      if (stt[k] > 0.0) motion->beta[k] = str[k] / stt[k];
    }
    for (std::size_t j = 0; j < assoc.size(); ++j) r[j] -= motion->beta[assoc[j].segment] * motion->tau_s[j];
  }
  return true;
}

// J^T W J and J^T W r, accumulated per segment: dr/dn = ((x, y, 1) - r (n_x, n_y, 0) inv_m) inv_m is per
// event, dn/dX = M per segment, so sum_j w gj gjᵀ is collected per segment (3x3) and mapped once.
void normal_equations(const std::vector<ProjectedSegment>& segs, const std::vector<Association>& assoc,
                      const std::vector<LineGeometry>& geom, const std::vector<double>& r, const std::vector<double>& w,
                      Matrix6d& H, Vector6d& g, const SegmentMotion* motion = nullptr) {
  std::vector<Eigen::Matrix3d> A(segs.size(), Eigen::Matrix3d::Zero());
  std::vector<Eigen::Vector3d> b(segs.size(), Eigen::Vector3d::Zero());
  // With segment motions: sum w tau², sum w tau g and sum w tau r per segment, for the Schur complement of beta.
  std::vector<double> ctt, ctr;
  std::vector<Eigen::Vector3d> htg;
  if (motion != nullptr) {
    ctt.assign(segs.size(), 0.0);
    ctr.assign(segs.size(), 0.0);
    htg.assign(segs.size(), Eigen::Vector3d::Zero());
  }
  for (std::size_t j = 0; j < assoc.size(); ++j) {
    if (w[j] == 0.0) continue;
    const std::size_t k = assoc[j].segment;
    const LineGeometry& lg = geom[k];
    const Eigen::Vector2d& p = assoc[j].p_n;
    const double s = r[j] * lg.inv_m;
    const Eigen::Vector3d gj((p.x() - s * lg.n.x()) * lg.inv_m, (p.y() - s * lg.n.y()) * lg.inv_m, lg.inv_m);
    A[k].noalias() += w[j] * gj * gj.transpose();
    b[k].noalias() += (w[j] * r[j]) * gj;
    if (motion != nullptr) {
      const double tau = motion->tau_s[j];
      ctt[k] += w[j] * tau * tau;
      ctr[k] += w[j] * tau * r[j];
      htg[k].noalias() += (w[j] * tau) * gj;
    }
  }
  if (motion != nullptr) {
    for (std::size_t k = 0; k < segs.size(); ++k) {
      if (!(ctt[k] > 0.0)) continue;
      A[k].noalias() -= htg[k] * htg[k].transpose() / ctt[k];
      b[k].noalias() -= htg[k] * (ctr[k] / ctt[k]);
    }
  }
  H.setZero();
  g.setZero();
  for (std::size_t k = 0; k < segs.size(); ++k) {
    H.noalias() += geom[k].M.transpose() * A[k] * geom[k].M;
    g.noalias() += geom[k].M.transpose() * b[k];
  }
}

struct RoundResult {
  camera::Pose T;
  std::vector<double> w;  // least-squares weights at T (the segment motions' fit at the final pose uses them)
  double sigma_n{0.0};    // robust (S-) scale of the residuals (normalised units): the gate, health and covariance
  int iterations{0};
  bool converged{false};
};

// The robust cost whose minimum the round seeks, and the least-squares weights of the next step, at residuals r.
// Textbook: C = sum rho_c(r / sigma), weights w_c(r / sigma) at the fixed sigma. LOPET: weights recomputed
// (and normalised) from r, C = sum (w r)², the least-squares weights are w².
double robust_cost(const std::vector<double>& r, double sigma, const TrackerOptions& o, std::vector<double>& w_ls,
                   std::vector<double>& scratch) {
  w_ls.resize(r.size());
  double cost = 0.0;
  if (o.lopet_compatible) {
    scratch.resize(r.size());
    for (std::size_t j = 0; j < r.size(); ++j) scratch[j] = std::abs(r[j]);
    mm::lopet_weights(scratch, w_ls);
    for (std::size_t j = 0; j < r.size(); ++j) {
      cost += (w_ls[j] * r[j]) * (w_ls[j] * r[j]);
      w_ls[j] *= w_ls[j];
    }
    return cost;
  }
  return loss::tukey_cost_and_weights(r, sigma, o.c_mm, w_ls);
}

// The edge's scale in residuals r_n (normalised units) that are a mixture of the edge's, Gaussian N(0, sigma²) with
// an unknown count, and the background's, uniform over the gate [-gate_n, gate_n] with a known density
// background_per_n (events per normalised unit of residual): EM for sigma and the edge's count (a Poisson intensity
// n_e phi(d; sigma) + background_per_n, the background's part fixed), started at start_n (the S-scale) with the count
// the background leaves; sigma is floored at floor_n. Returns start_n unless the iteration settles with at least
// kMinEdgeEvents for the edge (something to measure a scale on) and under half of the residuals (past the S-scale's
// breakdown point). The gate's Gaussian truncation is ignored (the gate is >= 4 sigma_S).
double edge_scale(const std::vector<double>& r_n, double start_n, double background_per_n, double gate_n,
                  double floor_n) {
  constexpr int kMaxIterations = 30;
  constexpr double kRelativeTolerance = 1e-3;
  constexpr double kMinEdgeEvents = 10.0;
  const double n = static_cast<double>(r_n.size());
  double edge_events = std::max(n - background_per_n * 2.0 * gate_n, 0.1 * n), sigma_n = start_n;
  for (int it = 0; it < kMaxIterations; ++it) {
    double sum_w = 0.0, sum_wd2 = 0.0;
    const double height = edge_events / (std::sqrt(2.0 * std::numbers::pi) * sigma_n);
    for (const double d : r_n) {
      const double g = height * std::exp(-0.5 * d * d / (sigma_n * sigma_n));
      const double w = g / (g + background_per_n);
      sum_w += w;
      sum_wd2 += w * d * d;
    }
    if (!(sum_w > 1.0)) return start_n;
    const double next_n = std::max(std::sqrt(sum_wd2 / sum_w), floor_n);
    if (!std::isfinite(next_n)) return start_n;
    const bool settled = std::abs(next_n / sigma_n - 1.0) < kRelativeTolerance;
    edge_events = sum_w;
    sigma_n = next_n;
    if (settled) return edge_events >= kMinEdgeEvents && edge_events < 0.5 * n ? sigma_n : start_n;
  }
  return start_n;  // not settled
}

RoundResult solve_round(const camera::Pose& T0, const std::vector<ProjectedSegment>& segs,
                        const std::vector<Association>& assoc, double sigma_floor_n, double sigma_previous_n,
                        const TrackerOptions& o, SegmentMotion* motion, double background_per_n, double gate_n) {
  RoundResult res;
  res.T = T0;
  const double near_m = std::max(o.projection.near_m, 1e-6);
  std::vector<LineGeometry> geom, geom_try;
  std::vector<double> r, r_try, w, w_try, scratch;
  if (motion != nullptr) motion->weights = nullptr;
  if (!residuals(T0, segs, assoc, near_m, true, geom, r, motion)) return res;
  if (o.lopet_compatible) {
    scratch.resize(r.size());
    for (std::size_t j = 0; j < r.size(); ++j) scratch[j] = std::abs(r[j]);
    res.sigma_n = std::max(mm::lopet_scale(scratch), sigma_floor_n);
  } else {
    mm::SScaleOptions so;
    so.c = o.c_s;
    so.max_iterations = o.s_max_iterations;
    if (sigma_previous_n > 0.0) {
      // The previous round's scale: the same root without a median per round. It was fitted with a wider gate,
      // so it starts above the root, and the fixed point contracts by only ~0.6-0.75 per step: more steps.
      so.start = sigma_previous_n;
      so.max_iterations = 3 * o.s_max_iterations;
    }
    const double s = mm::s_scale(r, so).sigma;
    res.sigma_n = s >= sigma_floor_n ? s : sigma_floor_n;  // NaN-safe floor
  }
  // The weights' scale: the S-scale, or the edge's under background (TrackerOptions::background_scale).
  double fit_sigma_n = res.sigma_n;
  if (background_per_n > 0.0 && gate_n > 0.0 && res.sigma_n > sigma_floor_n && !o.lopet_compatible)
    fit_sigma_n = std::min(res.sigma_n, edge_scale(r, res.sigma_n, background_per_n, gate_n, sigma_floor_n));
  double cost = robust_cost(r, fit_sigma_n, o, w, scratch);
  if (motion != nullptr) {
    // The segment motions were fitted with every association at weight 1: once more with the robust weights.
    motion->weights = &w;
    if (!residuals(T0, segs, assoc, near_m, true, geom, r, motion)) return res;
    cost = robust_cost(r, fit_sigma_n, o, w, scratch);
  }
  double lambda = o.lambda_initial;
  Matrix6d H;
  Vector6d g;
  for (int it = 0; it < o.max_iterations; ++it) {
    normal_equations(segs, assoc, geom, r, w, H, g, motion);
    double wsum = 0.0;
    for (double x : w) wsum += x;
    if (!(wsum > 0.0)) break;
    ++res.iterations;
    if (g.lpNorm<Eigen::Infinity>() / wsum < o.gradient_tolerance) {
      res.converged = true;
      break;
    }
    bool accepted = false;
    Vector6d delta = Vector6d::Zero();
    double cost_try = cost;
    for (int attempt = 0; attempt < 12 && !accepted; ++attempt) {
      Matrix6d A = H;
      for (int i = 0; i < 6; ++i) A(i, i) += lambda * std::max(H(i, i), 1e-12);
      delta = A.ldlt().solve(-g);
      if (!delta.allFinite()) {
        lambda *= 10.0;
        continue;
      }
      const camera::Pose T_try = apply_increment(res.T, delta);
      if (motion != nullptr) motion->weights = &w;
      if (residuals(T_try, segs, assoc, near_m, true, geom_try, r_try, motion)) {
        cost_try = robust_cost(r_try, fit_sigma_n, o, w_try, scratch);
        if (cost_try <= cost) {
          accepted = true;
          res.T = T_try;
          std::swap(geom, geom_try);
          std::swap(r, r_try);
          std::swap(w, w_try);
          lambda = std::max(lambda * 0.1, 1e-12);
          break;
        }
      }
      lambda *= 10.0;
    }
    if (!accepted) {
      res.converged = true;  // no descent direction left at this scale: a (local) minimum
      break;
    }
    const double rel_change = (cost - cost_try) / std::max(cost, 1e-300);
    cost = cost_try;
    if ((delta.head<3>().norm() < o.step_tolerance_rad && delta.tail<3>().norm() < o.step_tolerance_m) ||
        rel_change < o.cost_tolerance) {
      res.converged = true;
      break;
    }
  }
  if (motion != nullptr) {
    res.w = w;
    motion->weights = nullptr;  // w ends here
  }
  return res;
}

double angle_between_deg(const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const double c = std::abs(a.normalized().dot(b.normalized()));
  return std::acos(std::min(c, 1.0)) * 180.0 / std::numbers::pi;
}

// Do the segments with at least min_count entries in `counts` span two directions min_angle apart?
bool two_directions(const std::vector<ProjectedSegment>& segs, const std::vector<std::size_t>& counts,
                    std::size_t min_count, double min_angle_deg, std::size_t* seen) {
  std::vector<Eigen::Vector2d> dirs;
  for (std::size_t k = 0; k < segs.size(); ++k) {
    if (counts[k] >= min_count) dirs.push_back(segs[k].b_n - segs[k].a_n);
  }
  if (seen) *seen = dirs.size();
  for (std::size_t i = 0; i < dirs.size(); ++i) {
    for (std::size_t j = i + 1; j < dirs.size(); ++j) {
      if (angle_between_deg(dirs[i], dirs[j]) >= min_angle_deg) return true;
    }
  }
  return false;
}

// Coarse alignment for recovery: the image shift (dx, dy) of the projected model that puts the most events near
// a projected line, turned into a rotation about the camera centre (a shift of d pixels near the principal
// point is a rotation by d / f).
camera::Pose coarse_shift(EventSpan events, const camera::CameraModel& camera,
                          const std::vector<ProjectedSegment>& segs, const camera::Pose& T, double range_px,
                          double step_px) {
  cv::Mat mask(camera.height, camera.width, CV_8U, cv::Scalar(255));
  for (const auto& s : segs) {
    const double len_px = s.length_px;
    const int n = std::max(2, static_cast<int>(std::ceil(len_px * 2.0)));
    for (int i = 0; i <= n; ++i) {
      const Eigen::Vector2d px = camera.normalised_to_pixel(s.a_n + (s.b_n - s.a_n) * (double(i) / n));
      const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
      if (x >= 0 && y >= 0 && x < camera.width && y < camera.height) mask.at<std::uint8_t>(y, x) = 0;
    }
  }
  cv::Mat dist;
  cv::distanceTransform(mask, dist, cv::DIST_L2, 3);
  const int steps = static_cast<int>(std::floor(range_px / step_px));
  long best_score = -1;
  int best_dx = 0, best_dy = 0;
  for (int iy = -steps; iy <= steps; ++iy) {
    for (int ix = -steps; ix <= steps; ++ix) {
      const int dx = static_cast<int>(std::lround(ix * step_px)), dy = static_cast<int>(std::lround(iy * step_px));
      long score = 0;
      for (const Event& e : events) {
        const int x = e.x - dx, y = e.y - dy;
        if (x >= 0 && y >= 0 && x < camera.width && y < camera.height && dist.at<float>(y, x) <= 1.5f) ++score;
      }
      // Prefer the smaller shift on ties (the prediction is the best guess).
      if (score > best_score || (score == best_score && dx * dx + dy * dy < best_dx * best_dx + best_dy * best_dy)) {
        best_score = score;
        best_dx = dx;
        best_dy = dy;
      }
    }
  }
  const double f = focal_px(camera);
  const Eigen::Quaterniond dq(Eigen::AngleAxisd(-best_dy / f, Eigen::Vector3d::UnitX()) *
                              Eigen::AngleAxisd(best_dx / f, Eigen::Vector3d::UnitY()));
  camera::Pose out;
  out.q_cam_model = (dq * T.q_cam_model).normalized();
  out.t_cam_model_m = dq * T.t_cam_model_m;
  return out;
}

const UndistortMap& cached_map(const camera::CameraModel& camera) {
  // One table per thread, rebuilt when the camera changes: track_window(camera) stays a plain function.
  thread_local std::unique_ptr<UndistortMap> map;
  if (!map || !(map->camera() == camera)) map = std::make_unique<UndistortMap>(camera);
  return *map;
}

// Largest image motion (pixels) of the projected segments' ends between two poses (NaN or inf: not finite).
double image_motion_px(const std::vector<ProjectedSegment>& segs, const camera::Pose& T0, const camera::Pose& T1,
                       double f) {
  double moved2 = 0.0;
  for (const ProjectedSegment& s : segs) {
    for (const Eigen::Vector3d* P : {&s.a_m, &s.b_m}) {
      const Eigen::Vector3d p0 = T0.apply(*P), p1 = T1.apply(*P);
      const double d2 = (p0.head<2>() / p0.z() - p1.head<2>() / p1.z()).squaredNorm();
      if (!(d2 <= moved2)) moved2 = d2;  // a NaN counts as a move (no early stop on it)
    }
  }
  return std::sqrt(moved2) * f;
}

// One tracking run from T_start on the window's events (and the same events gathered for the association); the
// failures report T_predicted, as track_window promises.
TrackUpdate track_from(EventSpan events, const GatheredEvents& gathered, const UndistortMap& map,
                       const camera::LineModel& model, const camera::Pose& T_predicted, const camera::Pose& T_start,
                       const TrackerOptions& o, SegmentMotion* motion) {
  const camera::CameraModel& camera = map.camera();
  TrackUpdate up;
  up.T_cam_model = T_predicted;
  const double f = focal_px(camera);
  const double near_m = std::max(o.projection.near_m, 1e-6);
  camera::Pose T = T_start;
  if (o.coarse_search_px > 0.0) {
    const auto segs0 = project_model(camera, model, T, o.projection);
    if (!segs0.empty()) {
      T = coarse_shift(events, camera, segs0, T, o.coarse_search_px, std::max(o.coarse_search_step_px, 1.0));
    }
  }
  double gate_px = o.association.gate_px;
  // Events sit at pixel centres: an edge's crossing point is known to a pixel, uniform within it, so no scale of the
  // residuals is below the quantisation's standard deviation 1/sqrt(12) px (a smaller one comes from events of a
  // few edges in single pixel columns whose common offset is a bias, not a measurement; docs/algorithms.md).
  const double sigma_floor_n = 1.0 / std::sqrt(12.0) / f;
  std::vector<ProjectedSegment> segs;
  std::vector<Association> assoc;
  std::vector<double> last_w;  // the last round's weights (segment motions at the final pose)
  double sigma_n = 0.0;
  const int rounds = std::max(o.association_rounds, 1);
  for (int round = 0; round < rounds; ++round) {
    segs = project_model(camera, model, T, o.projection);
    if (segs.empty()) {
      up.reason = round == 0 ? "model out of view (no projected segment >= min_length_px in the image)"
                             : "model left the view during the solve";
      up.T_cam_model = T_predicted;
      return up;
    }
    AssociationOptions ao = o.association;
    ao.gate_px = gate_px;
    associate_events(gathered, map, segs, ao, assoc);
    std::vector<std::size_t> counts(segs.size(), 0);
    for (const auto& a : assoc) ++counts[a.segment];
    if (motion != nullptr && !assoc.empty()) {
      // Times from the pose's time, but not past the end of the events' own time span: a sparse window's history
      // (a target slowing to a stop) is not extrapolated beyond its data. The span's end is estimated from the
      // events near the lines (within gate_min_px; background noise spreads over the gate and the whole span) as
      // a uniform distribution's with their mean and spread, mean + sqrt(3) sd: for a full window it is the
      // window's end. One reference for every segment: per-segment times would bend the model.
      double n = 0.0, sum = 0.0, sum2 = 0.0;
      for (const Association& a : assoc) {
        if (a.distance_px > o.gate_min_px) continue;
        const auto dt = static_cast<double>(events[a.event_index].t_us - motion->t_ref_us);
        n += 1.0;
        sum += dt;
        sum2 += dt * dt;
      }
      double ref_us = 0.0;
      if (n > 0.0) {
        const double mean = sum / n;
        ref_us = std::min(0.0, mean + std::sqrt(3.0 * std::max(sum2 / n - mean * mean, 0.0)));
      }
      motion->tau_s.resize(assoc.size());
      for (std::size_t j = 0; j < assoc.size(); ++j) {
        motion->tau_s[j] = 1e-6 * (static_cast<double>(events[assoc[j].event_index].t_us - motion->t_ref_us) - ref_us);
      }
    }
    if (assoc.size() < 6) {
      up.reason = fmt::format("{} events associated with the model (need >= 6)", assoc.size());
      up.T_cam_model = T_predicted;
      up.segments_visible = segs.size();
      return up;
    }
    if (!two_directions(segs, counts, o.min_line_inliers, o.min_direction_angle_deg, nullptr)) {
      up.reason = "events on lines of one direction only (aperture problem: the pose is not observable)";
      up.T_cam_model = T_predicted;
      up.segments_visible = segs.size();
      up.associated = assoc.size();
      return up;
    }
    // The background's height in the residuals (TrackerOptions::background_scale): the gathered events left out of
    // the association, per pixel of the image outside the gate's band, times the projected model's length (per pixel
    // of residual), in normalised units. An approximation: the bands' ends, overlaps and the image border are not
    // modelled, and events the ambiguity rules drop inside the band count as away.
    double background_per_n = 0.0;
    if (o.background_scale) {
      double length_px = 0.0;
      for (const ProjectedSegment& sg : segs) length_px += (sg.b_n - sg.a_n).norm() * f;
      const double away_px2 = static_cast<double>(camera.width) * camera.height - 2.0 * gate_px * length_px;
      const double away_events = static_cast<double>(gathered.index.size()) - static_cast<double>(assoc.size());
      if (away_px2 > 0.0 && away_events > 0.0) background_per_n = away_events / away_px2 * length_px * f;
    }
    RoundResult rr = solve_round(T, segs, assoc, sigma_floor_n, sigma_n, o, motion, background_per_n, gate_px / f);
    last_w = std::move(rr.w);
    const double moved_px = image_motion_px(segs, T, rr.T, f);
    T = rr.T;
    sigma_n = rr.sigma_n;
    up.iterations += rr.iterations;
    up.converged = rr.converged;
    up.rounds = round + 1;
    up.gate_px = gate_px;
    const double next_gate_px =
        std::clamp(std::min(o.gate_shrink * gate_px, o.gate_sigma_factor * sigma_n * f), o.gate_min_px, gate_px);
    // Converged: the next round would re-associate with the same gate around a pose that moved less than
    // round_tolerance_px, so only events within that distance of a gate or ambiguity boundary could change — and
    // at the gate (>= 4 sigma) their Tukey weight is already 0 or nearly so.
    if (next_gate_px == gate_px && moved_px < o.round_tolerance_px) break;
    gate_px = next_gate_px;
  }

  // Final statistics at the final pose with the last round's association and scale.
  std::vector<LineGeometry> geom;
  std::vector<double> r, w;
  if (motion != nullptr) motion->weights = &last_w;
  if (!T.t_cam_model_m.allFinite() || !T.q_cam_model.coeffs().allFinite() ||
      !residuals(T, segs, assoc, near_m, true, geom, r, motion)) {
    up.reason = "the solve left the model's valid geometry (segment behind the camera)";
    up.T_cam_model = T_predicted;
    return up;
  }
  up.T_cam_model = T;
  up.associated = assoc.size();
  up.segments_visible = segs.size();
  w.resize(r.size());
  double sigma_cov = sigma_n;
  if (o.lopet_compatible) {
    std::vector<double> absr(r.size());
    for (std::size_t j = 0; j < r.size(); ++j) absr[j] = std::abs(r[j]);
    sigma_cov = std::max(mm::lopet_scale(absr), sigma_floor_n);
  }
  mm::mm_weights(r, sigma_cov, w, o.c_mm);
  std::vector<std::size_t> inliers_per_seg(segs.size(), 0);
  for (std::size_t j = 0; j < r.size(); ++j) {
    if (w[j] > 0.0) {
      ++up.inliers;
      ++inliers_per_seg[assoc[j].segment];
    }
  }
  up.inlier_share = static_cast<double>(up.inliers) / static_cast<double>(events.size());
  up.sigma_px = sigma_cov * f;
  if (motion != nullptr && motion->beta.size() == segs.size()) {
    for (std::size_t k = 0; k < segs.size(); ++k) {
      if (inliers_per_seg[k] >= o.min_line_inliers) {
        up.max_edge_speed_px_s = std::max(up.max_edge_speed_px_s, std::abs(motion->beta[k]) * f);
      }
    }
  }
  const bool directions =
      two_directions(segs, inliers_per_seg, o.min_line_inliers, o.min_direction_angle_deg, &up.lines_seen);

  Matrix6d H;
  Vector6d g;
  normal_equations(segs, assoc, geom, r, w, H, g, motion);
  // Conditioning with translations in units of the mean depth, so that both blocks are angles.
  double depth = 0.0;
  for (const auto& s : segs) depth += 0.5 * (T.apply(s.a_m).z() + T.apply(s.b_m).z());
  depth /= static_cast<double>(segs.size());
  Vector6d scale;
  scale << 1.0, 1.0, 1.0, depth, depth, depth;
  const Matrix6d Hs = scale.asDiagonal() * H * scale.asDiagonal();
  const detail::SymmetricEigen6 es = detail::symmetric_eigen(Hs);
  const double ev_min = es.values(0), ev_max = es.values(5);
  up.condition = ev_min > 0.0 ? ev_max / ev_min : std::numeric_limits<double>::infinity();
  if (ev_min > 0.0 && std::isfinite(up.condition)) {
    // sigma² (J^T W J)^-1, from the eigen-decomposition of the scaled matrix (scaled back).
    const Matrix6d Hs_inv = es.vectors * es.values.cwiseInverse().asDiagonal() * es.vectors.transpose();
    // One measurement per occupied cell along the segments, not per event (tracker.hpp, covariance_cell_px).
    std::vector<std::vector<bool>> occupied(segs.size());
    for (std::size_t j = 0; j < r.size(); ++j) {
      if (w[j] == 0.0) continue;
      const ProjectedSegment& s = segs[assoc[j].segment];
      const Eigen::Vector2d d = s.b_n - s.a_n;
      const double len_px = d.norm() * f;
      // The cell: given, one per segment (< 0), or (0) the run over which an edge's pixel quantisation is common.
      // An edge at angle theta to a pixel axis crosses into the next pixel row (column) every 1 / |sin theta|
      // px along itself: its events in that run share one quantisation offset (uniform within the pixel).
      const double run_px =
          o.covariance_cell_px != 0.0
              ? o.covariance_cell_px
              : std::max(d.norm(), 1e-30) / std::max(std::min(std::abs(d.x()), std::abs(d.y())), 1e-30);
      const auto n_cells = run_px > 0.0 ? static_cast<std::size_t>(std::clamp(std::ceil(std::max(len_px, 1.0) / run_px),
                                                                              1.0, std::max(len_px, 1.0)))
                                        : std::size_t{1};
      auto& occ = occupied[assoc[j].segment];
      if (occ.size() != n_cells) occ.assign(n_cells, false);
      const double t = std::clamp((assoc[j].p_n - s.a_n).dot(d) / std::max(d.squaredNorm(), 1e-30), 0.0, 1.0);
      occ[std::min(n_cells - 1, static_cast<std::size_t>(t * static_cast<double>(n_cells)))] = true;
    }
    for (const auto& occ : occupied)
      up.covariance_cells += static_cast<std::size_t>(std::count(occ.begin(), occ.end(), true));
    const double per_cell =
        up.covariance_cells > 0 ? static_cast<double>(up.inliers) / static_cast<double>(up.covariance_cells) : 1.0;
    up.covariance =
        std::max(per_cell, 1.0) * sigma_cov * sigma_cov * (scale.asDiagonal() * Hs_inv * scale.asDiagonal());
    up.covariance = 0.5 * (up.covariance + up.covariance.transpose());
    up.covariance_known = up.covariance.allFinite();
    if (!up.covariance_known) up.covariance.setZero();
  }

  std::vector<std::string> why;  // health
  if (up.inliers < o.min_inliers) why.push_back(fmt::format("{} inliers < {}", up.inliers, o.min_inliers));
  if (up.inlier_share < o.min_inlier_share) {
    why.push_back(fmt::format("inlier share {:.3f} < {:.3f}", up.inlier_share, o.min_inlier_share));
  }
  if (!(up.sigma_px <= o.max_sigma_px)) {
    why.push_back(fmt::format("sigma {:.2f} px > {:.2f} px", up.sigma_px, o.max_sigma_px));
  }
  if (!directions) {
    why.push_back(fmt::format("inliers on {} segments without two directions >= {} deg apart (aperture)", up.lines_seen,
                              o.min_direction_angle_deg));
  }
  if (!(up.condition <= o.max_condition)) {
    why.push_back(fmt::format("J^T W J ill-conditioned ({:.3g} > {:.3g})", up.condition, o.max_condition));
  }
  if (!up.covariance_known) why.push_back("covariance not positive definite");
  up.healthy = why.empty();
  for (std::size_t i = 0; i < why.size(); ++i) up.reason += (i ? "; " : "") + why[i];
  return up;
}

// Mean of the segments' midpoints (model frame).
Eigen::Vector3d segment_centre(const camera::LineModel& model) {
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const auto& s : model.segments_m) centre += 0.5 * (s.a_m + s.b_m);
  return centre / static_cast<double>(std::max<std::size_t>(model.segments_m.size(), 1));
}

// The prediction turned by angle_deg about the line of sight to the model's centre (the model keeps its place
// in the image and turns there).
camera::Pose rolled(const camera::Pose& T, const camera::LineModel& model, double angle_deg) {
  const Eigen::Vector3d axis = T.apply(segment_centre(model));
  if (!(axis.norm() > 0.0)) return T;
  const Eigen::Quaterniond R(Eigen::AngleAxisd(angle_deg * std::numbers::pi / 180.0, axis.normalized()));
  camera::Pose out;
  out.q_cam_model = (R * T.q_cam_model).normalized();
  out.t_cam_model_m = R * T.t_cam_model_m;
  return out;
}

// The prediction tilted by angle_deg about the camera's x or y axis through the model's centre (an out-of-plane
// turn: the model's appearance changes, its place in the image does not).
camera::Pose tilted(const camera::Pose& T, const camera::LineModel& model, double angle_deg, int axis) {
  const Eigen::Vector3d c = T.apply(segment_centre(model));
  const Eigen::Quaterniond R(Eigen::AngleAxisd(angle_deg * std::numbers::pi / 180.0,
                                               axis == 0 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY()));
  camera::Pose out;
  out.q_cam_model = (R * T.q_cam_model).normalized();
  out.t_cam_model_m = R * (T.t_cam_model_m - c) + c;
  return out;
}

// Is a better than b? Healthy first, then more inliers, then the smaller scale.
bool better(const TrackUpdate& a, const TrackUpdate& b) {
  if (a.healthy != b.healthy) return a.healthy;
  if (a.inliers != b.inliers) return a.inliers > b.inliers;
  return a.sigma_px < b.sigma_px;
}

}  // namespace

TrackUpdate track_window(EventSpan events, const UndistortMap& map, const camera::LineModel& model,
                         const camera::Pose& T_predicted, const TrackerOptions& options,
                         const std::optional<MotionHint>& motion) {
  const TrackerOptions& o = options;
  TrackUpdate up;
  up.T_cam_model = T_predicted;
  if (!T_predicted.t_cam_model_m.allFinite() || !T_predicted.q_cam_model.coeffs().allFinite()) {
    up.reason = "predicted pose is not finite";
    return up;
  }
  if (events.empty()) {
    up.reason = "empty window";
    return up;
  }
  // Speed cap: a uniform stride keeps the window's spatial and temporal spread.
  std::vector<Event> thinned;
  if (o.max_events > 0 && events.size() > o.max_events) {
    const double stride = static_cast<double>(events.size()) / static_cast<double>(o.max_events);
    thinned.reserve(o.max_events);
    for (std::size_t i = 0; i < o.max_events; ++i) {
      thinned.push_back(events[static_cast<std::size_t>(static_cast<double>(i) * stride)]);
    }
    events = thinned;
  }
  GatheredEvents gathered;
  gather_events(events, map, gathered);
  // Segment motions are measured from the pose's time: the hint's, else the middle of the events' span.
  std::optional<SegmentMotion> seg_motion;
  if (o.segment_motion) {
    seg_motion.emplace();
    seg_motion->t_ref_us = motion ? motion->t_us : events.front().t_us + (events.back().t_us - events.front().t_us) / 2;
  }
  SegmentMotion* const c = seg_motion ? &*seg_motion : nullptr;
  up = track_from(events, gathered, map, model, T_predicted, T_predicted, o, c);
  const auto try_start = [&](const camera::Pose& start) {
    TrackUpdate alt = track_from(events, gathered, map, model, T_predicted, start, o, c);
    if (better(alt, up)) up = std::move(alt);
  };
  for (int k = 1; o.recovery_roll_deg > 0.0 && k <= o.recovery_roll_steps; ++k) {
    for (const double sign : {1.0, -1.0}) try_start(rolled(T_predicted, model, sign * k * o.recovery_roll_deg));
  }
  if (o.recovery_tilt_deg > 0.0) {
    for (int axis = 0; axis < 2; ++axis) {
      for (const double sign : {1.0, -1.0}) try_start(tilted(T_predicted, model, sign * o.recovery_tilt_deg, axis));
    }
  }
  if (up.healthy && o.verify) {
    up.verification = verify_pose(events, map.camera(), model, up.T_cam_model, o.verification, motion);
    if (!up.verification.ok) {
      up.healthy = false;
      up.reason = up.verification.reason;
    }
  }
  return up;
}

TrackUpdate track_window(EventSpan events, const camera::CameraModel& camera, const camera::LineModel& model,
                         const camera::Pose& T_predicted, const TrackerOptions& options,
                         const std::optional<MotionHint>& motion) {
  return track_window(events, cached_map(camera), model, T_predicted, options, motion);
}

}  // namespace evpipe::pose
