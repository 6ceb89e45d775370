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
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector2d hi = -lo;
  for (int y = 0; y < camera.height; ++y) {
    for (int x = 0; x < camera.width; ++x) {
      const Eigen::Vector2d p = camera.pixel_to_normalised(Eigen::Vector2d(x, y));
      table_[i++] = p;
      if (p.allFinite()) {
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
    }
  }
  if (!(lo.x() <= hi.x())) lo = hi = Eigen::Vector2d::Zero();
  grid_.origin = lo;
  grid_.cell = kGridCellPx / focal_px(camera);
  grid_.nx = static_cast<int>(std::floor((hi.x() - lo.x()) / grid_.cell)) + 1;
  grid_.ny = static_cast<int>(std::floor((hi.y() - lo.y()) / grid_.cell)) + 1;
  cells_.resize(table_.size());
  for (std::size_t j = 0; j < table_.size(); ++j) {
    const Eigen::Vector2d& p = table_[j];
    if (!p.allFinite()) continue;  // never looked up: associate_events skips such pixels
    const int cx = std::clamp(static_cast<int>(std::floor((p.x() - lo.x()) / grid_.cell)), 0, grid_.nx - 1);
    const int cy = std::clamp(static_cast<int>(std::floor((p.y() - lo.y()) / grid_.cell)), 0, grid_.ny - 1);
    cells_[j] = static_cast<std::uint32_t>(cy * grid_.nx + cx);
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

// A grid cell's candidate segment with a lower bound of its squared distance to any point of the cell.
struct Candidate {
  std::uint32_t k;
  double lower2;
};

// Nearest and second-nearest of the candidates, then the gates; appends the association when the event passes
// them. Candidates come sorted by their bound, and the loop stops as soon as no remaining one can change the
// outcome: all remaining are further than the second-nearest so far, or further than the nearest and than both
// ambiguity thresholds (the nearest, its distance and both ambiguity tests then stay as they are), or — with
// none inside the gate yet — beyond the gate (the event then fails the distance gate whatever they are). Equal nearest
// distances resolve to the lower segment index, so the result equals the loop over every segment in index order.
void decide_sorted(std::uint32_t i, const Eigen::Vector2d& p, const std::vector<SegGeom>& segs, const Candidate* begin,
                   const Candidate* end, const Gates& g, std::vector<Association>& out) {
  double best = std::numeric_limits<double>::infinity(), second = best;
  std::uint32_t best_k = 0;
  for (const Candidate* c = begin; c != end; ++c) {
    // Nothing inside the gate so far and every remaining segment at least a gate away: not associated,
    // whatever the rest (most of a noisy window's events end here, at their cell's first candidates).
    if (c->lower2 >= g.gate2 && !(best < g.gate2)) return;
    if (c->lower2 > second) break;
    if (c->lower2 > best && c->lower2 > std::max(g.ratio2 * best, g.junction2)) break;
    const double d2 = distance2(segs[c->k], p);
    if (d2 < best || (d2 == best && c->k < best_k)) {
      second = best;
      best = d2;
      best_k = c->k;
    } else if (d2 < second) {
      second = d2;
    }
  }
  if (!(best < g.gate2)) return;
  if (!(second > g.ratio2 * best) || !(second > g.junction2)) return;
  out.push_back({i, best_k, p, std::sqrt(best) * g.f});
}

}  // namespace

void associate_events_exhaustive(EventSpan events, const UndistortMap& map,
                                 const std::vector<ProjectedSegment>& segments, const AssociationOptions& options,
                                 std::vector<Association>& out) {
  out.clear();
  if (segments.empty() || map.empty()) return;
  const Gates g(map, options);
  const auto segs = segment_geometry(segments);
  // Every segment in index order with a zero bound: decide_sorted() then never stops early.
  std::vector<Candidate> all(segs.size());
  for (std::uint32_t k = 0; k < segs.size(); ++k) all[k] = {k, 0.0};
  GatheredEvents gathered;
  gather_events(events, map, gathered);
  for (std::size_t j = 0; j < gathered.index.size(); ++j) {
    decide_sorted(gathered.index[j], gathered.p_n[j], segs, all.data(), all.data() + all.size(), g, out);
  }
}

void gather_events(EventSpan events, const UndistortMap& map, GatheredEvents& out) {
  out.index.clear();
  out.p_n.clear();
  out.cell.clear();
  if (map.empty()) return;
  for (std::size_t i = 0; i < events.size(); ++i) {
    const Event& e = events[i];
    if (!map.contains(e.x, e.y)) continue;
    const Eigen::Vector2d& p = map.at(e.x, e.y);
    if (!p.allFinite()) continue;  // no finite distance to anything: never associated
    out.index.push_back(static_cast<std::uint32_t>(i));
    out.p_n.push_back(p);
    out.cell.push_back(map.cell_of(e.x, e.y));
  }
}

void associate_events(EventSpan events, const UndistortMap& map, const std::vector<ProjectedSegment>& segments,
                      const AssociationOptions& options, std::vector<Association>& out) {
  GatheredEvents gathered;
  gather_events(events, map, gathered);
  associate_events(gathered, map, segments, options, out);
}

void associate_events(const GatheredEvents& events, const UndistortMap& map,
                      const std::vector<ProjectedSegment>& segments, const AssociationOptions& options,
                      std::vector<Association>& out) {
  out.clear();
  if (segments.empty() || map.empty()) return;
  const Gates g(map, options);
  const auto segs = segment_geometry(segments);
  // Grid over the table's normalised extent. A cell lists every segment within margin + half its diagonal of
  // its centre — a superset of the segments within `margin` of any point in the cell (inflated slightly against
  // rounding) — with a lower bound of its distance to any point of the cell, sorted by that bound.
  const UndistortMap::Grid& grid = map.grid();
  const double cell = grid.cell;
  const double half_diagonal = cell * std::numbers::sqrt2 / 2.0;
  const Eigen::Vector2d origin = grid.origin;
  const int nx = grid.nx, ny = grid.ny;
  const double reach = (g.margin + half_diagonal) * (1.0 + 1e-9) + 1e-12;
  const double reach2 = reach * reach;
  struct Entry {
    std::uint32_t cell;
    Candidate candidate;
  };
  std::vector<Entry> entries;
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
        const double d2 = distance2(s, centre);
        if (d2 <= reach2) {
          // |p - centre| <= half_diagonal for p in the cell, so distance(p) >= distance(centre) - half_diagonal
          // (shrunk a little against rounding).
          const double lower = (std::sqrt(d2) - half_diagonal) * (1.0 - 1e-9) - 1e-12;
          entries.push_back({static_cast<std::uint32_t>(cy * nx + cx), {k, lower > 0.0 ? lower * lower : 0.0}});
        }
      }
    }
  }
  // Counting sort by cell, then each cell's list by its bound.
  std::vector<std::uint32_t> first(static_cast<std::size_t>(nx) * static_cast<std::size_t>(ny) + 1, 0);
  for (const Entry& e : entries) ++first[e.cell + 1];
  for (std::size_t c = 1; c < first.size(); ++c) first[c] += first[c - 1];
  std::vector<Candidate> list(entries.size());
  {
    std::vector<std::uint32_t> fill(first.begin(), first.end() - 1);
    for (const Entry& e : entries) list[fill[e.cell]++] = e.candidate;
  }
  for (std::size_t c = 0; c + 1 < first.size(); ++c) {
    if (first[c + 1] - first[c] > 1) {
      std::sort(list.begin() + first[c], list.begin() + first[c + 1],
                [](const Candidate& l, const Candidate& r) { return l.lower2 < r.lower2; });
    }
  }
  for (std::size_t j = 0; j < events.index.size(); ++j) {
    const std::uint32_t c = events.cell[j];
    const Candidate* b = list.data() + first[c];
    const Candidate* e = list.data() + first[c + 1];
    // decide_sorted's first test, before the call: most events of a noisy window are in cells with no segment
    // within the gate.
    if (b == e || b->lower2 >= g.gate2) continue;
    decide_sorted(events.index[j], events.p_n[j], segs, b, e, g, out);
  }
}

}  // namespace evpipe::pose
