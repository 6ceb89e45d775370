#include "evpipe/pose/prior_alignment.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <numeric>
#include <vector>

namespace evpipe::pose {

namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

constexpr double kNear_m = 0.01;

double rad(double d) {
  return d * std::numbers::pi / 180.0;
}

// The events' occupancy in undistorted pixels (an ideal pinhole with the camera's K), on a grid that holds the
// undistorted sensor; blurred copies per level.
class Occupancy {
 public:
  Occupancy(EventSpan events, const camera::CameraModel& cam) {
    // The undistorted image of the sensor's border bounds the grid.
    Vector2d lo = Vector2d::Constant(1e300), hi = Vector2d::Constant(-1e300);
    const auto grow = [&](double x, double y) {
      const Vector2d u = cam.undistort({x, y});
      if (!u.allFinite()) return;
      lo = lo.cwiseMin(u);
      hi = hi.cwiseMax(u);
    };
    for (int x = 0; x < cam.width; ++x) {
      grow(x, 0);
      grow(x, cam.height - 1);
    }
    for (int y = 0; y < cam.height; ++y) {
      grow(0, y);
      grow(cam.width - 1, y);
    }
    // At most 3x the sensor each way (a strong distortion model extrapolates wildly at the corners).
    lo = lo.cwiseMax(Vector2d(-cam.width, -cam.height));
    hi = hi.cwiseMin(Vector2d(2.0 * cam.width, 2.0 * cam.height));
    x0_ = std::floor(lo.x()) - 2;
    y0_ = std::floor(lo.y()) - 2;
    w_ = static_cast<int>(std::ceil(hi.x()) - x0_) + 3;
    h_ = static_cast<int>(std::ceil(hi.y()) - y0_) + 3;
    occ_.assign(static_cast<std::size_t>(w_) * static_cast<std::size_t>(h_), 0.0F);
    std::vector<Vector2d> table(static_cast<std::size_t>(cam.width) * static_cast<std::size_t>(cam.height),
                                Vector2d::Constant(std::numeric_limits<double>::quiet_NaN()));
    std::vector<char> done(table.size(), 0);
    for (const Event& e : events) {
      if (e.x >= cam.width || e.y >= cam.height) continue;
      const std::size_t i = static_cast<std::size_t>(e.y) * static_cast<std::size_t>(cam.width) + e.x;
      if (done[i] != 0) continue;
      done[i] = 1;
      table[i] = cam.undistort({static_cast<double>(e.x), static_cast<double>(e.y)});
      const Vector2d& u = table[i];
      if (!u.allFinite()) continue;
      const int gx = static_cast<int>(std::lround(u.x() - x0_)), gy = static_cast<int>(std::lround(u.y() - y0_));
      if (gx < 0 || gy < 0 || gx >= w_ || gy >= h_) continue;
      occ_[static_cast<std::size_t>(gy) * static_cast<std::size_t>(w_) + static_cast<std::size_t>(gx)] = 1.0F;
      ++pixels_;
    }
  }

  [[nodiscard]] std::size_t pixels() const { return pixels_; }

  // The occupancy blurred with a Gaussian of sigma pixels (separable).
  void blur(double sigma) {
    const int r = std::max(1, static_cast<int>(std::ceil(3.0 * sigma)));
    std::vector<float> k(static_cast<std::size_t>(2 * r + 1));
    float sum = 0.0F;
    for (int i = -r; i <= r; ++i) {
      k[static_cast<std::size_t>(i + r)] = static_cast<float>(std::exp(-0.5 * i * i / (sigma * sigma)));
      sum += k[static_cast<std::size_t>(i + r)];
    }
    for (float& v : k) v /= sum;
    std::vector<float> tmp(occ_.size(), 0.0F);
    g_.assign(occ_.size(), 0.0F);
    for (int y = 0; y < h_; ++y) {
      for (int x = 0; x < w_; ++x) {
        float s = 0.0F;
        for (int i = -r; i <= r; ++i) {
          const int xx = x + i;
          if (xx >= 0 && xx < w_) s += k[static_cast<std::size_t>(i + r)] * at(occ_, xx, y);
        }
        tmp[static_cast<std::size_t>(y) * static_cast<std::size_t>(w_) + static_cast<std::size_t>(x)] = s;
      }
    }
    for (int y = 0; y < h_; ++y) {
      for (int x = 0; x < w_; ++x) {
        float s = 0.0F;
        for (int i = -r; i <= r; ++i) {
          const int yy = y + i;
          if (yy >= 0 && yy < h_) s += k[static_cast<std::size_t>(i + r)] * at(tmp, x, yy);
        }
        g_[static_cast<std::size_t>(y) * static_cast<std::size_t>(w_) + static_cast<std::size_t>(x)] = s;
      }
    }
  }

  // Ridge-contrast images of the blurred occupancy for kBins normal directions (over 180 deg): at each grid pixel
  // g(x) - (g(x + h n) + g(x - h n)) / 2. The level-0 grid reads them at the nearest pixel (one read per sample).
  static constexpr int kBins = 16;
  static int bin_of(const Vector2d& n) {
    double a = std::atan2(n.y(), n.x());
    if (a < 0.0) a += std::numbers::pi;
    return static_cast<int>(std::lround(a / std::numbers::pi * kBins)) % kBins;
  }
  void contrast(double h) {
    c_.assign(static_cast<std::size_t>(kBins), std::vector<float>(g_.size(), 0.0F));
    for (int b = 0; b < kBins; ++b) {
      const double a = b * std::numbers::pi / kBins;
      const Vector2d n(std::cos(a), std::sin(a));
      auto& img = c_[static_cast<std::size_t>(b)];
      for (int y = 0; y < h_; ++y) {
        for (int x = 0; x < w_; ++x) {
          const Vector2d p(x + x0_, y + y0_);
          img[static_cast<std::size_t>(y) * static_cast<std::size_t>(w_) + static_cast<std::size_t>(x)] =
              static_cast<float>(at(g_, x, y) - 0.5 * (g(p + h * n) + g(p - h * n)));
        }
      }
    }
  }
  // The nearest pixel is std::lround's (half away from zero), written inline: the libm call was a quarter of an
  // alignment's time. Inside (-0.5, n - 0.5) adding the largest double below 0.5 and truncating rounds exactly as
  // lround does (GCC's own inline expansion of lround); outside, and for NaN, lround's pixel is off the grid too.
  [[nodiscard]] double c_near(const Vector2d& p, int bin) const {
    constexpr double kJustBelowHalf = 0.49999999999999994;  // std::nextafter(0.5, 0.0)
    const double fx = p.x() - x0_, fy = p.y() - y0_;
    if (!(fx > -0.5 && fy > -0.5 && fx < w_ - 0.5 && fy < h_ - 0.5)) return 0.0;
    const auto x = static_cast<long>(fx + kJustBelowHalf), y = static_cast<long>(fy + kJustBelowHalf);
    return c_[static_cast<std::size_t>(bin)]
             [static_cast<std::size_t>(y) * static_cast<std::size_t>(w_) + static_cast<std::size_t>(x)];
  }

  // Bilinear lookup of the blurred image at undistorted pixel p (0 outside).
  [[nodiscard]] double g(const Vector2d& p) const {
    const double fx = p.x() - x0_, fy = p.y() - y0_;
    if (!(fx >= 0.0 && fy >= 0.0 && fx < w_ - 1 && fy < h_ - 1)) return 0.0;
    const int ix = static_cast<int>(fx), iy = static_cast<int>(fy);
    const double ax = fx - ix, ay = fy - iy;
    return (1 - ay) * ((1 - ax) * at(g_, ix, iy) + ax * at(g_, ix + 1, iy)) +
           ay * ((1 - ax) * at(g_, ix, iy + 1) + ax * at(g_, ix + 1, iy + 1));
  }

 private:
  [[nodiscard]] float at(const std::vector<float>& v, int x, int y) const {
    return v[static_cast<std::size_t>(y) * static_cast<std::size_t>(w_) + static_cast<std::size_t>(x)];
  }
  double x0_{0}, y0_{0};
  int w_{0}, h_{0};
  std::vector<float> occ_, g_;
  std::vector<std::vector<float>> c_;
  std::size_t pixels_{0};
};

// Per projected segment in front of the camera (pinhole, undistorted pixels): its length and the image distance to
// the nearest other segment parallel to it (within 5 deg) and beside it (infinity when none).
struct Neighbour {
  double length_px{0.0};
  double nearest_px{std::numeric_limits<double>::infinity()};
};

std::vector<Neighbour> parallel_neighbours(const camera::CameraModel& camera, const camera::LineModel& model,
                                           const camera::Pose& T_cam_model) {
  struct S2 {
    Vector2d a, b;
  };
  const auto pinhole = [&](const Vector3d& p) {
    return Vector2d(camera.fx * p.x() / p.z() + camera.cx, camera.fy * p.y() / p.z() + camera.cy);
  };
  std::vector<S2> segs;
  for (const auto& s : model.segments_m) {
    const Vector3d A = T_cam_model.apply(s.a_m), B = T_cam_model.apply(s.b_m);
    if (A.z() < kNear_m || B.z() < kNear_m) continue;
    segs.push_back({pinhole(A), pinhole(B)});
  }
  std::vector<Neighbour> out(segs.size());
  for (std::size_t i = 0; i < segs.size(); ++i) {
    const Vector2d d = segs[i].b - segs[i].a;
    const double len = d.norm();
    if (!std::isfinite(len)) continue;
    out[i].length_px = len;
    if (!(len > 1.0)) continue;
    const Vector2d u = d / len;
    for (std::size_t j = 0; j < segs.size(); ++j) {
      if (j == i) continue;
      const Vector2d e = segs[j].b - segs[j].a;
      if (!(e.norm() > 1.0) || std::abs(u.x() * e.y() - u.y() * e.x()) / e.norm() > std::sin(rad(5.0))) continue;
      const Vector2d m = 0.5 * (segs[j].a + segs[j].b) - segs[i].a;
      const double t = m.dot(u);
      if (t < 0.0 || t > len) continue;  // not beside each other
      const double dist = std::abs(u.x() * m.y() - u.y() * m.x());
      if (dist > 0.5) out[i].nearest_px = std::min(out[i].nearest_px, dist);
    }
  }
  return out;
}

}  // namespace

double parallel_spacing_px(const camera::CameraModel& camera, const camera::LineModel& model,
                           const camera::Pose& T_cam_model) {
  double best = std::numeric_limits<double>::infinity();
  for (const Neighbour& n : parallel_neighbours(camera, model, T_cam_model)) best = std::min(best, n.nearest_px);
  return best;
}

double crowded_length_share(const camera::CameraModel& camera, const camera::LineModel& model,
                            const camera::Pose& T_cam_model, double spacing_px) {
  double crowded = 0.0, total = 0.0;
  for (const Neighbour& n : parallel_neighbours(camera, model, T_cam_model)) {
    total += n.length_px;
    if (n.nearest_px < spacing_px) crowded += n.length_px;
  }
  return total > 0.0 ? crowded / total : 0.0;
}

namespace {

// Parameters of a pose around the prior (see the header).
struct Params {
  std::array<double, 6> v{};  // du, dv, roll, log scale, tilt x, tilt y
};

struct Sample {
  Vector2d p;
  Vector2d n;
  double w{1.0};
  int bin{0};  // Occupancy::bin_of(n)
};

class Aligner {
 public:
  Aligner(const camera::CameraModel& cam, const camera::LineModel& model, const camera::PosePrior& prior,
          Occupancy& occ)
      : cam_(cam), model_(model), prior_(prior), occ_(occ) {
    Vector3d lo = Vector3d::Constant(1e300), hi = Vector3d::Constant(-1e300);
    for (const auto& s : model.segments_m) {
      lo = lo.cwiseMin(s.a_m).cwiseMin(s.b_m);
      hi = hi.cwiseMax(s.a_m).cwiseMax(s.b_m);
    }
    centre_model_ = 0.5 * (lo + hi);
    centre_cam_ = prior.pose.apply(centre_model_);
    u0_ = pinhole(centre_cam_);
  }

  [[nodiscard]] bool in_front() const { return centre_cam_.z() > kNear_m && u0_.allFinite(); }

  [[nodiscard]] Vector2d pinhole(const Vector3d& p) const {
    return {cam_.fx * p.x() / p.z() + cam_.cx, cam_.fy * p.y() / p.z() + cam_.cy};
  }

  [[nodiscard]] camera::Pose pose(const Params& p) const {
    const double z = centre_cam_.z() * std::exp(-p.v[3]);
    const Vector3d c((u0_.x() + p.v[0] - cam_.cx) / cam_.fx * z, (u0_.y() + p.v[1] - cam_.cy) / cam_.fy * z, z);
    const Eigen::Quaterniond R = Eigen::Quaterniond(Eigen::AngleAxisd(p.v[2], centre_cam_.normalized())) *
                                 Eigen::Quaterniond(Eigen::AngleAxisd(p.v[4], Vector3d::UnitX())) *
                                 Eigen::Quaterniond(Eigen::AngleAxisd(p.v[5], Vector3d::UnitY()));
    camera::Pose T;
    T.q_cam_model = (R * prior_.pose.q_cam_model).normalized();
    T.t_cam_model_m = R * (prior_.pose.t_cam_model_m - centre_cam_) + c;
    return T;
  }

  // The image radius of the model around its centre at the prior (pixels): the lever of roll and scale.
  [[nodiscard]] double radius_px() const {
    double r = 0.0;
    for (const auto& s : model_.segments_m) {
      for (const Vector3d& m : {s.a_m, s.b_m}) {
        const Vector3d c = prior_.pose.apply(m);
        if (c.z() > kNear_m) r = std::max(r, (pinhole(c) - u0_).norm());
      }
    }
    return std::max(r, 5.0);
  }

  [[nodiscard]] double parallel_spacing_px() const { return pose::parallel_spacing_px(cam_, model_, prior_.pose); }

  // Samples along the projected model (undistorted pixels) every `spacing` pixels.
  void samples(const camera::Pose& T, double spacing, std::vector<Sample>& out) const {
    out.clear();
    for (const auto& s : model_.segments_m) {
      Vector3d A = T.apply(s.a_m), B = T.apply(s.b_m);
      if (A.z() < kNear_m && B.z() < kNear_m) continue;
      if (A.z() < kNear_m) A = A + (kNear_m - A.z()) / (B.z() - A.z()) * (B - A);
      if (B.z() < kNear_m) B = B + (kNear_m - B.z()) / (A.z() - B.z()) * (A - B);
      const Vector2d a = pinhole(A), b = pinhole(B);
      const double len = (b - a).norm();
      if (!std::isfinite(len) || len < 1.0) continue;
      const Vector2d d = (b - a) / len;
      const Vector2d n(-d.y(), d.x());
      const int k = std::min(4000, static_cast<int>(std::floor(len / spacing)));
      const double step = len / std::max(k, 1);
      const int bin = Occupancy::bin_of(n);
      for (int i = 0; i <= k; ++i) {
        out.push_back({a + (i * step) * d, n, (i == 0 || i == k) ? 0.5 * step : step, bin});
      }
    }
  }

  // Ridge contrast of the samples shifted by (dx, dy) pixels.
  [[nodiscard]] double score(const std::vector<Sample>& s, double h, double dx = 0.0, double dy = 0.0) const {
    double sum = 0.0;
    const Vector2d o(dx, dy);
    for (const Sample& q : s) {
      const Vector2d p = q.p + o;
      sum += q.w * (occ_.g(p) - 0.5 * (occ_.g(p + h * q.n) + occ_.g(p - h * q.n)));
    }
    return sum;
  }

  // The same from the contrast images at the nearest pixel (level 0).
  [[nodiscard]] double score_near(const std::vector<Sample>& s, double dx, double dy) const {
    double sum = 0.0;
    const Vector2d o(dx, dy);
    for (const Sample& q : s) sum += q.w * occ_.c_near(q.p + o, q.bin);
    return sum;
  }

  [[nodiscard]] double score(const Params& p, double spacing, double h) {
    ++evaluations;
    samples(pose(p), spacing, buf_);
    return score(buf_, h);
  }

  // Largest image displacement between the projected models of two poses (segment ends, undistorted pixels).
  [[nodiscard]] double image_distance(const camera::Pose& a, const camera::Pose& b) const {
    double d = 0.0;
    for (const auto& s : model_.segments_m) {
      for (const Vector3d& m : {s.a_m, s.b_m}) {
        const Vector3d pa = a.apply(m), pb = b.apply(m);
        if (pa.z() < kNear_m || pb.z() < kNear_m) return 1e9;
        d = std::max(d, (pinhole(pa) - pinhole(pb)).norm());
      }
    }
    return d;
  }

  [[nodiscard]] bool within_prior(const camera::Pose& T) const {
    return camera::translation_distance_m(T, prior_.pose) <= prior_.position_tolerance_m &&
           camera::rotation_angle_deg(T, prior_.pose) <= prior_.angle_tolerance_deg;
  }

  std::size_t evaluations{0};

 private:
  const camera::CameraModel& cam_;
  const camera::LineModel& model_;
  const camera::PosePrior& prior_;
  Occupancy& occ_;
  Vector3d centre_model_;
  Vector3d centre_cam_;
  Vector2d u0_;
  std::vector<Sample> buf_;
};

struct Cand {
  Params p;
  double score{0.0};
};

// Pattern search at one level: each parameter +- its step, the best improving move taken; steps halved (twice)
// when none improves.
Cand pattern_search(Aligner& al, Cand c, std::array<double, 6> step, double spacing, double h, int max_moves) {
  c.score = al.score(c.p, spacing, h);
  for (int halvings = 0, iter = 0; halvings <= 2 && iter < max_moves; ++iter) {
    Cand best = c;
    for (std::size_t k = 0; k < 6; ++k) {
      for (const double sgn : {-1.0, 1.0}) {
        Cand t = c;
        t.p.v[k] += sgn * step[k];
        t.score = al.score(t.p, spacing, h);
        if (t.score > best.score) best = t;
      }
    }
    if (best.score > c.score) {
      c = best;
      continue;
    }
    for (double& s : step) s *= 0.5;
    ++halvings;
  }
  return c;
}

}  // namespace

PriorAlignmentResult align_at_prior(EventSpan events, const camera::CameraModel& camera, const camera::LineModel& model,
                                    const camera::PosePrior& prior, const PriorAlignmentOptions& o) {
  PriorAlignmentResult res;
  res.T_cam_model = prior.pose;
  if (events.empty() || model.segments_m.empty()) {
    res.message = "no events or no model";
    return res;
  }
  Occupancy occ(events, camera);
  Aligner al(camera, model, prior, occ);
  if (!al.in_front()) {
    res.message = "the model's centre is not in front of the camera at the prior";
    return res;
  }
  const double R = al.radius_px();
  const double f = 0.5 * (camera.fx + camera.fy);
  // The search range from the prior's tolerance: the centre's image moves by f x (position error) / depth; the depth
  // moves within the position tolerance (the image scale with it); roll and tilts within the angle tolerance.
  const camera::Pose& P = prior.pose;
  Vector3d lo = Vector3d::Constant(1e300), hi = Vector3d::Constant(-1e300);
  for (const auto& s : model.segments_m) {
    lo = lo.cwiseMin(s.a_m).cwiseMin(s.b_m);
    hi = hi.cwiseMax(s.a_m).cwiseMax(s.b_m);
  }
  const double zc = P.apply(0.5 * (lo + hi)).z();
  const double shift_range = std::min(o.max_shift_px, f * prior.position_tolerance_m / zc);
  const double roll_range = rad(std::min(o.max_roll_deg, prior.angle_tolerance_deg));
  const double ls_hi = std::log(zc / std::max(0.5 * zc, zc - prior.position_tolerance_m));
  const double ls_lo = std::log(zc / (zc + prior.position_tolerance_m));
  const double tilt_range = rad(std::min(o.coarse_tilt_deg * o.coarse_tilt_steps, prior.angle_tolerance_deg));

  // Level 0: the grid, at the finest blur whose work fits max_level0_reads.
  const int ntilt =
      o.coarse_tilt_steps > 0 && o.coarse_tilt_deg > 0 ? static_cast<int>(tilt_range / rad(o.coarse_tilt_deg)) : 0;
  std::vector<Sample> base;
  al.samples(P, 1.0, base);
  const auto projected_px = static_cast<double>(base.size());  // the model's image length at the prior (about)
  const auto level0_reads = [&](double s) {
    const double a = s / R;
    const double poses = (2.0 * std::floor(roll_range / a) + 1.0) * (std::floor((ls_hi - ls_lo) / a) + 1.0) *
                         (std::numbers::pi * std::pow(std::floor(shift_range / s) + 0.5, 2.0)) *
                         std::pow(2.0 * ntilt + 1.0, 2.0);
    return poses * (projected_px / s + static_cast<double>(model.segments_m.size()));
  };
  double sigma = std::max(1.0, std::min(o.coarse_sigma_px, 0.5 * al.parallel_spacing_px()));
  while (level0_reads(sigma) > o.max_level0_reads && sigma < shift_range) sigma *= 1.25;
  occ.blur(sigma);
  double h = std::max(2.5, 2.5 * sigma);
  occ.contrast(h);
  const double ang_step = sigma / R;
  std::vector<Cand> all;
  // Only the best scores can become candidates: the list is cut back to them as it grows (bounded memory).
  const std::size_t keep_best = std::max<std::size_t>(o.candidates * 4096, 1);
  const auto by_score = [](const Cand& a, const Cand& b) { return a.score > b.score; };
  const int nroll = static_cast<int>(std::floor(roll_range / ang_step));
  const int nshift = static_cast<int>(std::floor(shift_range / sigma));
  for (int it = -ntilt; it <= ntilt; ++it) {
    for (int jt = -ntilt; jt <= ntilt; ++jt) {
      for (int ir = -nroll; ir <= nroll; ++ir) {
        for (double ls = std::ceil(ls_lo / ang_step) * ang_step; ls <= ls_hi + 1e-12; ls += ang_step) {
          Params p;
          p.v = {0.0, 0.0, ir * ang_step, ls, it * rad(o.coarse_tilt_deg), jt * rad(o.coarse_tilt_deg)};
          al.samples(al.pose(p), sigma, base);
          if (base.empty()) continue;
          for (int iu = -nshift; iu <= nshift; ++iu) {
            for (int iv = -nshift; iv <= nshift; ++iv) {
              if (std::hypot(iu, iv) * sigma > shift_range) continue;
              ++al.evaluations;
              Cand c;
              c.p = p;
              c.p.v[0] = iu * sigma;
              c.p.v[1] = iv * sigma;
              c.score = al.score_near(base, iu * sigma, iv * sigma);
              all.push_back(c);
            }
          }
          if (all.size() >= 4 * keep_best) {
            std::nth_element(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(keep_best), all.end(), by_score);
            all.resize(keep_best);
          }
        }
      }
    }
  }
  if (all.empty()) {
    res.message = "the model is not in view anywhere within the prior's tolerance";
    return res;
  }
  std::vector<std::size_t> order(all.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return all[a].score > all[b].score; });
  std::vector<Cand> keep;
  for (const std::size_t i : order) {
    if (keep.size() >= o.candidates || all[i].score <= 0.0) break;
    bool distinct = true;
    // One candidate per place: the best roll and scale there (the variants of one wrong place would fill the list).
    for (const Cand& k : keep)
      distinct = distinct && std::hypot(k.p.v[0] - all[i].p.v[0], k.p.v[1] - all[i].p.v[1]) > 2.0 * sigma;
    if (distinct) keep.push_back(all[i]);
  }
  all.clear();
  // Finer levels.
  while (true) {
    const bool last = sigma <= 1.0;
    const double spacing = std::max(o.sample_px, 0.5 * sigma);
    const std::array<double, 6> step = {sigma, sigma, sigma / R, sigma / R, 3.0 * sigma / R, 3.0 * sigma / R};
    for (Cand& c : keep) c = pattern_search(al, c, step, spacing, h, o.max_moves);
    if (last) break;
    sigma = std::max(1.0, 0.5 * sigma);
    occ.blur(sigma);
    h = std::max(2.5, 2.5 * sigma);
  }
  // Nearby local maxima of the best (a grid shifted by a line or two): searched from its pose shifted by a few
  // pixels each way at the finest level.
  std::sort(keep.begin(), keep.end(), [](const Cand& a, const Cand& b) { return a.score > b.score; });
  const double spacing = o.sample_px;
  const std::array<double, 6> fine = {1.0, 1.0, 1.0 / R, 1.0 / R, 3.0 / R, 3.0 / R};
  if (!keep.empty()) {
    const Cand best = keep.front();
    for (const double dist : {3.0, 6.0, 9.0}) {
      for (int k = 0; k < 8; ++k) {
        Cand c = best;
        c.p.v[0] += dist * std::cos(k * std::numbers::pi / 4.0);
        c.p.v[1] += dist * std::sin(k * std::numbers::pi / 4.0);
        keep.push_back(pattern_search(al, c, fine, spacing, h, o.max_moves));
      }
    }
  }
  std::sort(keep.begin(), keep.end(), [](const Cand& a, const Cand& b) { return a.score > b.score; });
  res.evaluations = al.evaluations;
  std::optional<Cand> best;
  for (const Cand& c : keep) {
    const camera::Pose T = al.pose(c.p);
    if (!al.within_prior(T) || c.score <= 0.0) continue;
    if (!best) {
      best = c;
      res.T_cam_model = T;
      res.score = c.score;
      continue;
    }
    if (al.image_distance(T, res.T_cam_model) > o.runner_up_px) {
      res.runner_up = T;
      res.runner_up_score = c.score;
      break;
    }
  }
  if (!best) {
    res.message = "no pose within the prior's tolerance shows the model's edges";
    return res;
  }
  res.ok = true;
  res.message = fmt::format("ridge contrast {:.1f} (runner-up {:.1f}), {} poses scored", res.score, res.runner_up_score,
                            res.evaluations);
  return res;
}

double prior_alignment_score(EventSpan events, const camera::CameraModel& camera, const camera::LineModel& model,
                             const camera::Pose& T_cam_model, double sigma_px, double sample_px) {
  Occupancy occ(events, camera);
  camera::PosePrior p;
  p.pose = T_cam_model;
  Aligner al(camera, model, p, occ);
  if (!al.in_front()) return 0.0;
  const double sigma = std::max(1.0, sigma_px);
  occ.blur(sigma);
  return al.score(Params{}, std::max(sample_px, 0.5 * sigma), std::max(2.5, 2.5 * sigma));
}

}  // namespace evpipe::pose
