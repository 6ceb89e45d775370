#include "evpipe/sim/distractors.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

namespace evpipe::sim {

namespace {

constexpr std::array<std::pair<DistractorKind, const char*>, 5> kKinds = {
    {{DistractorKind::lines, "lines"},
     {DistractorKind::moving_lines, "moving-lines"},
     {DistractorKind::decoy, "decoy"},
     {DistractorKind::decoy_static, "decoy-static"},
     {DistractorKind::flicker, "flicker"}}};

constexpr double kDecoyDepthFactor = 1.5;  // the decoy is this much farther than the target (and as much larger)
constexpr double kDecoyShift = 0.4;        // sideways shift of the decoy, in target image widths

/// The camera-frame point seen at pixel (u, v) at depth z_m.
Eigen::Vector3d back_project(const camera::CameraModel& cam, double u, double v, double z_m) {
  const Eigen::Vector2d n = cam.pixel_to_normalised(Eigen::Vector2d(u, v));
  return Eigen::Vector3d(n.x() * z_m, n.y() * z_m, z_m);
}

camera::Segment3 seg_px(const camera::CameraModel& cam, double ua, double va, double ub, double vb, double z_m) {
  return {back_project(cam, ua, va, z_m), back_project(cam, ub, vb, z_m)};
}

/// Depth of the target's bounding-box centre at T.
double target_depth_m(const camera::LineModel& model, const camera::Pose& T) {
  return std::max(0.1, T.apply(bbox_centre(model)).z());
}

/// Three vertical bars and a diagonal in the wider free band beside the target's image (camera frame, at the
/// target's depth). When the target leaves less than 40 px on both sides, the band overlaps it (clutter on top).
std::vector<camera::Segment3> bars_beside(const camera::CameraModel& cam, const ImageBox& box, double z_m) {
  const double W = cam.width - 1.0;
  const double H = cam.height - 1.0;
  const bool right = (W - box.u1) >= box.u0;
  double lo = right ? box.u1 : 0.0;
  double hi = right ? W : box.u0;
  if (hi - lo < 40.0) {
    lo = right ? 0.65 * W : 0.0;
    hi = right ? W : 0.35 * W;
  }
  lo += 4.0;
  hi -= 4.0;
  const double w = hi - lo;
  std::vector<camera::Segment3> s;
  for (const double f : {0.2, 0.5, 0.8}) s.push_back(seg_px(cam, lo + f * w, 0.15 * H, lo + f * w, 0.85 * H, z_m));
  s.push_back(seg_px(cam, lo + 0.05 * w, 0.25 * H, hi - 0.05 * w, 0.75 * H, z_m));
  return s;
}

/// A rectangle with the target's image outline, shifted sideways towards the wider free side, at
/// kDecoyDepthFactor times the target's depth (camera frame).
std::vector<camera::Segment3> decoy_rectangle(const camera::CameraModel& cam, const ImageBox& box, double z_m) {
  const double W = cam.width - 1.0;
  const bool right = (W - box.u1) >= box.u0;
  const double shift = (right ? 1.0 : -1.0) * kDecoyShift * box.width();
  const double u0 = box.u0 + shift, u1 = box.u1 + shift, v0 = box.v0, v1 = box.v1;
  const double z = kDecoyDepthFactor * z_m;
  return {seg_px(cam, u0, v0, u1, v0, z), seg_px(cam, u1, v0, u1, v1, z), seg_px(cam, u1, v1, u0, v1, z),
          seg_px(cam, u0, v1, u0, v0, z)};
}

/// Segments given in the camera frame at pose T0 of the target, expressed in the target's frame: a body fixed to
/// the target (it follows the target's trajectory).
std::vector<camera::Segment3> in_target_frame(const std::vector<camera::Segment3>& cam_segments,
                                              const camera::Pose& T0) {
  const camera::Pose inv = T0.inverse();
  std::vector<camera::Segment3> out;
  for (const auto& s : cam_segments) out.push_back({inv.apply(s.a_m), inv.apply(s.b_m)});
  return out;
}

Eigen::Vector3d centroid(const std::vector<camera::Segment3>& segments) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const auto& s : segments) c += 0.5 * (s.a_m + s.b_m);
  return segments.empty() ? c : Eigen::Vector3d(c / static_cast<double>(segments.size()));
}

}  // namespace

const char* to_string(DistractorKind kind) noexcept {
  for (const auto& [k, name] : kKinds)
    if (k == kind) return name;
  return "?";
}

DistractorKind distractor_kind(const std::string& name) {
  for (const auto& [k, n] : kKinds)
    if (name == n) return k;
  std::string known;
  for (const auto& n : distractor_kind_names()) known += (known.empty() ? "" : ", ") + n;
  throw std::invalid_argument("unknown distractor '" + name + "' (known: " + known + ")");
}

std::vector<std::string> distractor_kind_names() {
  std::vector<std::string> out;
  for (const auto& kv : kKinds) out.emplace_back(kv.second);
  return out;
}

ImageBox target_image_box(const camera::CameraModel& cam, const camera::LineModel& model, const camera::Pose& T) {
  double u0 = 1e18, v0 = 1e18, u1 = -1e18, v1 = -1e18;
  constexpr int kPieces = 16;
  for (const auto& s : model.segments_m) {
    for (int k = 0; k <= kPieces; ++k) {
      const Eigen::Vector3d p = T.apply(s.a_m + (s.b_m - s.a_m) * (static_cast<double>(k) / kPieces));
      if (p.z() < 0.05) continue;
      const Eigen::Vector2d px = cam.normalised_to_pixel(p.head<2>() / p.z());
      if (!std::isfinite(px.x()) || !std::isfinite(px.y())) continue;
      u0 = std::min(u0, px.x());
      u1 = std::max(u1, px.x());
      v0 = std::min(v0, px.y());
      v1 = std::max(v1, px.y());
    }
  }
  const double W = cam.width - 1.0;
  const double H = cam.height - 1.0;
  ImageBox b{std::clamp(u0, 0.0, W), std::clamp(v0, 0.0, H), std::clamp(u1, 0.0, W), std::clamp(v1, 0.0, H)};
  if (!(b.u1 > b.u0) || !(b.v1 > b.v0)) b = {0.25 * W, 0.25 * H, 0.75 * W, 0.75 * H};  // not in view: the middle
  return b;
}

DistractorBody make_distractor_body(DistractorKind kind, const camera::CameraModel& cam,
                                    const camera::LineModel& target,
                                    const std::vector<camera::StampedPose>& target_trajectory, MotionOptions motion,
                                    std::mt19937_64& rng) {
  if (target_trajectory.size() < 2) throw std::invalid_argument("make_distractor_body: trajectory needs 2 rows");
  if (kind == DistractorKind::flicker) throw std::invalid_argument("make_distractor_body: flicker is not a body");
  const camera::Pose& T0 = target_trajectory.front().pose;
  const ImageBox box = target_image_box(cam, target, T0);
  const double z = target_depth_m(target, T0);
  DistractorBody body;
  body.kind = kind;
  body.model.name = to_string(kind);
  const bool decoy = kind == DistractorKind::decoy || kind == DistractorKind::decoy_static;
  const std::vector<camera::Segment3> cam_segments = decoy ? decoy_rectangle(cam, box, z) : bars_beside(cam, box, z);
  switch (kind) {
    case DistractorKind::lines:
    case DistractorKind::decoy:
      body.model.segments_m = in_target_frame(cam_segments, T0);
      body.trajectory = target_trajectory;
      break;
    case DistractorKind::decoy_static:
      body.model.segments_m = cam_segments;
      body.trajectory = {{target_trajectory.front().t_us, camera::Pose{}},
                         {target_trajectory.back().t_us, camera::Pose{}}};
      break;
    case DistractorKind::moving_lines:
      body.model.segments_m = cam_segments;
      motion.base = camera::Pose{};
      motion.pivot_model_m = centroid(cam_segments);
      motion.stops.clear();
      body.trajectory = generate_motion(target_trajectory.front().t_us, target_trajectory.back().t_us, motion, rng);
      break;
    case DistractorKind::flicker:
      break;
  }
  return body;
}

ImageBox flicker_patch(const camera::CameraModel& cam, const camera::LineModel& target, const camera::Pose& T,
                       int size_px) {
  const ImageBox box = target_image_box(cam, target, T);
  const double cu = 0.5 * (box.u0 + box.u1), cv = 0.5 * (box.v0 + box.v1);
  const double margin = 10.0;
  const double s = std::max(1, size_px);
  const double W = cam.width, H = cam.height;
  double best = -1;
  ImageBox out;
  for (const double u : {margin, W - margin - s}) {
    for (const double v : {margin, H - margin - s}) {
      const double d = std::hypot(u + 0.5 * s - cu, v + 0.5 * s - cv);
      if (d > best) {
        best = d;
        out = {std::max(0.0, u), std::max(0.0, v), std::max(0.0, u) + s, std::max(0.0, v) + s};
      }
    }
  }
  return out;
}

std::vector<Event> flicker_events(const ImageBox& patch, std::int64_t t0_us, std::int64_t t1_us,
                                  const FlickerOptions& o, int levels, double jitter_us, std::mt19937_64& rng) {
  std::vector<Event> out;
  if (t1_us <= t0_us || !(o.rate_hz > 0.0)) return out;
  levels = std::max(1, levels);
  const double period_us = 1e6 / o.rate_hz;
  std::uniform_real_distribution<double> phase(0.0, period_us);
  const double first_us = static_cast<double>(t0_us) + phase(rng) - period_us;
  std::normal_distribution<double> jitter(0.0, jitter_us > 0 ? jitter_us : 1.0);
  const int x0 = static_cast<int>(std::ceil(patch.u0)), x1 = static_cast<int>(std::ceil(patch.u1)) - 1;
  const int y0 = static_cast<int>(std::ceil(patch.v0)), y1 = static_cast<int>(std::ceil(patch.v1)) - 1;
  for (double tc = first_us; tc < static_cast<double>(t1_us); tc += period_us) {
    for (const bool on : {true, false}) {
      const double tt = tc + (on ? 0.0 : 0.5 * period_us);
      for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) {
          for (int k = 1; k <= levels; ++k) {
            double t = tt + o.rise_us * (k - 0.5) / levels;
            if (jitter_us > 0) t += jitter(rng);
            const auto ti = static_cast<std::int64_t>(std::llround(t));
            if (ti < t0_us || ti >= t1_us) continue;
            out.push_back({ti, static_cast<std::uint16_t>(x), static_cast<std::uint16_t>(y), on});
          }
        }
      }
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  return out;
}

}  // namespace evpipe::sim
