#include "evpipe/pose/projection.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

namespace evpipe::pose {

UndistortMap::UndistortMap(const camera::CameraModel& camera) : camera_(camera) {
  if (camera.width <= 0 || camera.height <= 0) return;
  table_.resize(static_cast<std::size_t>(camera.width) * static_cast<std::size_t>(camera.height));
  std::size_t i = 0;
  min_n_ = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  max_n_ = -min_n_;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const Eigen::Vector2d p = camera.pixel_to_normalised(Eigen::Vector2d(x, y));
      table_[i++] = p;
      if (p.allFinite()) {
        min_n_ = min_n_.cwiseMin(p);
        max_n_ = max_n_.cwiseMax(p);
      }
    }
  }
  if (!(min_n_.x() <= max_n_.x())) min_n_ = max_n_ = Eigen::Vector2d::Zero();
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

namespace {

// The gates of one association call, in normalised units.
struct Gates {
  double f, gate2, ratio2, junction2, margin;
  Gates(const UndistortMap& map, const AssociationOptions& options) {
    f = focal_px(map.camera());
    const double gate_n = options.gate_px / f;
    gate2 = gate_n * gate_n;
    ratio2 = options.ambiguity_ratio * options.ambiguity_ratio;
    const double junction_n = options.junction_px / f;
    junction2 = junction_n * junction_n;
    // A segment further than `margin` from an event cannot change its decision: if it were the nearest, the
    // event fails the distance gate with or without it; if it were the second-nearest, both ambiguity tests
    // pass with or without it.
    margin = std::max({gate_n, options.ambiguity_ratio * gate_n, junction_n});
  }
};

struct SegGeom {
  Eigen::Vector2d a, d;
  double inv_len2;
};

std::vector<SegGeom> segment_geometry(const std::vector<ProjectedSegment>& segments) {
  std::vector<SegGeom> segs;
  segs.reserve(segments.size());
  for (const auto& s : segments) {
    const Eigen::Vector2d d = s.b_n - s.a_n;
    const double l2 = d.squaredNorm();
    segs.push_back({s.a_n, d, l2 > 0.0 ? 1.0 / l2 : 0.0});
  }
  return segs;
}

inline double distance2(const SegGeom& s, const Eigen::Vector2d& p) noexcept {
  const Eigen::Vector2d ap = p - s.a;
  const double u = std::clamp(ap.dot(s.d) * s.inv_len2, 0.0, 1.0);
  return (ap - u * s.d).squaredNorm();
}

// Nearest and second-nearest of the candidate segments (ascending indices: ties keep the lower index), then the
// gates; appends the association when the event passes them.
template <class Candidates>
void decide(std::uint32_t i, const Eigen::Vector2d& p, const std::vector<SegGeom>& segs, const Candidates& candidates,
            const Gates& g, std::vector<Association>& out) {
  double best = std::numeric_limits<double>::infinity(), second = best;
  std::uint32_t best_k = 0;
  for (const std::uint32_t k : candidates) {
    const double d2 = distance2(segs[k], p);
    if (d2 < best) {
      second = best;
      best = d2;
      best_k = k;
    } else if (d2 < second) {
      second = d2;
    }
  }
  if (!(best < g.gate2)) return;
  if (!(second > g.ratio2 * best) || !(second > g.junction2)) return;
  out.push_back({i, best_k, p, std::sqrt(best) * g.f});
}

// The integers [0, n) as a range (the exhaustive loop's candidates).
struct Iota {
  std::uint32_t n;
  struct It {
    std::uint32_t k;
    std::uint32_t operator*() const noexcept { return k; }
    It& operator++() noexcept {
      ++k;
      return *this;
    }
    bool operator!=(const It& o) const noexcept { return k != o.k; }
  };
  [[nodiscard]] It begin() const noexcept { return {0}; }
  [[nodiscard]] It end() const noexcept { return {n}; }
};

struct Span32 {
  const std::uint32_t* b;
  const std::uint32_t* e;
  [[nodiscard]] const std::uint32_t* begin() const noexcept { return b; }
  [[nodiscard]] const std::uint32_t* end() const noexcept { return e; }
};

constexpr double kCellPx = 8.0;

}  // namespace

void associate_events_exhaustive(EventSpan events, const UndistortMap& map,
                                 const std::vector<ProjectedSegment>& segments, const AssociationOptions& options,
                                 std::vector<Association>& out) {
  out.clear();
  if (segments.empty() || map.empty()) return;
  const Gates g(map, options);
  const auto segs = segment_geometry(segments);
  const Iota all{static_cast<std::uint32_t>(segs.size())};
  for (std::size_t i = 0; i < events.size(); ++i) {
    const Event& e = events[i];
    if (!map.contains(e.x, e.y)) continue;
    decide(static_cast<std::uint32_t>(i), map.at(e.x, e.y), segs, all, g, out);
  }
}

void associate_events(EventSpan events, const UndistortMap& map, const std::vector<ProjectedSegment>& segments,
                      const AssociationOptions& options, std::vector<Association>& out) {
  out.clear();
  if (segments.empty() || map.empty()) return;
  const Gates g(map, options);
  const auto segs = segment_geometry(segments);
  // Grid over the table's normalised extent. A cell lists every segment within margin + half its diagonal of
  // its centre: a superset of the segments within `margin` of any point in the cell (inflated slightly against
  // rounding), in ascending order.
  const double cell = kCellPx / g.f;
  const Eigen::Vector2d origin = map.min_n();
  const int nx = static_cast<int>(std::floor((map.max_n().x() - origin.x()) / cell)) + 1;
  const int ny = static_cast<int>(std::floor((map.max_n().y() - origin.y()) / cell)) + 1;
  const double reach = (g.margin + cell * std::numbers::sqrt2 / 2.0) * (1.0 + 1e-9) + 1e-12;
  const double reach2 = reach * reach;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> cell_seg;  // (cell, segment)
  for (std::uint32_t k = 0; k < segs.size(); ++k) {
    const SegGeom& s = segs[k];
    const Eigen::Vector2d b = s.a + s.d;
    if (!s.a.allFinite() || !b.allFinite()) continue;  // can be nobody's nearest (NaN distances)
    // Clamped in double before the conversion: a far end must not overflow the int.
    const auto cell_of = [&](double v, double o, int n) {
      return static_cast<int>(std::clamp(std::floor((v - o) / cell), -1.0, static_cast<double>(n)));
    };
    const int x0 = std::max(cell_of(std::min(s.a.x(), b.x()) - reach, origin.x(), nx), 0);
    const int x1 = std::min(cell_of(std::max(s.a.x(), b.x()) + reach, origin.x(), nx), nx - 1);
    const int y0 = std::max(cell_of(std::min(s.a.y(), b.y()) - reach, origin.y(), ny), 0);
    const int y1 = std::min(cell_of(std::max(s.a.y(), b.y()) + reach, origin.y(), ny), ny - 1);
    for (int cy = y0; cy <= y1; ++cy) {
      for (int cx = x0; cx <= x1; ++cx) {
        const Eigen::Vector2d centre = origin + cell * Eigen::Vector2d(cx + 0.5, cy + 0.5);
        if (distance2(s, centre) <= reach2) {
          cell_seg.emplace_back(static_cast<std::uint32_t>(cy * nx + cx), k);
        }
      }
    }
  }
  // Counting sort by cell (stable: segment order kept).
  std::vector<std::uint32_t> first(static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny) + 1, 0);
  for (const auto& [c, k] : cell_seg) ++first[c + 1];
  for (std::size_t c = 1; c < first.size(); ++c) first[c] += first[c - 1];
  std::vector<std::uint32_t> list(cell_seg.size());
  {
    std::vector<std::uint32_t> fill(first.begin(), first.end() - 1);
    for (const auto& [c, k] : cell_seg) list[fill[c]++] = k;
  }
  for (std::size_t i = 0; i < events.size(); ++i) {
    const Event& e = events[i];
    if (!map.contains(e.x, e.y)) continue;
    const Eigen::Vector2d& p = map.at(e.x, e.y);
    if (!p.allFinite()) continue;  // no finite distance to anything: rejected by the exhaustive loop too
    const int cx = std::clamp(static_cast<int>(std::floor((p.x() - origin.x()) / cell)), 0, nx - 1);
    const int cy = std::clamp(static_cast<int>(std::floor((p.y() - origin.y()) / cell)), 0, ny - 1);
    const std::size_t c = static_cast<std::size_t>(cy) * static_cast<std::size_t>(nx) + static_cast<std::size_t>(cx);
    decide(static_cast<std::uint32_t>(i), p, segs, Span32{list.data() + first[c], list.data() + first[c + 1]}, g, out);
  }
}

}  // namespace evpipe::pose
