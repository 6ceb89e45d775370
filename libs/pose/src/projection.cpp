#include "evpipe/pose/projection.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace evpipe::pose {

UndistortMap::UndistortMap(const camera::CameraModel& camera) : camera_(camera) {
  if (camera.width <= 0 || camera.height <= 0) return;
  table_.resize(static_cast<std::size_t>(camera.width) * static_cast<std::size_t>(camera.height));
  std::size_t i = 0;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      table_[i++] = camera.pixel_to_normalised(Eigen::Vector2d(x, y));
    }
  }
}

double point_segment_distance(const Eigen::Vector2d& p, const Eigen::Vector2d& a, const Eigen::Vector2d& b) noexcept {
  const Eigen::Vector2d ab = b - a;
  const double len2 = ab.squaredNorm();
  const double u = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + u * ab)).norm();
}

namespace {

// Is the point at parameter s of the camera-frame segment pa→pb inside the image (and in front, and not beyond
// the distortion fold)?
bool visible_at(const camera::CameraModel& camera, const Eigen::Vector3d& pa, const Eigen::Vector3d& pb, double s,
                double near_m) {
  const Eigen::Vector3d p = pa + s * (pb - pa);
  if (p.z() <= near_m) return false;
  const auto px = camera.project(p);
  return px && camera.in_image(*px);
}

// Bisection between an outside parameter and an inside one: returns a parameter inside, within ~1e-6 of the
// border crossing (relative to the segment).
double refine_border(const camera::CameraModel& camera, const Eigen::Vector3d& pa, const Eigen::Vector3d& pb,
                     double s_out, double s_in, double near_m) {
  for (int i = 0; i < 24; ++i) {
    const double mid = 0.5 * (s_out + s_in);
    if (visible_at(camera, pa, pb, mid, near_m)) {
      s_in = mid;
    } else {
      s_out = mid;
    }
  }
  return s_in;
}

// Appends the part [sa, sb] of model segment k when its image is at least min_length_px long.
void add_part(const camera::CameraModel& camera, const camera::Pose& T_cam_model, const camera::Segment3& seg,
              std::size_t k, double sa, double sb, double near_m, const ProjectionOptions& options,
              std::vector<ProjectedSegment>& out) {
  ProjectedSegment ps;
  ps.model_index = k;
  ps.a_m = seg.a_m + sa * (seg.b_m - seg.a_m);
  ps.b_m = seg.a_m + sb * (seg.b_m - seg.a_m);
  const auto chord = camera::project_segment(camera, T_cam_model, camera::Segment3{ps.a_m, ps.b_m}, near_m);
  if (!chord) return;
  ps.segment_px = *chord;
  ps.length_px = (chord->b_px - chord->a_px).norm();
  if (!(ps.length_px >= options.min_length_px)) return;
  const Eigen::Vector3d ca = T_cam_model.apply(ps.a_m), cb = T_cam_model.apply(ps.b_m);
  ps.a_n = ca.head<2>() / ca.z();
  ps.b_n = cb.head<2>() / cb.z();
  out.push_back(ps);
}

}  // namespace

std::vector<ProjectedSegment> project_model(const camera::CameraModel& camera, const camera::LineModel& model,
                                            const camera::Pose& T_cam_model, const ProjectionOptions& options) {
  std::vector<ProjectedSegment> out;
  const double near_m = std::max(options.near_m, 1e-6);
  const double f = focal_px(camera);
  const double step_px = std::max(options.clip_sample_px, 0.1);
  for (std::size_t k = 0; k < model.segments_m.size(); ++k) {
    const camera::Segment3& seg = model.segments_m[k];
    const Eigen::Vector3d pa = T_cam_model.apply(seg.a_m);
    const Eigen::Vector3d pb = T_cam_model.apply(seg.b_m);
    if (!pa.allFinite() || !pb.allFinite()) continue;
    // Part in front of the near plane: z(s) = za + s (zb - za) > near.
    double s0 = 0.0, s1 = 1.0;
    const double dz = pb.z() - pa.z();
    if (pa.z() <= near_m && pb.z() <= near_m) continue;
    if (pa.z() <= near_m) s0 = (near_m - pa.z()) / dz;
    if (pb.z() <= near_m) s1 = (near_m - pa.z()) / dz;
    s0 = std::min(std::max(s0, 0.0), 1.0);
    s1 = std::min(std::max(s1, 0.0), 1.0);
    // Sample the front part every ~step_px of its image (capped: a part ending near the near plane projects
    // arbitrarily far, all of it outside the image).
    // Both ends inside: the whole part is taken as visible (the curved image of a segment between two inside
    // points stays inside for any lens without a fold in the image): no sampling, the common case when tracking.
    if (s0 == 0.0 && s1 == 1.0 && visible_at(camera, pa, pb, 0.0, near_m) && visible_at(camera, pa, pb, 1.0, near_m)) {
      add_part(camera, T_cam_model, seg, k, 0.0, 1.0, near_m, options, out);
      continue;
    }
    const Eigen::Vector3d qa = pa + s0 * (pb - pa), qb = pa + s1 * (pb - pa);
    const double len_n = (qb.head<2>() / qb.z() - qa.head<2>() / qa.z()).norm();
    const int n = static_cast<int>(std::clamp(std::ceil(len_n * f / step_px), 2.0, 4000.0));
    int first = -1, last = -1;
    for (int i = 0; i <= n; ++i) {
      const double s = s0 + (s1 - s0) * i / n;
      if (visible_at(camera, pa, pb, s, near_m)) {
        if (first < 0) first = i;
        last = i;
      }
    }
    if (first < 0) continue;
    double sa = s0 + (s1 - s0) * first / n;
    double sb = s0 + (s1 - s0) * last / n;
    if (first > 0) sa = refine_border(camera, pa, pb, s0 + (s1 - s0) * (first - 1) / n, sa, near_m);
    if (last < n) sb = refine_border(camera, pa, pb, s0 + (s1 - s0) * (last + 1) / n, sb, near_m);
    add_part(camera, T_cam_model, seg, k, sa, sb, near_m, options, out);
  }
  return out;
}

void associate_events(EventSpan events, const UndistortMap& map, const std::vector<ProjectedSegment>& segments,
                      const AssociationOptions& options, std::vector<Association>& out) {
  out.clear();
  if (segments.empty() || map.empty()) return;
  const double f = focal_px(map.camera());
  const double gate_n = options.gate_px / f;
  const double gate2 = gate_n * gate_n;
  const double ratio2 = options.ambiguity_ratio * options.ambiguity_ratio;
  const double junction_n = options.junction_px / f;
  const double junction2 = junction_n * junction_n;
  // Segments further than `margin` from an event cannot change its decision (neither the nearest within the
  // gate nor a second-nearest close enough to reject it): a bounding-box test skips them.
  const double margin = std::max({gate_n, options.ambiguity_ratio * gate_n, junction_n});
  struct Seg {
    Eigen::Vector2d a, d;
    double inv_len2;
    double x0, x1, y0, y1;  // bounding box grown by margin
  };
  std::vector<Seg> segs;
  segs.reserve(segments.size());
  for (const auto& s : segments) {
    const Eigen::Vector2d d = s.b_n - s.a_n;
    const double l2 = d.squaredNorm();
    segs.push_back({s.a_n, d, l2 > 0.0 ? 1.0 / l2 : 0.0, std::min(s.a_n.x(), s.b_n.x()) - margin,
                    std::max(s.a_n.x(), s.b_n.x()) + margin, std::min(s.a_n.y(), s.b_n.y()) - margin,
                    std::max(s.a_n.y(), s.b_n.y()) + margin});
  }
  for (std::size_t i = 0; i < events.size(); ++i) {
    const Event& e = events[i];
    if (!map.contains(e.x, e.y)) continue;
    const Eigen::Vector2d& p = map.at(e.x, e.y);
    double best = std::numeric_limits<double>::infinity(), second = best;
    std::uint32_t best_k = 0;
    for (std::size_t k = 0; k < segs.size(); ++k) {
      if (p.x() < segs[k].x0 || p.x() > segs[k].x1 || p.y() < segs[k].y0 || p.y() > segs[k].y1) continue;
      const Eigen::Vector2d ap = p - segs[k].a;
      const double u = std::clamp(ap.dot(segs[k].d) * segs[k].inv_len2, 0.0, 1.0);
      const double d2 = (ap - u * segs[k].d).squaredNorm();
      if (d2 < best) {
        second = best;
        best = d2;
        best_k = static_cast<std::uint32_t>(k);
      } else if (d2 < second) {
        second = d2;
      }
    }
    if (!(best < gate2)) continue;
    if (!(second > ratio2 * best) || !(second > junction2)) continue;
    out.push_back({static_cast<std::uint32_t>(i), best_k, p, std::sqrt(best) * f});
  }
}

}  // namespace evpipe::pose
