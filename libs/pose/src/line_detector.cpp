#include "evpipe/pose/line_detector.hpp"

#include <Eigen/Eigenvalues>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace evpipe::pose {

namespace {

using Eigen::Vector2d;

// A segment in working coordinates (undistorted pixels with a camera, measured pixels without).
struct WSeg {
  Vector2d a;
  Vector2d b;
  [[nodiscard]] double length() const { return (b - a).norm(); }
  [[nodiscard]] Vector2d dir() const { return (b - a).normalized(); }
  [[nodiscard]] Vector2d mid() const { return 0.5 * (a + b); }
};

double deg(double rad) {
  return rad * 180.0 / std::numbers::pi;
}

// Angle between two directions modulo 180°, degrees in [0, 90].
double angle_mod_pi_deg(const Vector2d& u, const Vector2d& v) {
  const double c = std::clamp(std::abs(u.dot(v)) / (u.norm() * v.norm()), 0.0, 1.0);
  return deg(std::acos(c));
}

// Perpendicular distance of p from the infinite line of s.
double line_distance(const WSeg& s, const Vector2d& p) {
  const Vector2d u = s.dir();
  const Vector2d d = p - s.a;
  return std::abs(u.x() * d.y() - u.y() * d.x());
}

// Coordinates of the converter between measured and working pixels.
class Space {
 public:
  Space(const std::optional<camera::CameraModel>& cam, SensorGeometry g) : cam_(cam), g_(g) {
    if (cam_) cache_.assign(g.pixels(), Vector2d(std::numeric_limits<double>::quiet_NaN(), 0.0));
  }
  [[nodiscard]] Vector2d to_work(const Vector2d& px) const { return cam_ ? cam_->undistort(px) : px; }
  [[nodiscard]] Vector2d to_measured(const Vector2d& pu) const {
    if (!cam_) return pu;
    const Vector2d xy((pu.x() - cam_->cx) / cam_->fx, (pu.y() - cam_->cy) / cam_->fy);
    return cam_->normalised_to_pixel(xy);
  }
  // Working position of a sensor pixel's centre (cached: every pixel is undistorted at most once).
  const Vector2d& pixel(int x, int y) {
    if (!cam_) {
      tmp_ = Vector2d(x, y);
      return tmp_;
    }
    Vector2d& c = cache_[static_cast<std::size_t>(y) * static_cast<std::size_t>(g_.width) + x];
    if (std::isnan(c.x())) c = cam_->undistort(Vector2d(x, y));
    return c;
  }

 private:
  const std::optional<camera::CameraModel>& cam_;
  SensorGeometry g_;
  std::vector<Vector2d> cache_;
  Vector2d tmp_;
};

// Replaces pairs of (anti-)parallel, overlapping segments a few pixels apart by their mid-line (the two flanks
// of one event ridge, pose.md §9.2).
std::vector<WSeg> merge_double_responses(std::vector<WSeg> segs, const LineDetectorOptions& o) {
  std::sort(segs.begin(), segs.end(), [](const WSeg& l, const WSeg& r) { return l.length() > r.length(); });
  std::vector<bool> used(segs.size(), false);
  std::vector<WSeg> out;
  for (std::size_t i = 0; i < segs.size(); ++i) {
    if (used[i]) continue;
    used[i] = true;
    const WSeg& si = segs[i];
    const Vector2d ui = si.dir();
    std::size_t best = segs.size();
    double best_d = 1e300;
    for (std::size_t j = i + 1; j < segs.size(); ++j) {
      if (used[j]) continue;
      const WSeg& sj = segs[j];
      if (angle_mod_pi_deg(ui, sj.dir()) >= o.merge_angle_deg) continue;
      const double d = std::max(
          {line_distance(si, sj.a), line_distance(si, sj.b), line_distance(sj, si.a), line_distance(sj, si.b)});
      if (d > o.merge_distance_px) continue;
      // Extents along si must overlap.
      const double sa = ui.dot(sj.a - si.a), sb = ui.dot(sj.b - si.a);
      if (std::max(sa, sb) < 0.0 || std::min(sa, sb) > si.length()) continue;
      if (d < best_d) {
        best_d = d;
        best = j;
      }
    }
    if (best == segs.size()) {
      out.push_back(si);
      continue;
    }
    used[best] = true;
    const WSeg& sj = segs[best];
    Vector2d uj = sj.dir();
    if (uj.dot(ui) < 0) uj = -uj;
    const Vector2d u = (si.length() * ui + sj.length() * uj).normalized();
    const Vector2d c = 0.5 * (si.mid() + sj.mid());  // halfway between the two parallel lines
    double lo = 1e300, hi = -1e300;
    for (const Vector2d& p : {si.a, si.b, sj.a, sj.b}) {
      lo = std::min(lo, u.dot(p - c));
      hi = std::max(hi, u.dot(p - c));
    }
    out.push_back({c + lo * u, c + hi * u});
  }
  return out;
}

// Joins collinear fragments (repeatedly, until nothing changes).
std::vector<WSeg> merge_collinear(std::vector<WSeg> segs, double max_distance_px, double max_gap_px,
                                  double max_angle_deg) {
  bool changed = true;
  while (changed) {
    changed = false;
    std::sort(segs.begin(), segs.end(), [](const WSeg& l, const WSeg& r) { return l.length() > r.length(); });
    for (std::size_t i = 0; i < segs.size() && !changed; ++i) {
      for (std::size_t j = i + 1; j < segs.size() && !changed; ++j) {
        const WSeg& L = segs[i];  // the longer one
        const WSeg& S = segs[j];
        if (angle_mod_pi_deg(L.dir(), S.dir()) >= max_angle_deg) continue;
        if (std::max(line_distance(L, S.a), line_distance(L, S.b)) > max_distance_px) continue;
        const Vector2d u = L.dir();
        const double s0 = u.dot(S.a - L.a), s1 = u.dot(S.b - L.a);
        const double gap = std::max(std::min(s0, s1) - L.length(), -std::max(s0, s1));
        if (gap > max_gap_px) continue;
        Vector2d us = S.dir();
        if (us.dot(u) < 0) us = -us;
        const double wl = L.length(), ws = S.length();
        const Vector2d dir = (wl * u + ws * us).normalized();
        const Vector2d c = (wl * L.mid() + ws * S.mid()) / (wl + ws);
        double lo = 1e300, hi = -1e300;
        for (const Vector2d& p : {L.a, L.b, S.a, S.b}) {
          lo = std::min(lo, dir.dot(p - c));
          hi = std::max(hi, dir.dot(p - c));
        }
        segs[i] = {c + lo * dir, c + hi * dir};
        segs.erase(segs.begin() + static_cast<std::ptrdiff_t>(j));
        changed = true;
      }
    }
  }
  return segs;
}

struct Fit {
  WSeg seg;
  std::vector<std::size_t> pixels;  ///< the supporting pixels
  std::size_t support{0};
  double rms{0.0};
};

// One supporting pixel: working position, events there, signed distance and position along the line.
struct Support {
  std::size_t idx;  ///< pixel index
  Vector2d q;
  double w;
  double d;
  double s;
};

class Refitter {
 public:
  Refitter(const EventFrame& raw, Space& space, const LineDetectorOptions& o)
      : raw_(raw), space_(space), o_(o), stamp_(raw.counts.size(), 0) {}

  std::optional<Fit> refit(const WSeg& start) {
    Vector2d c = start.mid();
    Vector2d u = start.dir();
    double lo = -0.5 * start.length(), hi = 0.5 * start.length();
    const double band = o_.fit_band_px;
    const double margin = 2.0 * band;
    std::vector<Support> pts;
    for (int it = 0; it < std::max(1, o_.fit_iterations); ++it) {
      gather(c, u, lo - margin, hi + margin, band, pts);
      if (pts.size() < 2) return std::nullopt;
      // Huber-weighted total least squares: weighted centroid + principal direction of the scatter.
      double sw = 0.0;
      Vector2d m = Vector2d::Zero();
      for (const Support& p : pts) {
        const double w = p.w * (std::abs(p.d) <= o_.huber_k_px ? 1.0 : o_.huber_k_px / std::abs(p.d));
        sw += w;
        m += w * p.q;
      }
      m /= sw;
      Eigen::Matrix2d C = Eigen::Matrix2d::Zero();
      for (const Support& p : pts) {
        const double w = p.w * (std::abs(p.d) <= o_.huber_k_px ? 1.0 : o_.huber_k_px / std::abs(p.d));
        const Vector2d r = p.q - m;
        C += w * r * r.transpose();
      }
      Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> es(C);
      Vector2d un = es.eigenvectors().col(1);
      if (!un.allFinite()) return std::nullopt;
      if (un.dot(u) < 0) un = -un;
      // Keep the old extent in the new frame, then re-estimate it from the support.
      const double shift = un.dot(c - m);
      lo += shift;
      hi += shift;
      c = m;
      u = un.normalized();
      gather(c, u, lo - margin, hi + margin, band, pts);
      const auto ext = extent(pts, lo - margin, hi + margin);
      if (!ext) return std::nullopt;
      lo = ext->first;
      hi = ext->second;
    }
    // Final support and RMS inside the extent.
    gather(c, u, lo, hi, band, pts);
    double sw = 0.0, sr = 0.0;
    for (const Support& p : pts) {
      sw += p.w;
      sr += p.w * p.d * p.d;
    }
    if (sw <= 0.0) return std::nullopt;
    Fit f;
    f.pixels.reserve(pts.size());
    for (const Support& p : pts) f.pixels.push_back(p.idx);
    f.seg = {c + lo * u, c + hi * u};
    f.support = static_cast<std::size_t>(std::lround(sw));
    f.rms = std::sqrt(sr / sw);
    return f;
  }

 private:
  // Pixels with events whose working position lies within `band` of the line (c, u) and in [s0, s1] along it.
  void gather(const Vector2d& c, const Vector2d& u, double s0, double s1, double band, std::vector<Support>& out) {
    out.clear();
    ++tick_;
    const Vector2d n(-u.y(), u.x());
    const int r = static_cast<int>(std::ceil(band + 1.5));  // measured-pixel radius around each sample
    const double step = 1.0;
    for (double s = s0; s <= s1 + 0.5 * step; s += step) {
      const Vector2d pm = space_.to_measured(c + s * u);
      const int x0 = static_cast<int>(std::lround(pm.x())), y0 = static_cast<int>(std::lround(pm.y()));
      for (int y = y0 - r; y <= y0 + r; ++y) {
        if (y < 0 || y >= raw_.height) continue;
        for (int x = x0 - r; x <= x0 + r; ++x) {
          if (x < 0 || x >= raw_.width) continue;
          const std::size_t idx = static_cast<std::size_t>(y) * static_cast<std::size_t>(raw_.width) + x;
          if (stamp_[idx] == tick_) continue;
          stamp_[idx] = tick_;
          const float cnt = raw_.counts[idx];
          if (cnt <= 0.0F) continue;
          const Vector2d& q = space_.pixel(x, y);
          const double d = n.dot(q - c), sp = u.dot(q - c);
          if (std::abs(d) > band || sp < s0 || sp > s1) continue;
          out.push_back({idx, q, static_cast<double>(cnt), d, sp});
        }
      }
    }
  }

  // The extent along the line: the run of occupied 1-px bins (gaps bridged) holding the most events.
  std::optional<std::pair<double, double>> extent(const std::vector<Support>& pts, double s0, double s1) const {
    const int nb = std::max(1, static_cast<int>(std::ceil(s1 - s0)));
    std::vector<double> bins(static_cast<std::size_t>(nb), 0.0);
    for (const Support& p : pts) {
      if (std::abs(p.d) > o_.fit_band_px) continue;
      const int b = std::clamp(static_cast<int>(std::floor(p.s - s0)), 0, nb - 1);
      bins[static_cast<std::size_t>(b)] += p.w;
    }
    std::vector<double> nz;
    for (const double b : bins) {
      if (b > 0) nz.push_back(b);
    }
    if (nz.empty()) return std::nullopt;
    std::nth_element(nz.begin(), nz.begin() + static_cast<std::ptrdiff_t>(nz.size() / 2), nz.end());
    const double need = std::max(2.0, o_.extent_share * nz[nz.size() / 2]);
    const int max_gap = static_cast<int>(std::floor(o_.extent_gap_px));
    int best_a = -1, best_b = -1;
    double best_w = 0.0;
    int a = -1, last = -1;
    double w = 0.0;
    for (int i = 0; i <= nb; ++i) {
      const bool occ = i < nb && bins[static_cast<std::size_t>(i)] >= need;
      if (occ && a >= 0 && i - last - 1 > max_gap) {  // gap too long: close the run
        if (w > best_w) {
          best_w = w;
          best_a = a;
          best_b = last;
        }
        a = -1;
      }
      if (occ) {
        if (a < 0) {
          a = i;
          w = 0.0;
        }
        w += bins[static_cast<std::size_t>(i)];
        last = i;
      }
      if (i == nb && a >= 0 && w > best_w) {
        best_w = w;
        best_a = a;
        best_b = last;
      }
    }
    if (best_a < 0) return std::nullopt;
    // The extreme supporting events of the end bins give the endpoints (sub-bin).
    double lo = 1e300, hi = -1e300;
    for (const Support& p : pts) {
      if (std::abs(p.d) > o_.fit_band_px) continue;
      const int b = std::clamp(static_cast<int>(std::floor(p.s - s0)), 0, nb - 1);
      if (b < best_a || b > best_b) continue;
      lo = std::min(lo, p.s);
      hi = std::max(hi, p.s);
    }
    if (!(hi > lo)) return std::nullopt;
    return std::pair{lo, hi};
  }

  const EventFrame& raw_;
  Space& space_;
  const LineDetectorOptions& o_;
  std::vector<std::uint32_t> stamp_;
  std::uint32_t tick_{0};
};

}  // namespace

std::vector<camera::Segment2> lsd_segments(const EventFrame& frame, double lsd_scale) {
  std::vector<camera::Segment2> out;
  if (frame.width <= 0 || frame.height <= 0) return out;
  std::vector<std::uint8_t> img = to_u8(frame);
  const cv::Mat m(frame.height, frame.width, CV_8U, img.data());
  const cv::Ptr<cv::LineSegmentDetector> lsd =
      cv::createLineSegmentDetector(cv::LSD_REFINE_STD, std::clamp(lsd_scale, 0.1, 4.0));
  std::vector<cv::Vec4f> lines;
  lsd->detect(m, lines);
  out.reserve(lines.size());
  for (const cv::Vec4f& l : lines) {
    out.push_back({Vector2d(l[0], l[1]), Vector2d(l[2], l[3])});
  }
  return out;
}

std::vector<DetectedLine> detect_lines(EventSpan events, SensorGeometry geometry, const LineDetectorOptions& options) {
  std::vector<DetectedLine> result;
  if (events.empty() || geometry.width <= 0 || geometry.height <= 0) return result;
  EventFrameOptions raw_opts = options.frame;
  raw_opts.blur_sigma_px = 0.0;
  raw_opts.clip_count = 0.0F;
  const EventFrame raw = accumulate_event_frame(events, geometry, raw_opts);  // unclipped counts for the refit
  const EventFrame frame = accumulate_event_frame(events, geometry, options.frame);

  Space space(options.camera, geometry);
  std::vector<WSeg> segs;
  for (const camera::Segment2& s : lsd_segments(frame, options.lsd_scale)) {
    const WSeg w{space.to_work(s.a_px), space.to_work(s.b_px)};
    if (w.a.allFinite() && w.b.allFinite() && w.length() >= 3.0) segs.push_back(w);
  }
  segs = merge_double_responses(std::move(segs), options);
  segs = merge_collinear(std::move(segs), options.collinear_distance_px, options.collinear_gap_px,
                         options.merge_angle_deg);
  // Short pieces may still be parts of a long edge: only the refit decides their final length.
  std::erase_if(segs, [&](const WSeg& s) { return s.length() < 0.5 * options.min_length_px; });

  Refitter refitter(raw, space, options);
  std::vector<Fit> fits;
  for (const WSeg& s : segs) {
    if (auto f = refitter.refit(s)) fits.push_back(*f);
  }
  // Refits of pieces of one edge land on the same line: join them and refit the union once more.
  std::vector<WSeg> refit_segs;
  for (const Fit& f : fits) refit_segs.push_back(f.seg);
  const std::size_t before = refit_segs.size();
  refit_segs = merge_collinear(std::move(refit_segs), 0.5 * options.merge_distance_px, options.collinear_gap_px,
                               options.merge_angle_deg);
  if (refit_segs.size() != before) {
    fits.clear();
    for (const WSeg& s : refit_segs) {
      if (auto f = refitter.refit(s)) fits.push_back(*f);
    }
  }
  // Duplicates: a line whose supporting events mostly support a better line already (two proposals refit to
  // one ridge, or a fragment at a junction) is dropped.
  std::sort(fits.begin(), fits.end(), [](const Fit& l, const Fit& r) { return l.support > r.support; });
  std::vector<Fit> kept;
  std::vector<std::uint8_t> claimed(raw.counts.size(), 0);
  for (const Fit& f : fits) {
    if (f.seg.length() < options.min_length_px || f.support < options.min_support) continue;
    double total = 0.0, shared = 0.0;
    for (const std::size_t idx : f.pixels) {
      total += raw.counts[idx];
      if (claimed[idx]) shared += raw.counts[idx];
    }
    if (total <= 0.0 || shared > options.max_shared_support * total) continue;
    for (const std::size_t idx : f.pixels) claimed[idx] = 1;
    kept.push_back(f);
  }
  for (const Fit& f : kept) {
    DetectedLine d;
    d.segment_px = {space.to_measured(f.seg.a), space.to_measured(f.seg.b)};
    if (!d.segment_px.a_px.allFinite() || !d.segment_px.b_px.allFinite()) continue;
    d.support = f.support;
    d.rms_px = f.rms;
    result.push_back(d);
  }
  return result;
}

}  // namespace evpipe::pose
