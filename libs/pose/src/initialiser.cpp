#include "evpipe/pose/initialiser.hpp"

#include "evpipe/pose/opnl.hpp"
#include "evpipe/pose/tracker.hpp"
#include "evpipe/pose/types.hpp"
#include "evpipe/pose/verification.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <random>
#include <set>
#include <utility>

namespace evpipe::pose {

namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr double kPi = std::numbers::pi;
constexpr double kNear_m = 0.01;  // model points closer than this (or behind) do not project

double rad(double d) {
  return d * kPi / 180.0;
}

// Angle of a direction modulo pi, in [0, pi).
double line_angle(const Vector2d& d) {
  double a = std::atan2(d.y(), d.x());
  if (a < 0) a += kPi;
  if (a >= kPi) a -= kPi;
  return a;
}
// Signed difference of two line angles modulo pi, in [-pi/2, pi/2).
double wrap_half(double a) {
  if (!std::isfinite(a)) return 0.5 * kPi;
  if (std::abs(a) > 8.0 * kPi) a = std::fmod(a, kPi);
  while (a >= 0.5 * kPi) a -= kPi;
  while (a < -0.5 * kPi) a += kPi;
  return a;
}

// A segment in undistorted pixels (an ideal pinhole with the camera's K): images of 3D lines are straight.
struct Seg2 {
  Vector2d a;
  Vector2d b;
  [[nodiscard]] double length() const { return (b - a).norm(); }
  [[nodiscard]] Vector2d dir() const { return (b - a).normalized(); }
  [[nodiscard]] Vector2d mid() const { return 0.5 * (a + b); }
  [[nodiscard]] double angle() const { return line_angle(b - a); }
};

double line_distance(const Seg2& s, const Vector2d& p) {
  const Vector2d u = s.dir();
  const Vector2d d = p - s.a;
  return std::abs(u.x() * d.y() - u.y() * d.x());
}

// Position of p along s, 0 at a, 1 at b.
double along(const Seg2& s, const Vector2d& p) {
  return (p - s.a).dot(s.b - s.a) / (s.b - s.a).squaredNorm();
}

std::optional<Vector2d> intersect(const Seg2& l, const Seg2& m) {
  const Vector2d r = l.b - l.a, s = m.b - m.a;
  const double den = r.x() * s.y() - r.y() * s.x();
  if (std::abs(den) < 1e-9 * r.norm() * s.norm()) return std::nullopt;
  const Vector2d q = m.a - l.a;
  const double t = (q.x() * s.y() - q.y() * s.x()) / den;
  return l.a + t * r;
}

struct Detected {
  Seg2 u;             // undistorted pixels
  double angle{0};    // u.angle()
  LineObservation n;  // normalised coordinates for OPnL
  double length{0};
  double weight{1.0};   // OPnL weight: the line's support relative to the mean (its endpoints' precision)
  double support{0.0};  // events on the line
};

struct Visible {
  int index{-1};    // model segment
  Seg2 u;           // projection (undistorted pixels), clipped to the image's neighbourhood
  double angle{0};  // u.angle()
};

// Pinhole projection (no distortion) into undistorted pixels.
Vector2d pinhole(const camera::CameraModel& cam, const Vector3d& p) {
  return {cam.fx * p.x() / p.z() + cam.cx, cam.fy * p.y() / p.z() + cam.cy};
}

// The model segments a pose shows (in front of the camera, overlapping the image) in undistorted pixels.
std::vector<Visible> visible_segments(const camera::CameraModel& cam, const camera::LineModel& model,
                                      const camera::Pose& T, double margin) {
  std::vector<Visible> out;
  const double x0 = -margin, y0 = -margin, x1 = cam.width + margin, y1 = cam.height + margin;
  for (std::size_t i = 0; i < model.segments_m.size(); ++i) {
    Vector3d A = T.apply(model.segments_m[i].a_m), B = T.apply(model.segments_m[i].b_m);
    if (A.z() < kNear_m && B.z() < kNear_m) continue;
    if (A.z() < kNear_m) A = A + (kNear_m - A.z()) / (B.z() - A.z()) * (B - A);
    if (B.z() < kNear_m) B = B + (kNear_m - B.z()) / (A.z() - B.z()) * (A - B);
    const Vector2d a = pinhole(cam, A), b = pinhole(cam, B);
    // Liang-Barsky clipping to the (enlarged) image.
    double t0 = 0.0, t1 = 1.0;
    const Vector2d d = b - a;
    bool inside = true;
    const double p[4] = {-d.x(), d.x(), -d.y(), d.y()};
    const double q[4] = {a.x() - x0, x1 - a.x(), a.y() - y0, y1 - a.y()};
    for (int k = 0; k < 4 && inside; ++k) {
      if (p[k] == 0.0) {
        if (q[k] < 0) inside = false;
        continue;
      }
      const double r = q[k] / p[k];
      if (p[k] < 0) {
        t0 = std::max(t0, r);
      } else {
        t1 = std::min(t1, r);
      }
      if (t0 > t1) inside = false;
    }
    if (!inside) continue;
    const Seg2 s{a + t0 * d, a + t1 * d};
    if (!s.a.allFinite() || !s.b.allFinite() || s.length() < 5.0) continue;
    out.push_back({static_cast<int>(i), s, s.angle()});
  }
  return out;
}

// Events explained by a pose: events within `band` pixels of the projected model (distortion included: each
// segment is projected as a polyline of short pieces). A pixel counts once however many segments pass it.
class SupportCounter {
 public:
  SupportCounter(EventSpan events, const camera::CameraModel& cam, double band_px)
      : cam_(cam),
        band_(band_px),
        counts_(static_cast<std::size_t>(cam.width) * cam.height, 0),
        stamp_(counts_.size(), 0) {
    for (const Event& e : events) {
      if (e.x < cam.width && e.y < cam.height) ++counts_[static_cast<std::size_t>(e.y) * cam.width + e.x];
    }
  }

  std::size_t explained(const camera::Pose& T, const camera::LineModel& model) {
    ++tick_;
    std::size_t sum = 0;
    for (const auto& s : model.segments_m) {
      Vector3d A = T.apply(s.a_m), B = T.apply(s.b_m);
      if (A.z() < kNear_m && B.z() < kNear_m) continue;
      if (A.z() < kNear_m) A = A + (kNear_m - A.z()) / (B.z() - A.z()) * (B - A);
      if (B.z() < kNear_m) B = B + (kNear_m - B.z()) / (A.z() - B.z()) * (A - B);
      const double len_px = (pinhole(cam_, A) - pinhole(cam_, B)).norm();
      if (!std::isfinite(len_px)) continue;
      const int n = std::clamp(static_cast<int>(std::ceil(len_px / 6.0)), 1, 400);
      std::optional<Vector2d> prev = cam_.project(A);
      for (int k = 1; k <= n; ++k) {
        const std::optional<Vector2d> cur = cam_.project(A + (B - A) * (static_cast<double>(k) / n));
        if (prev && cur) sum += piece(*prev, *cur);
        prev = cur;
      }
    }
    return sum;
  }

 private:
  std::size_t piece(const Vector2d& p, const Vector2d& q) {
    // Clamped in double before the cast: a point near the camera plane projects billions of pixels away, beyond
    // int's range (casting that is undefined behaviour); NaN counts as off the sensor. A box wholly off the sensor
    // gives an empty loop.
    const auto clamped = [](double v, int size) {
      return std::isnan(v) ? -1 : static_cast<int>(std::clamp(v, -1.0, static_cast<double>(size)));
    };
    const int xa = std::max(0, clamped(std::floor(std::min(p.x(), q.x()) - band_), cam_.width));
    const int xb = std::min(cam_.width - 1, clamped(std::ceil(std::max(p.x(), q.x()) + band_), cam_.width));
    const int ya = std::max(0, clamped(std::floor(std::min(p.y(), q.y()) - band_), cam_.height));
    const int yb = std::min(cam_.height - 1, clamped(std::ceil(std::max(p.y(), q.y()) + band_), cam_.height));
    const Vector2d d = q - p;
    const double dd = std::max(d.squaredNorm(), 1e-12);
    const double b2 = band_ * band_;
    std::size_t sum = 0;
    for (int y = ya; y <= yb; ++y) {
      for (int x = xa; x <= xb; ++x) {
        const Vector2d r = Vector2d(x, y) - p;
        const double t = std::clamp(r.dot(d) / dd, 0.0, 1.0);
        if ((r - t * d).squaredNorm() > b2) continue;
        const std::size_t idx = static_cast<std::size_t>(y) * cam_.width + x;
        if (stamp_[idx] == tick_) continue;
        stamp_[idx] = tick_;
        sum += counts_[idx];
      }
    }
    return sum;
  }

  const camera::CameraModel& cam_;
  double band_;
  std::vector<std::uint32_t> counts_;
  std::vector<std::uint32_t> stamp_;
  std::uint32_t tick_{0};
};

// A 2D alignment of the projected model with the detected lines and the matches it makes consistent.
struct Alignment {
  double score{0.0};                         // summed length of the consistent detected lines
  std::vector<std::pair<int, int>> matches;  // (detected line, model segment)
};

// Largest image displacement (pixels) of the model's segment ends between two poses; infinity when one is not in
// front of the camera.
double image_distance_px(const camera::CameraModel& cam, const camera::LineModel& model, const camera::Pose& a,
                         const camera::Pose& b) {
  double d = 0.0;
  for (const auto& s : model.segments_m) {
    for (const Vector3d& m : {s.a_m, s.b_m}) {
      const Vector3d pa = a.apply(m), pb = b.apply(m);
      if (pa.z() < kNear_m || pb.z() < kNear_m) return std::numeric_limits<double>::infinity();
      d = std::max(d, (pinhole(cam, pa) - pinhole(cam, pb)).norm());
    }
  }
  return d;
}

struct Scored {
  camera::Pose T;
  std::size_t explained{0};
  std::size_t correspondences{0};
  bool verified{false};            // set for the refined candidates
  std::size_t supported_cells{0};  // of the verification
};

// The refined candidates' order: verified first, then by supported cells, then by explained events. Two distinct
// verified poses are not decided by it (initialise_from_lines compares them on the events).
bool ranked_before(const Scored& a, const Scored& b) {
  if (a.verified != b.verified) return a.verified;
  if (a.verified && a.supported_cells != b.supported_cells) return a.supported_cells > b.supported_cells;
  return a.explained > b.explained;
}

class Search {
 public:
  Search(const std::vector<Detected>& det, const camera::CameraModel& cam, const camera::LineModel& model,
         const std::optional<camera::PosePrior>& prior, const InitialiserOptions& o, SupportCounter& support,
         double line_support, EventSpan events)
      : det_(det),
        cam_(cam),
        model_(model),
        prior_(prior),
        o_(o),
        support_(support),
        line_support_(line_support),
        events_(events) {}

  // Phase A: the 2D alignments a pseudo-prior offers.
  void align(const camera::Pose& pseudo) {
    aligns_.clear();
    align_from(pseudo);
    // This start's best distinct alignments.
    std::stable_sort(aligns_.begin(), aligns_.end(),
                     [](const Alignment& l, const Alignment& r) { return l.score > r.score; });
    std::vector<Alignment> keep;
    for (Alignment& a : aligns_) {
      if (keep.size() >= o_.alignments) break;
      std::sort(a.matches.begin(), a.matches.end());
      bool same = false;
      for (const Alignment& t : keep) same = same || t.matches == a.matches;
      if (!same) keep.push_back(std::move(a));
    }
    per_start_.push_back(std::move(keep));
  }

  void align_from(const camera::Pose& pseudo) {
    const std::vector<Visible> vis = visible_segments(cam_, model_, pseudo, o_.hypothesis_margin_px);
    if (vis.size() < 2) return;
    std::vector<std::size_t> order(det_.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t l, std::size_t r) { return det_[l].length > det_[r].length; });
    order.resize(std::min(order.size(), o_.seed_lines));
    const double gate = prior_ ? rad(std::min(o_.max_match_angle_deg, prior_->angle_tolerance_deg + 5.0)) : kPi;
    const double cons = rad(o_.consistency_angle_deg);
    const double par = rad(std::max(o_.parallel_deg, 15.0));
    for (std::size_t ii = 0; ii < order.size(); ++ii) {
      for (std::size_t jj = ii + 1; jj < order.size(); ++jj) {
        const Detected& d1 = det_[order[ii]];
        const Detected& d2 = det_[order[jj]];
        const double dd = wrap_half(d2.angle - d1.angle);
        if (std::abs(dd) < par) continue;
        const auto Xd = intersect(d1.u, d2.u);
        if (!Xd || Xd->x() < -cam_.width || Xd->x() > 2.0 * cam_.width || Xd->y() < -cam_.height ||
            Xd->y() > 2.0 * cam_.height)
          continue;
        for (const Visible& m1 : vis) {
          const double a1 = wrap_half(d1.angle - m1.angle);
          if (std::abs(a1) > gate) continue;
          for (const Visible& m2 : vis) {
            if (m2.index == m1.index) continue;
            const double a2 = wrap_half(d2.angle - m2.angle);
            if (std::abs(a2) > gate || std::abs(wrap_half(a2 - a1)) > cons) continue;
            const auto Xm = intersect(m1.u, m2.u);
            if (!Xm) continue;
            const double psi = a1 + 0.5 * wrap_half(a2 - a1);
            score_alignment(vis, psi, *Xm, *Xd, order[ii], m1.index, order[jj], m2.index);
          }
        }
      }
    }
  }

  // Phase B + C: RANSAC over minimal sets from the best alignments, then re-association and re-solving.
  // The refined candidates, in the order of the events they explained before the refinement.
  std::vector<Scored> solve(std::size_t& hypotheses) {
    // The best `alignments` over all starts, then each start's best not yet in (with many pseudo-priors the
    // right one's alignment must not be crowded out by high-scoring wrong ones of the others).
    std::vector<const Alignment*> all;
    for (const auto& v : per_start_) {
      for (const Alignment& a : v) all.push_back(&a);
    }
    std::stable_sort(all.begin(), all.end(),
                     [](const Alignment* l, const Alignment* r) { return l->score > r->score; });
    std::vector<Alignment> top;
    const auto add = [&](const Alignment& a) {
      for (const Alignment& t : top) {
        if (t.matches == a.matches) return;
      }
      top.push_back(a);
    };
    for (const Alignment* a : all) {
      if (top.size() >= o_.alignments) break;
      add(*a);
    }
    for (const auto& v : per_start_) {
      if (!v.empty()) add(v.front());
    }
    std::mt19937_64 rng(o_.seed);
    OpnlOptions fast;
    fast.refine = false;
    fast.fallback = false;
    std::vector<Scored> poses;
    std::set<std::vector<std::pair<int, int>>> solved;
    std::size_t best_explained = 0;
    bool stop = false;
    // Too few lines seen for the model's size: matching them is weak evidence, never stop early.
    const bool enough_lines = static_cast<double>(det_.size()) >=
                              o_.early_stop_min_line_fraction * static_cast<double>(model_.segments_m.size());
    for (const Alignment& a : top) {
      if (stop) break;
      for (int draw = 0; draw <= o_.draws_per_alignment; ++draw) {
        std::vector<std::pair<int, int>> set;
        if (draw == o_.draws_per_alignment) {
          set = a.matches;  // the whole consistent set once
        } else {
          for (int tries = 0; tries < 20 && set.empty(); ++tries) {
            std::vector<std::pair<int, int>> s = a.matches;
            std::shuffle(s.begin(), s.end(), rng);
            s.resize(4);
            if (two_directions(s)) set = std::move(s);
          }
        }
        if (set.size() < 4) continue;
        // A set already solved (an alignment of 4-5 matches has few distinct minimal sets, and the whole set of 4
        // is its only one) gives the same poses again: skip it, so that duplicates neither cost a solve nor take
        // the refinement's candidate slots.
        std::vector<std::pair<int, int>> key = set;
        std::sort(key.begin(), key.end());
        if (!solved.insert(std::move(key)).second) continue;
        ++hypotheses;
        const OpnlResult r = solve_opnl(correspondences(set), fast);
        if (!r.ok) continue;
        std::size_t tried = 0;
        for (const OpnlCandidate& c : r.candidates) {
          if (tried++ >= 3) break;
          consider(c.T_cam_model, set.size(), poses);
        }
        if (r.candidates.empty()) consider(r.T_cam_model, set.size(), poses);
        // Adaptive stop: a new best pose explains (nearly) all the events on the detected lines, and the lines
        // themselves: explained events alone also count events near the model that lie on no detected line,
        // and stopping on them accepted wrong poses (docs/algorithms.md).
        for (const Scored& p : poses) {
          if (p.explained <= best_explained) continue;
          best_explained = p.explained;
          stop = enough_lines && static_cast<double>(p.explained) >= o_.early_stop_share * line_support_ &&
                 line_share(p.T) >= o_.early_stop_line_share;
        }
      }
    }
    if (poses.empty()) return {};
    // Sorted through indices: libstdc++'s stable_sort buffer ignores over-alignment, and Scored holds an Eigen
    // quaternion that needs 32-byte alignment under AVX (-march=native crashed here).
    std::vector<std::size_t> order(poses.size());
    std::iota(order.begin(), order.end(), std::size_t{0});
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t l, std::size_t r) { return poses[l].explained > poses[r].explained; });
    std::vector<Scored> sorted;
    sorted.reserve(poses.size());
    for (const std::size_t i : order) sorted.push_back(poses[i]);
    poses = std::move(sorted);
    // The re-solve on all inliers (refine()): OPnL, then LM (line_refine.hpp) with a Huber loss so that one wrong
    // association cannot pull the pose.
    std::vector<Scored> refined;
    for (std::size_t k = 0; k < std::min(poses.size(), o_.refine_candidates); ++k) {
      if (2 * poses[k].explained < poses[0].explained) break;  // far behind the best: not worth a re-solve
      refined.push_back(refine(poses[k]));
    }
    return refined;
  }

  // Re-association and re-solve on all inliers, then the verification.
  Scored refine(Scored cur) {
    OpnlOptions full;
    full.refine_options.loss = RefineOptions::Loss::huber;
    full.refine_options.loss_scale_n = o_.refine_huber_px / (0.5 * (cam_.fx + cam_.fy));
    cur.correspondences = 0;
    for (int round = 0; round < o_.refine_rounds; ++round) {
      const auto inl = inliers(cur.T);
      if (inl.size() < 4 || !two_directions(inl)) break;
      const OpnlResult r = solve_opnl(correspondences(inl), full);
      if (!r.ok || !acceptable(r.T_cam_model)) break;
      const std::size_t ex = support_.explained(r.T_cam_model, model_);
      if (ex < cur.explained && cur.correspondences > 0) break;
      cur = {r.T_cam_model, ex, inl.size()};
    }
    if (cur.correspondences == 0) cur.correspondences = inliers(cur.T).size();
    // Ranked by the verification first (verification.hpp: support along every segment, beating the scene's
    // other structure), then by explained events: events near the model alone favour a pose that lays its lines
    // over any strong structure (a monitor's border 1.45x a board: every outer segment on an edge, the inner ones
    // over the board's own grid).
    const VerifyResult v = verify_pose(events_, cam_, model_, cur.T, o_.verification);
    cur.verified = v.ok;
    cur.supported_cells = v.cells_supported;
    return cur;
  }

  [[nodiscard]] std::size_t explained(const camera::Pose& T) { return support_.explained(T, model_); }

  // Inlier correspondences of a pose: each detected line with the closest projected model segment within the
  // gates (angle, both endpoints' distance, overlap).
  std::vector<std::pair<int, int>> inliers(const camera::Pose& T) const {
    std::vector<std::pair<int, int>> out;
    const std::vector<Visible> vis = visible_segments(cam_, model_, T, 10.0);
    for (std::size_t i = 0; i < det_.size(); ++i) {
      const Detected& d = det_[i];
      int best = -1;
      double best_d = o_.inlier_px;
      for (const Visible& m : vis) {
        if (std::abs(wrap_half(d.angle - m.angle)) > rad(o_.inlier_angle_deg)) continue;
        const double dist = std::max(line_distance(m.u, d.u.a), line_distance(m.u, d.u.b));
        const double t0 = along(m.u, d.u.a), t1 = along(m.u, d.u.b);
        if (std::max(t0, t1) < -0.05 || std::min(t0, t1) > 1.05) continue;
        if (dist <= best_d) {
          best_d = dist;
          best = m.index;
        }
      }
      if (best >= 0) out.emplace_back(static_cast<int>(i), best);
    }
    return out;
  }

  /// Share of the detected lines' support on lines that are inliers of T.
  [[nodiscard]] double line_share(const camera::Pose& T) const {
    double explained = 0.0;
    for (const auto& [line, segment] : inliers(T)) explained += det_[static_cast<std::size_t>(line)].support;
    return line_support_ > 0.0 ? explained / line_support_ : 0.0;
  }

  [[nodiscard]] bool acceptable(const camera::Pose& T) const {
    if (!T.t_cam_model_m.allFinite() || !T.q_cam_model.coeffs().allFinite()) return false;
    for (const auto& s : model_.segments_m) {  // the whole model in front of the camera
      if (T.apply(s.a_m).z() < kNear_m || T.apply(s.b_m).z() < kNear_m) return false;
    }
    if (prior_) {
      if (camera::translation_distance_m(T, prior_->pose) > prior_->position_tolerance_m) return false;
      if (camera::rotation_angle_deg(T, prior_->pose) > prior_->angle_tolerance_deg) return false;
    }
    return true;
  }

 private:
  void score_alignment(const std::vector<Visible>& vis, double psi, const Vector2d& Xm, const Vector2d& Xd,
                       std::size_t i1, int j1, std::size_t i2, int j2) {
    const Eigen::Rotation2Dd R(psi);
    const auto tf = [&](const Vector2d& p) -> Vector2d { return R * (p - Xm) + Xd; };
    thread_local std::vector<Seg2> moved;
    moved.clear();
    for (const Visible& m : vis) moved.push_back({tf(m.u.a), tf(m.u.b)});
    Alignment a;
    const double cons_rad = rad(o_.consistency_angle_deg);
    for (std::size_t i = 0; i < det_.size(); ++i) {
      const Detected& d = det_[i];
      if (i == i1 || i == i2) {
        a.matches.emplace_back(static_cast<int>(i), i == i1 ? j1 : j2);
        a.score += d.length;
        continue;
      }
      const double tol = o_.consistency_px + o_.consistency_scale * (d.u.mid() - Xd).norm();
      int best = -1;
      double best_d = tol;
      for (std::size_t k = 0; k < vis.size(); ++k) {
        const Seg2& m = moved[k];
        if (vis[k].index == j1 || vis[k].index == j2) continue;
        if (std::abs(wrap_half(d.angle - vis[k].angle - psi)) > cons_rad) continue;
        const double dist = std::max(line_distance(m, d.u.a), line_distance(m, d.u.b));
        if (dist > best_d) continue;
        const double tm = along(m, d.u.mid());
        if (tm < -0.25 || tm > 1.25) continue;
        best_d = dist;
        best = vis[k].index;
      }
      if (best >= 0) {
        a.matches.emplace_back(static_cast<int>(i), best);
        a.score += d.length;
      }
    }
    if (a.matches.size() < 4 || !two_directions(a.matches)) return;
    aligns_.push_back(std::move(a));
    // Bound the memory: keep the better half when the pool grows large.
    if (aligns_.size() > 20000) {
      std::stable_sort(aligns_.begin(), aligns_.end(),
                       [](const Alignment& l, const Alignment& r) { return l.score > r.score; });
      aligns_.resize(5000);
    }
  }

  [[nodiscard]] bool two_directions(const std::vector<std::pair<int, int>>& set) const {
    for (std::size_t i = 0; i < set.size(); ++i) {
      for (std::size_t j = i + 1; j < set.size(); ++j) {
        const double a = wrap_half(det_[static_cast<std::size_t>(set[i].first)].angle -
                                   det_[static_cast<std::size_t>(set[j].first)].angle);
        if (std::abs(a) >= rad(o_.parallel_deg)) return true;
      }
    }
    return false;
  }

  [[nodiscard]] std::vector<LineCorrespondence> correspondences(const std::vector<std::pair<int, int>>& set) const {
    std::vector<LineCorrespondence> c;
    c.reserve(set.size());
    for (const auto& [i, j] : set) {
      LineCorrespondence lc;
      lc.image = det_[static_cast<std::size_t>(i)].n;
      lc.model = model_.segments_m[static_cast<std::size_t>(j)];
      lc.weight = det_[static_cast<std::size_t>(i)].weight;
      c.push_back(lc);
    }
    return c;
  }

  void consider(const camera::Pose& T, std::size_t nset, std::vector<Scored>& poses) {
    if (!acceptable(T)) return;
    poses.push_back({T, support_.explained(T, model_), nset});
  }

  const std::vector<Detected>& det_;
  const camera::CameraModel& cam_;
  const camera::LineModel& model_;
  const std::optional<camera::PosePrior>& prior_;
  const InitialiserOptions& o_;

  SupportCounter& support_;
  double line_support_;
  EventSpan events_;
  std::vector<Alignment> aligns_;                  // the current start's alignments
  std::vector<std::vector<Alignment>> per_start_;  // each start's best, best first
};

Vector3d model_centre(const camera::LineModel& model) {
  Vector3d lo = Vector3d::Constant(1e300), hi = Vector3d::Constant(-1e300);
  for (const auto& s : model.segments_m) {
    lo = lo.cwiseMin(s.a_m).cwiseMin(s.b_m);
    hi = hi.cwiseMax(s.a_m).cwiseMax(s.b_m);
  }
  return 0.5 * (lo + hi);
}

// The rotation taking direction a onto b: Eigen's Quaternion::FromTwoVectors, written out (the same arithmetic, so
// the same quaternion) without its SVD branch for directions within 1e-12 of opposite, which cost 12 s of compile.
// There this turns half about an axis perpendicular to a (off b by up to ~1e-6 rad; pseudo_priors' views never
// come near: their cosine with the axis stays above -(1 - 1/samples)).
Eigen::Quaterniond rotation_onto(const Vector3d& a, const Vector3d& b) {
  const Vector3d v0 = a.normalized(), v1 = b.normalized();
  const double c = v1.dot(v0);
  if (c < -1.0 + Eigen::NumTraits<double>::dummy_precision()) {
    const Vector3d other = std::abs(v0.x()) < 0.9 ? Vector3d::UnitX() : Vector3d::UnitY();
    return Eigen::Quaterniond(Eigen::AngleAxisd(kPi, v0.cross(other).normalized()));
  }
  const double s = std::sqrt((1.0 + c) * 2.0);
  Eigen::Quaterniond q;
  q.vec() = v0.cross(v1) * (1.0 / s);
  q.w() = s * 0.5;
  return q;
}

// Without a prior: view directions on a Fibonacci sphere (the camera looks at the model's centre from each),
// each with the depth at which the model's projected extent matches the detected lines' extent.
std::vector<camera::Pose> pseudo_priors(const std::vector<Detected>& det, const camera::CameraModel& cam,
                                        const camera::LineModel& model, int samples) {
  Vector3d lo = Vector3d::Constant(1e300), hi = Vector3d::Constant(-1e300);
  for (const auto& s : model.segments_m) {
    lo = lo.cwiseMin(s.a_m).cwiseMin(s.b_m);
    hi = hi.cwiseMax(s.a_m).cwiseMax(s.b_m);
  }
  const Vector3d centre = 0.5 * (lo + hi);
  // Image extent and centre of the detected lines.
  Vector2d ilo = Vector2d::Constant(1e300), ihi = Vector2d::Constant(-1e300);
  for (const Detected& d : det) {
    ilo = ilo.cwiseMin(d.u.a).cwiseMin(d.u.b);
    ihi = ihi.cwiseMax(d.u.a).cwiseMax(d.u.b);
  }
  const double img_extent = (ihi - ilo).norm();
  const Vector2d img_centre = 0.5 * (ilo + ihi);
  const Vector3d ray((img_centre.x() - cam.cx) / cam.fx, (img_centre.y() - cam.cy) / cam.fy, 1.0);
  const double f = 0.5 * (cam.fx + cam.fy);
  std::vector<camera::Pose> out;
  const double golden = kPi * (3.0 - std::sqrt(5.0));
  for (int k = 0; k < samples; ++k) {
    const double z = 1.0 - (2.0 * k + 1.0) / samples;
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const Vector3d view(r * std::cos(golden * k), r * std::sin(golden * k), z);  // model-frame direction to camera
    // R_cam_model maps -view onto the optical axis (the camera looks along -view); any roll: the 2D alignment
    // finds the in-plane rotation.
    const Eigen::Quaterniond q = rotation_onto(-view, Vector3d::UnitZ());
    // Extent of the model seen from there (orthographic, at 1 m), vs the image extent.
    Vector2d plo = Vector2d::Constant(1e300), phi = Vector2d::Constant(-1e300);
    for (const auto& s : model.segments_m) {
      for (const Vector3d& p : {s.a_m, s.b_m}) {
        const Vector3d c = q * (p - centre);
        plo = plo.cwiseMin(c.head<2>());
        phi = phi.cwiseMax(c.head<2>());
      }
    }
    const double depth = std::max(0.05, f * (phi - plo).norm() / std::max(img_extent, 1.0));
    camera::Pose T;
    T.q_cam_model = q;
    T.t_cam_model_m = ray.normalized() * depth - q * centre;
    out.push_back(T);
  }
  return out;
}

}  // namespace

namespace {

// The direct alignment with the prior (InitialiserOptions::direct_alignment), refined and verified by the tracker.
InitResult initialise_by_alignment(EventSpan events, const camera::CameraModel& camera, const camera::LineModel& model,
                                   const camera::PosePrior& prior, const InitialiserOptions& options) {
  InitResult res;
  res.T_cam_model = prior.pose;
  res.direct = true;
  res.pseudo_priors = 1;
  const PriorAlignmentResult a = align_at_prior(events, camera, model, prior, options.alignment);
  res.hypotheses = a.evaluations;
  if (!a.ok) {
    res.message = a.message;
    return res;
  }
  TrackerOptions to;
  to.verification = options.verification;
  const TrackUpdate best = track_window(events, camera, model, a.T_cam_model, to);
  const bool inside = camera::translation_distance_m(best.T_cam_model, prior.pose) <= prior.position_tolerance_m &&
                      camera::rotation_angle_deg(best.T_cam_model, prior.pose) <= prior.angle_tolerance_deg;
  if (!best.healthy || !inside) {
    res.message = fmt::format("its pose ({}) does not verify once refined: {}", a.message,
                              inside ? best.reason : "outside the prior's tolerance");
    return res;
  }
  if (a.runner_up) {
    // The events must tell the pose from the nearest other local optimum (a grid shifted by a line).
    const TrackUpdate other = track_window(events, camera, model, *a.runner_up, to);
    if (other.healthy &&
        image_distance_px(camera, model, best.T_cam_model, other.T_cam_model) > options.alignment.runner_up_px) {
      const PoseComparison cmp =
          compare_poses(events, camera, model, best.T_cam_model, other.T_cam_model, options.verification);
      if (cmp.log_ratio < symmetry_decision_log_ratio(options.verification)) {
        res.message = fmt::format(
            "its pose and the runner-up (a distinct local optimum) both verify and the events do not tell them apart "
            "(log-likelihood ratio {:.1f} on {} + {} cells): ambiguous",
            cmp.log_ratio, cmp.cells_a_only, cmp.cells_b_only);
        return res;
      }
    }
  }
  res.ok = true;
  res.verified = true;
  res.T_cam_model = best.T_cam_model;
  res.explained_events = best.inliers;
  res.support_share = best.inlier_share;
  res.message = fmt::format("direct alignment ({}), refined: {} inliers, sigma {:.2f} px", a.message, best.inliers,
                            best.sigma_px);
  return res;
}

InitResult initialise_from_lines(EventSpan events, const camera::CameraModel& camera, const camera::LineModel& model,
                                 const std::optional<camera::PosePrior>& prior, const InitialiserOptions& options);

}  // namespace

InitResult initialise_pose(EventSpan events, const camera::CameraModel& camera, const camera::LineModel& model,
                           const std::optional<camera::PosePrior>& prior, const InitialiserOptions& options) {
  if (prior && !events.empty() && options.direct_alignment == DirectAlignment::automatic &&
      crowded_length_share(camera, model, prior->pose, options.consistency_px) > 0.5) {
    // Most of the model's lines lie closer together than the correspondences resolve: a detected line matches two
    // model lines, and a fine grid's poses alias (scaled and tilted, the model's lines on other grid lines: a board
    // 55 px wide was tracked 180 mm / 29 deg off). The direct alignment alone, with its runner-up test.
    InitResult direct = initialise_by_alignment(events, camera, model, *prior, options);
    if (!direct.ok)
      direct.message = "direct alignment (a model finer than the line search resolves): " + direct.message;
    return direct;
  }
  InitResult lines = initialise_from_lines(events, camera, model, prior, options);
  if (!prior || options.direct_alignment != DirectAlignment::on || events.empty() || (lines.ok && lines.verified)) {
    return lines;
  }
  InitResult direct = initialise_by_alignment(events, camera, model, *prior, options);
  if (direct.ok) {
    direct.lines_detected = lines.lines_detected;
    return direct;
  }
  // Neither verified: the lines' outcome as without the option (an unverified pose is for the estimator's tracking
  // polish to verify or refuse; refusing it here cost a roadheader under 5 Hz/px of noise half its poses).
  lines.message = fmt::format("{}{}; direct alignment: {}", lines.message,
                              lines.verified || lines.message.empty() ? "" : " (not verified)", direct.message);
  return lines;
}

namespace {

InitResult initialise_from_lines(EventSpan events, const camera::CameraModel& camera, const camera::LineModel& model,
                                 const std::optional<camera::PosePrior>& prior, const InitialiserOptions& options) {
  InitResult res;
  if (prior) res.T_cam_model = prior->pose;
  if (events.empty()) {
    res.message = "empty window: no events";
    return res;
  }
  std::size_t usable = 0;
  for (const auto& s : model.segments_m) usable += s.length_m() >= camera::kMinSegmentLength_m ? 1 : 0;
  if (usable < options.min_lines) {
    res.message = fmt::format("the model has {} usable segments, need {}", usable, options.min_lines);
    return res;
  }
  LineDetectorOptions dopt = options.detector;
  dopt.camera = camera;
  const std::vector<DetectedLine> lines = detect_lines(events, SensorGeometry{camera.width, camera.height}, dopt);
  res.lines_detected = lines.size();
  if (lines.size() < options.min_lines) {
    res.message = fmt::format("{} lines detected, need {}", lines.size(), options.min_lines);
    return res;
  }
  std::vector<Detected> det;
  double line_support = 0.0;
  for (const DetectedLine& l : lines) {
    Detected d;
    d.u = {camera.undistort(l.segment_px.a_px), camera.undistort(l.segment_px.b_px)};
    d.n.a_n = camera.pixel_to_normalised(l.segment_px.a_px);
    d.n.b_n = camera.pixel_to_normalised(l.segment_px.b_px);
    d.length = d.u.length();
    d.angle = d.u.angle();
    if (!d.u.a.allFinite() || !d.u.b.allFinite() || !d.n.a_n.allFinite() || !d.n.b_n.allFinite()) continue;
    d.support = static_cast<double>(l.support);
    d.weight = d.support;
    det.push_back(d);
    line_support += static_cast<double>(l.support);
  }
  for (Detected& d : det) d.weight = std::max(1e-3, d.weight * static_cast<double>(det.size()) / line_support);
  bool two_dirs = false;
  for (std::size_t i = 0; i < det.size() && !two_dirs; ++i) {
    for (std::size_t j = i + 1; j < det.size() && !two_dirs; ++j) {
      two_dirs = std::abs(wrap_half(det[i].angle - det[j].angle)) >= rad(options.parallel_deg);
    }
  }
  if (!two_dirs) {
    res.message = fmt::format("all {} detected lines are parallel (within {} deg): the pose is not determined",
                              det.size(), options.parallel_deg);
    return res;
  }

  SupportCounter support(events, camera, options.support_band_px);
  Search search(det, camera, model, prior, options, support, line_support, events);
  std::vector<camera::Pose> starts;
  if (prior) {
    // The prior and its tilts about the camera's x and y axes (through the model's centre): the 2D alignment
    // absorbs shifts and in-plane turns, not the change of a 3D model's appearance under out-of-plane turns.
    const double range = std::min(options.prior_search_deg, prior->angle_tolerance_deg);
    const int steps = options.prior_step_deg > 0 ? static_cast<int>(std::floor(range / options.prior_step_deg)) : 0;
    const Vector3d c = prior->pose.apply(model_centre(model));
    starts.push_back(prior->pose);
    for (int ix = -steps; ix <= steps; ++ix) {
      for (int iy = -steps; iy <= steps; ++iy) {
        if (ix == 0 && iy == 0) continue;
        const Eigen::Quaterniond R = Eigen::AngleAxisd(rad(ix * options.prior_step_deg), Vector3d::UnitX()) *
                                     Eigen::AngleAxisd(rad(iy * options.prior_step_deg), Vector3d::UnitY());
        camera::Pose p;
        p.q_cam_model = (R * prior->pose.q_cam_model).normalized();
        p.t_cam_model_m = R * (prior->pose.t_cam_model_m - c) + c;
        starts.push_back(p);
      }
    }
  } else {
    starts = pseudo_priors(det, camera, model, options.view_samples);
  }
  res.pseudo_priors = starts.size();
  for (const camera::Pose& p : starts) search.align(p);
  const std::vector<Scored> refined = search.solve(res.hypotheses);
  if (refined.empty()) {
    res.message = prior ? "no hypothesis gave a pose within the prior's tolerance" : "no hypothesis gave a pose";
    return res;
  }
  // Distinct verified candidates (refined to poses more than inlier_px apart in the image) are compared on the cells
  // where they differ, as the model's symmetries below: the pose must explain the events clearly better than each
  // other one (log-likelihood ratio at the symmetries' decision level), else the window is ambiguous. Ranking them
  // by supported cells or explained events preferred a pose laid partly on a decoy's edges (it explains the decoy's
  // events too) over the true pose, which the comparison favoured by 11.8 (docs/algorithms.md).
  const double level = symmetry_decision_log_ratio(options.verification);
  // In the ranking's order (stable: equal ones in the refine's order), so that of two copies the better-ranked
  // one represents its pose and ties go to the ranking.
  std::vector<const Scored*> ranked;
  for (const Scored& c : refined) ranked.push_back(&c);
  std::stable_sort(ranked.begin(), ranked.end(),
                   [](const Scored* l, const Scored* r) { return ranked_before(*l, *r); });
  const Scored* best = ranked.front();
  std::vector<const Scored*> verified;
  for (const Scored* c : ranked) {
    if (!c->verified) continue;
    const bool copy = std::any_of(verified.begin(), verified.end(), [&](const Scored* v) {
      return image_distance_px(camera, model, v->T, c->T) <= options.inlier_px;
    });
    if (!copy) verified.push_back(c);
  }
  if (verified.size() > 1) {
    // Each candidate's least log-likelihood ratio against the others; a pair without a discriminating cell (the
    // two images within the side strips everywhere: the same pose at the events' resolution) is no rival.
    const Scored* winner = nullptr;
    const Scored* rival = nullptr;
    double margin = -std::numeric_limits<double>::infinity();
    for (const Scored* a : verified) {
      double least = std::numeric_limits<double>::infinity();
      const Scored* least_of = nullptr;
      for (const Scored* b : verified) {
        if (b == a) continue;
        const PoseComparison cmp = compare_poses(events, camera, model, a->T, b->T, options.verification);
        if (cmp.cells_a_only + cmp.cells_b_only == 0) continue;
        if (cmp.log_ratio < least) {
          least = cmp.log_ratio;
          least_of = b;
        }
      }
      if (least > margin) {
        margin = least;
        winner = a;
        rival = least_of;
      }
    }
    if (margin < level) {
      res.message = fmt::format(
          "{} distinct poses verify and the events do not tell the best apart from another (log-likelihood ratio "
          "{:.1f}, need {:.1f}; {:.0f} mm / {:.1f} deg apart): ambiguous",
          verified.size(), margin, level, 1000.0 * camera::translation_distance_m(winner->T, rival->T),
          camera::rotation_angle_deg(winner->T, rival->T));
      return res;
    }
    best = winner;
  }
  res.explained_events = best->explained;
  res.support_share = static_cast<double>(best->explained) / static_cast<double>(events.size());
  res.correspondences = best->correspondences;
  res.line_share = search.line_share(best->T);
  const double share = line_support > 0 ? static_cast<double>(best->explained) / line_support : 0.0;
  if (best->correspondences < options.min_lines || share < options.min_explained_share) {
    res.message = fmt::format(
        "best pose has {} line correspondences and explains {} events ({:.0f}% of the events on detected lines, "
        "need {:.0f}%)",
        best->correspondences, best->explained, 100.0 * share, 100.0 * options.min_explained_share);
    return res;
  }
  // The model's partial symmetries (verification.hpp): the pose turned by one shares most of its image with the
  // pose, and the search may stop on either (the board seen from behind: its outline and top bar on the true ones,
  // only the inner marks elsewhere). Each alternative inside the prior's tolerance (with a prior the others are
  // excluded by it) is compared on the cells where the two differ: one that explains the events clearly better
  // replaces the pose (refined like the candidates, and verified); one that cannot be ruled out refuses it.
  Scored chosen = *best;
  for (int pass = 0; pass < 2; ++pass) {
    bool switched = false;
    for (std::size_t k = 0; k < options.verification.symmetries.size() && !switched; ++k) {
      const camera::Pose alt = chosen.T * options.verification.symmetries[k];
      if (!search.acceptable(alt)) continue;
      const PoseComparison cmp = compare_poses(events, camera, model, chosen.T, alt, options.verification);
      if (cmp.log_ratio >= level) continue;
      if (cmp.log_ratio > -level) {
        res.message = fmt::format(
            "the pose and the pose turned by the model's symmetry {} explain the events alike (log-likelihood ratio "
            "{:.1f} on {} + {} cells where they differ): ambiguous",
            k, cmp.log_ratio, cmp.cells_a_only, cmp.cells_b_only);
        return res;
      }
      Scored other = search.refine(Scored{alt, search.explained(alt), 0});
      if (!other.verified ||
          compare_poses(events, camera, model, other.T, chosen.T, options.verification).log_ratio < level) {
        res.message = fmt::format(
            "the pose turned by the model's symmetry {} explains the events better (log-likelihood ratio {:.1f}), "
            "but it does not verify once refined",
            k, -cmp.log_ratio);
        return res;
      }
      chosen = other;
      switched = true;
    }
    if (!switched) break;
  }
  if (chosen.T.t_cam_model_m != best->T.t_cam_model_m) {
    res.explained_events = chosen.explained;
    res.support_share = static_cast<double>(chosen.explained) / static_cast<double>(events.size());
    res.correspondences = chosen.correspondences;
    res.line_share = search.line_share(chosen.T);
  }
  res.ok = true;
  res.verified = chosen.verified;
  res.T_cam_model = chosen.T;
  res.message = fmt::format(
      "{} lines ({:.0f}% of their events on lines the pose matches), {} correspondences, {} "
      "events explained ({:.0f}% of the window)",
      lines.size(), 100.0 * res.line_share, best->correspondences, best->explained, 100.0 * res.support_share);
  return res;
}

}  // namespace

}  // namespace evpipe::pose
