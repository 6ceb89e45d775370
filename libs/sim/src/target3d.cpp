#include "evpipe/sim/target3d.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

namespace evpipe::sim {

namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

/// Pose at t_us by linear interpolation of the trajectory (clamped at the ends).
camera::Pose pose_at(const std::vector<camera::StampedPose>& traj, std::int64_t t_us) {
  auto it = std::lower_bound(traj.begin(), traj.end(), t_us,
                             [](const camera::StampedPose& p, std::int64_t t) { return p.t_us < t; });
  if (it == traj.begin()) return traj.front().pose;
  if (it == traj.end()) return traj.back().pose;
  return camera::interpolate(*(it - 1), *it, t_us);
}

struct SegmentState {
  bool valid = false;
  Vector3d line;  ///< homogeneous line through the normalised endpoints, scaled so that (a, b) is unit
  Vector2d a_n, b_n;
  Vector2d a_px, b_px;
};

constexpr double kNear_m = 0.05;

SegmentState segment_state(const camera::CameraModel& cam, const camera::Pose& T, const camera::Segment3& s) {
  SegmentState st;
  const Vector3d a = T.apply(s.a_m);
  const Vector3d b = T.apply(s.b_m);
  if (a.z() < kNear_m || b.z() < kNear_m) return st;  // the scenes keep the target well in front
  st.a_n = a.head<2>() / a.z();
  st.b_n = b.head<2>() / b.z();
  const Vector3d l = Vector3d(st.a_n.x(), st.a_n.y(), 1.0).cross(Vector3d(st.b_n.x(), st.b_n.y(), 1.0));
  const double n = l.head<2>().norm();
  if (n < 1e-12) return st;
  st.line = l / n;
  st.a_px = cam.normalised_to_pixel(st.a_n);
  st.b_px = cam.normalised_to_pixel(st.b_n);
  st.valid = true;
  return st;
}

}  // namespace

std::vector<Event> render_target(const TargetScene& scene, std::int64_t t0_us, std::int64_t t1_us,
                                 std::mt19937_64& rng) {
  std::vector<Event> out;
  const auto& traj = scene.trajectory;
  if (traj.size() < 2 || scene.model.segments_m.empty()) return out;
  t0_us = std::max(t0_us, traj.front().t_us);
  t1_us = std::min(t1_us, traj.back().t_us);
  if (t1_us <= t0_us) return out;

  const auto& cam = scene.camera;
  const auto& e = scene.edge;
  const int W = cam.width;
  const int H = cam.height;
  // Normalised undistorted coordinates of every pixel centre.
  std::vector<Vector2d> norm(static_cast<std::size_t>(W) * static_cast<std::size_t>(H));
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) norm[static_cast<std::size_t>(y) * W + x] = cam.pixel_to_normalised(Vector2d(x, y));

  const int levels = std::max(1, static_cast<int>(std::floor(e.contrast_log / e.threshold_log + 1e-9)));
  // Offsets from the edge line (pixels) at which the ramp has changed a pixel by k thresholds.
  std::vector<double> offsets_px;
  for (int k = 1; k <= levels; ++k) offsets_px.push_back(((k - 0.5) / levels - 0.5) * e.blur_px);
  const double f = 0.5 * (cam.fx + cam.fy);  // normalised → pixel scale for the small offsets
  std::vector<int> bright_side;              // +1: the positive side of the line is bright
  std::bernoulli_distribution coin(0.5);
  for (std::size_t i = 0; i < scene.model.segments_m.size(); ++i) bright_side.push_back(coin(rng) ? 1 : -1);

  const std::int64_t base_step_us = 1000;
  std::vector<SegmentState> sa(scene.model.segments_m.size()), sb(sa.size());
  auto states = [&](std::int64_t t, std::vector<SegmentState>& dst) {
    const auto T = pose_at(traj, t);
    for (std::size_t i = 0; i < dst.size(); ++i) dst[i] = segment_state(cam, T, scene.model.segments_m[i]);
  };

  for (std::int64_t tb0 = t0_us; tb0 < t1_us; tb0 += base_step_us) {
    const std::int64_t tb1 = std::min(tb0 + base_step_us, t1_us);
    // Subdivide so that no segment endpoint moves more than max_step_px per step.
    states(tb0, sa);
    states(tb1, sb);
    double disp = 0;
    for (std::size_t i = 0; i < sa.size(); ++i)
      if (sa[i].valid && sb[i].valid)
        disp = std::max({disp, (sa[i].a_px - sb[i].a_px).norm(), (sa[i].b_px - sb[i].b_px).norm()});
    const int nsub = std::max(1, static_cast<int>(std::ceil(disp / e.max_step_px)));
    for (int sub = 0; sub < nsub; ++sub) {
      const std::int64_t ta = tb0 + (tb1 - tb0) * sub / nsub;
      const std::int64_t tb = tb0 + (tb1 - tb0) * (sub + 1) / nsub;
      if (tb <= ta) continue;
      if (nsub > 1) {
        states(ta, sa);
        states(tb, sb);
      }
      for (std::size_t i = 0; i < sa.size(); ++i) {
        const auto& A = sa[i];
        const auto& B = sb[i];
        if (!A.valid || !B.valid) continue;
        // Pixel band around the segment at both ends of the step (chord in pixels + a margin for the
        // curvature distortion gives the image of the line, the blur and the motion).
        const Vector2d mid_curve = cam.normalised_to_pixel(0.5 * (A.a_n + A.b_n));
        const double margin = (mid_curve - 0.5 * (A.a_px + A.b_px)).norm() + e.blur_px + disp / nsub + 1.5;
        const double x_lo = std::min({A.a_px.x(), A.b_px.x(), B.a_px.x(), B.b_px.x()}) - margin;
        const double x_hi = std::max({A.a_px.x(), A.b_px.x(), B.a_px.x(), B.b_px.x()}) + margin;
        const double y_lo = std::min({A.a_px.y(), A.b_px.y(), B.a_px.y(), B.b_px.y()}) - margin;
        const double y_hi = std::max({A.a_px.y(), A.b_px.y(), B.a_px.y(), B.b_px.y()}) + margin;
        const int px0 = std::max(0, static_cast<int>(std::floor(x_lo)));
        const int px1 = std::min(W - 1, static_cast<int>(std::ceil(x_hi)));
        const int py0 = std::max(0, static_cast<int>(std::floor(y_lo)));
        const int py1 = std::min(H - 1, static_cast<int>(std::ceil(y_hi)));
        if (px0 > px1 || py0 > py1) continue;
        // Walk along the major axis and visit only the pixels near the chord.
        const Vector2d d = A.b_px - A.a_px;
        const bool along_x = std::abs(d.x()) >= std::abs(d.y());
        const int major0 = along_x ? px0 : py0;
        const int major1 = along_x ? px1 : py1;
        for (int m = major0; m <= major1; ++m) {
          // Minor coordinate range of the band at this major coordinate, from the four chord lines.
          double lo = 1e9, hi = -1e9;
          for (const auto* S : {&A, &B}) {
            const Vector2d p = S->a_px, q = S->b_px;
            const double dm = along_x ? q.x() - p.x() : q.y() - p.y();
            const double dn = along_x ? q.y() - p.y() : q.x() - p.x();
            double u = std::abs(dm) > 1e-9 ? (m - (along_x ? p.x() : p.y())) / dm : 0.5;
            u = std::clamp(u, 0.0, 1.0);
            const double c = (along_x ? p.y() : p.x()) + u * dn;
            lo = std::min(lo, c);
            hi = std::max(hi, c);
          }
          const int n0 = std::max(along_x ? py0 : px0, static_cast<int>(std::floor(lo - margin)));
          const int n1 = std::min(along_x ? py1 : px1, static_cast<int>(std::ceil(hi + margin)));
          for (int n = n0; n <= n1; ++n) {
            const int x = along_x ? m : n;
            const int y = along_x ? n : m;
            const Vector2d& p = norm[static_cast<std::size_t>(y) * W + x];
            const Vector3d ph(p.x(), p.y(), 1.0);
            const double da = A.line.dot(ph) * f;  // signed distance, pixels
            const double db = B.line.dot(ph) * f;
            for (const double o : offsets_px) {
              const double ra = da - o;
              const double rb = db - o;
              if ((ra > 0) == (rb > 0)) continue;
              const double s = ra / (ra - rb);  // crossing fraction of the step
              // Inside the segment's extent at the crossing?
              const Vector2d a_n = A.a_n + s * (B.a_n - A.a_n);
              const Vector2d b_n = A.b_n + s * (B.b_n - A.b_n);
              const Vector2d ab = b_n - a_n;
              const double u = (p - a_n).dot(ab) / ab.squaredNorm();
              if (u < 0.0 || u > 1.0) continue;
              const double t = static_cast<double>(ta) + s * static_cast<double>(tb - ta);
              // The pixel now lies on side sign(rb) of the (ramp-offset) line and so sees that side's content:
              // it got brighter if that is the bright side.
              const int now_side = rb > 0 ? 1 : -1;
              const bool on = now_side == bright_side[i];
              out.push_back({static_cast<std::int64_t>(std::llround(t)), static_cast<std::uint16_t>(x),
                             static_cast<std::uint16_t>(y), on});
            }
          }
        }
      }
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  // Refractory period per pixel, then readout jitter.
  std::vector<std::int64_t> last(norm.size(), std::numeric_limits<std::int64_t>::min() / 2);
  std::vector<Event> kept;
  kept.reserve(out.size());
  std::normal_distribution<double> jitter(0.0, e.jitter_us);
  for (const auto& ev : out) {
    auto& l = last[static_cast<std::size_t>(ev.y) * W + ev.x];
    if (ev.t_us - l < e.refractory_us) continue;
    l = ev.t_us;
    Event j = ev;
    if (e.jitter_us > 0) j.t_us = std::clamp<std::int64_t>(ev.t_us + std::llround(jitter(rng)), t0_us, t1_us - 1);
    kept.push_back(j);
  }
  std::stable_sort(kept.begin(), kept.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  return kept;
}

double motion_time_s(double t_s, const std::vector<MotionStop>& stops, double ramp_s) {
  if (ramp_s < 0.0) throw std::invalid_argument("motion stops: negative ramp");
  double end_prev = -std::numeric_limits<double>::infinity();
  double lost = 0.0;  // time lost to the stops before t_s
  const double r = ramp_s;
  const double pi = std::numbers::pi;
  // Integral of the speed factor over [0, x] of a ramp of length r: down 0.5 (1 + cos), up 0.5 (1 - cos).
  auto down = [&](double x) { return r > 0 ? 0.5 * x + 0.5 * r / pi * std::sin(pi * x / r) : 0.0; };
  auto up = [&](double x) { return r > 0 ? 0.5 * x - 0.5 * r / pi * std::sin(pi * x / r) : 0.0; };
  for (const auto& st : stops) {
    if (!(st.at_s >= 0.0) || !(st.for_s >= 0.0)) throw std::invalid_argument("motion stops: negative time");
    if (st.at_s - r < end_prev) throw std::invalid_argument("motion stops: unsorted or overlapping (ramps included)");
    end_prev = st.at_s + st.for_s + r;
  }
  for (const auto& st : stops) {
    const double a = st.at_s - r;  // start of the slow-down
    if (t_s <= a) break;
    if (t_s < st.at_s) return t_s - lost - ((t_s - a) - down(t_s - a));
    lost += r - down(r);
    if (t_s < st.at_s + st.for_s) return st.at_s - lost;
    lost += st.for_s;
    const double b = st.at_s + st.for_s;  // start of the speed-up
    if (t_s < b + r) return t_s - lost - ((t_s - b) - up(t_s - b));
    lost += r - up(r);
  }
  return t_s - lost;
}

std::vector<camera::StampedPose> generate_motion(std::int64_t t0_us, std::int64_t t1_us, const MotionOptions& o,
                                                 std::mt19937_64& rng) {
  (void)motion_time_s(0.0, o.stops, o.stop_ramp_s);  // validates the stops before anything is drawn
  std::uniform_real_distribution<double> freq(o.min_freq_hz, o.max_freq_hz);
  std::uniform_real_distribution<double> phase(0.0, 2.0 * std::numbers::pi);
  struct Axis {
    double f[3], ph[3], amp = 0;
  };
  Axis axes[6];
  for (int a = 0; a < 6; ++a) {
    const bool rot = a >= 3;
    const double range = rot ? o.range_deg * std::numbers::pi / 180.0 : o.range_m;
    const double vmax = (rot ? o.max_angular_speed_deg_s * std::numbers::pi / 180.0 : o.max_speed_m_s) / std::sqrt(3.0);
    double fsum = 0;
    for (int k = 0; k < 3; ++k) {
      axes[a].f[k] = freq(rng);
      axes[a].ph[k] = phase(rng);
      fsum += 2.0 * std::numbers::pi * axes[a].f[k];
    }
    // Sum of three sinusoids of amplitude amp/3: |x| <= amp and |dx/dt| <= amp/3 * sum(2 pi f); the speed bound
    // is per axis divided by sqrt(3) so the 3D speed stays below the limit.
    axes[a].amp = std::min(range, vmax * 3.0 / fsum);
  }
  std::vector<camera::StampedPose> out;
  const auto step_us = static_cast<std::int64_t>(std::llround(1e6 / o.rate_hz));
  const std::int64_t step = std::max<std::int64_t>(step_us, 1);
  // Every step from t0, and t1 itself when the span is not a whole number of steps (the end is covered).
  for (std::int64_t t = t0_us; t <= t1_us; t = (t < t1_us && t + step > t1_us) ? t1_us : t + step) {
    const double ts = motion_time_s(static_cast<double>(t - t0_us) * 1e-6, o.stops, o.stop_ramp_s);
    double v[6];
    for (int a = 0; a < 6; ++a) {
      v[a] = 0;
      for (int k = 0; k < 3; ++k)
        v[a] += axes[a].amp / 3.0 * std::sin(2.0 * std::numbers::pi * axes[a].f[k] * ts + axes[a].ph[k]);
    }
    const Eigen::Vector3d rv(v[3], v[4], v[5]);
    const double angle = rv.norm();
    const Eigen::Quaterniond dq =
        angle > 1e-15 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, rv / angle)) : Eigen::Quaterniond::Identity();
    camera::StampedPose sp;
    sp.t_us = t;
    // Turn about the pivot (it stays put but for the translation) and translate in the camera frame.
    sp.pose.q_cam_model = (dq * o.base.q_cam_model).normalized();
    sp.pose.t_cam_model_m =
        o.base.apply(o.pivot_model_m) + Eigen::Vector3d(v[0], v[1], v[2]) - sp.pose.q_cam_model * o.pivot_model_m;
    out.push_back(sp);
  }
  return out;
}

Eigen::Vector3d bbox_centre(const camera::LineModel& model) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e18), hi = Eigen::Vector3d::Constant(-1e18);
  for (const auto& s : model.segments_m) {
    lo = lo.cwiseMin(s.a_m).cwiseMin(s.b_m);
    hi = hi.cwiseMax(s.a_m).cwiseMax(s.b_m);
  }
  return 0.5 * (lo + hi);
}

camera::Pose facing_pose(const camera::LineModel& model, double distance_m, const Eigen::Quaterniond& R_cam_model) {
  const Eigen::Vector3d centre = bbox_centre(model);
  camera::Pose p;
  p.q_cam_model = R_cam_model.normalized();
  p.t_cam_model_m = Eigen::Vector3d(0, 0, distance_m) - (p.q_cam_model * centre);
  return p;
}

Eigen::Quaterniond look_at_z_up(double azimuth_deg, double elevation_deg) {
  const double az = azimuth_deg * std::numbers::pi / 180.0;
  const double el = elevation_deg * std::numbers::pi / 180.0;
  // Unit vector from the model towards the camera, model frame; the camera looks the other way.
  const Eigen::Vector3d towards_camera(std::cos(el) * std::cos(az), std::cos(el) * std::sin(az), std::sin(el));
  const Eigen::Vector3d forward = -towards_camera;
  const Eigen::Vector3d right = forward.cross(Eigen::Vector3d::UnitZ()).normalized();  // x right
  const Eigen::Vector3d down = forward.cross(right);                                   // y down
  Eigen::Matrix3d R_model_cam;
  R_model_cam.col(0) = right;
  R_model_cam.col(1) = down;
  R_model_cam.col(2) = forward;
  return Eigen::Quaterniond(Eigen::Matrix3d(R_model_cam.transpose())).normalized();
}

Eigen::Quaterniond default_view(const camera::LineModel& model) {
  double z_lo = 1e18, z_hi = -1e18;
  for (const auto& s : model.segments_m) {
    z_lo = std::min({z_lo, s.a_m.z(), s.b_m.z()});
    z_hi = std::max({z_hi, s.a_m.z(), s.b_m.z()});
  }
  if (model.segments_m.empty() || z_hi - z_lo <= 1e-9) return Eigen::Quaterniond::Identity();
  return look_at_z_up(kDefaultViewAzimuth_deg, kDefaultViewElevation_deg);
}

std::vector<camera::StampedPose> densify(const std::vector<camera::StampedPose>& traj, std::int64_t max_gap_us) {
  if (max_gap_us <= 0) max_gap_us = 1;
  std::vector<camera::StampedPose> out;
  out.reserve(traj.size());
  for (std::size_t i = 0; i < traj.size(); ++i) {
    if (i > 0) {
      const auto& a = traj[i - 1];
      const auto& b = traj[i];
      const std::int64_t gap = b.t_us - a.t_us;
      const std::int64_t pieces = (gap + max_gap_us - 1) / max_gap_us;
      for (std::int64_t k = 1; k < pieces; ++k) {
        const std::int64_t t = a.t_us + gap * k / pieces;
        out.push_back({t, camera::interpolate(a, b, t)});
      }
    }
    out.push_back(traj[i]);
  }
  return out;
}

camera::Pose perturb_pose(const camera::Pose& truth, double offset_m, double offset_deg, std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  auto direction = [&] {
    // Isotropic Gaussian, normalised: uniform on the sphere.
    while (true) {
      // One draw per statement: the order in which a call's arguments are evaluated is unspecified (GCC goes
      // right to left, clang left to right), and the same seed must give the same prior with every compiler.
      const double z = g(rng);
      const double y = g(rng);
      const double x = g(rng);
      const Eigen::Vector3d v(x, y, z);
      if (v.norm() > 1e-6) return Eigen::Vector3d(v.normalized());
    }
  };
  const Eigen::Vector3d shift = direction();
  const Eigen::Vector3d axis = direction();
  camera::Pose p;
  p.t_cam_model_m = truth.t_cam_model_m + offset_m * shift;
  p.q_cam_model =
      (Eigen::Quaterniond(Eigen::AngleAxisd(offset_deg * std::numbers::pi / 180.0, axis)) * truth.q_cam_model)
          .normalized();
  return p;
}

}  // namespace evpipe::sim
