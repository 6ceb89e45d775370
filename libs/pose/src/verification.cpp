// Pose verification (verification.hpp): per-cell support of the projected model against the window's noise
// density and the strips beside each cell, required where the motion makes edges fire, and the 6-DoF
// observability of what is supported.

#include "evpipe/pose/verification.hpp"

#include "pose_spread.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

namespace evpipe::pose {

namespace {

using Vector6d = Eigen::Matrix<double, 6, 1>;
using Matrix6d = Eigen::Matrix<double, 6, 6>;

constexpr double kNear_m = 1e-3;

struct Counts {
  double on{0}, left{0}, right{0};
  double on_px{0}, left_px{0}, right_px{0};
  double band_px{0};  ///< the band's pixels before those of other segments' bands were left out (>= on_px)
  /// Share of the band that is this segment's alone (1 where no other segment passes).
  [[nodiscard]] double own_share() const { return band_px > 0 ? on_px / band_px : 1.0; }
};

// Per-pixel event counts of the window.
class CountImage {
 public:
  CountImage(EventSpan events, int width, int height)
      : w_(width), h_(height), counts_(static_cast<std::size_t>(width) * height, 0), band_(counts_.size(), 0) {
    for (const Event& e : events) {
      if (e.x < w_ && e.y < h_) {
        ++counts_[idx(e.x, e.y)];
        ++total_;
      }
    }
  }
  [[nodiscard]] std::size_t idx(int x, int y) const { return static_cast<std::size_t>(y) * w_ + x; }

  // Which directions of projected segments pass each pixel: a bit per direction bin (kDirectionBins over 180 deg)
  // of every segment whose band (band_px) covers it. A pixel in the band of a segment of another direction (a
  // crossing grid line) is explained by that edge as much as by this one, and a side-strip pixel in any other
  // segment's band (a crossing, or a near parallel neighbour 4-6 px away on a small board) is not clutter beside
  // this segment: cell() leaves both out. Segments of one direction sharing a band (an edge drawn twice, collinear
  // pieces) keep it: their events support each of them alike.
  static constexpr int kDirectionBins = 16;
  [[nodiscard]] static int direction_bin(const Eigen::Vector2d& d) {
    double a = std::atan2(d.y(), d.x());
    if (a < 0.0) a += std::numbers::pi;
    return std::clamp(static_cast<int>(a / std::numbers::pi * kDirectionBins), 0, kDirectionBins - 1);
  }
  template <class Cells>
  void set_owners(const Cells& cells, double band_px) {
    owner_.assign(counts_.size(), 0);
    for (const auto& c : cells) {
      const int xa = std::max(0, static_cast<int>(std::floor(std::min(c.p_px.x(), c.q_px.x()) - band_px)));
      const int xb = std::min(w_ - 1, static_cast<int>(std::ceil(std::max(c.p_px.x(), c.q_px.x()) + band_px)));
      const int ya = std::max(0, static_cast<int>(std::floor(std::min(c.p_px.y(), c.q_px.y()) - band_px)));
      const int yb = std::min(h_ - 1, static_cast<int>(std::ceil(std::max(c.p_px.y(), c.q_px.y()) + band_px)));
      const Eigen::Vector2d d = c.q_px - c.p_px;
      const double dd = d.squaredNorm();
      const auto bit = static_cast<std::uint16_t>(1U << direction_bin(d));
      for (int y = ya; y <= yb; ++y) {
        for (int x = xa; x <= xb; ++x) {
          const Eigen::Vector2d r = Eigen::Vector2d(x, y) - c.p_px;
          const double t = dd > 0.0 ? std::clamp(r.dot(d) / dd, 0.0, 1.0) : 0.0;
          if ((r - t * d).norm() > band_px) continue;
          owner_[idx(x, y)] |= bit;
        }
      }
    }
  }
  // Whether pixel i's events belong to another segment than one of direction bin `bin` (-1: every pixel counts):
  // in the band, a segment of another direction (more than one bin away) passes it; in a side strip, any does.
  [[nodiscard]] bool foreign(std::size_t i, int bin, bool in_band) const {
    if (owner_.empty() || bin < 0 || owner_[i] == 0) return false;
    if (!in_band) return true;
    std::uint16_t same = 0;
    for (int k = -1; k <= 1; ++k)
      same |= static_cast<std::uint16_t>(1U << ((bin + k + kDirectionBins) % kDirectionBins));
    return (owner_[i] & static_cast<std::uint16_t>(~same)) != 0;
  }

  // Events in the band and the side strips of the cell p -> q (pixel centres at integer coordinates).
  Counts cell(const Eigen::Vector2d& p, const Eigen::Vector2d& q, const VerifyOptions& o, bool mark = true,
              int bin = -1) {
    Counts c;
    const Eigen::Vector2d d = q - p;
    const double len = d.norm();
    if (!(len > 1e-9)) return c;
    const Eigen::Vector2d u = d / len;
    const double side_in = o.band_px + o.side_gap_px, side_out = side_in + o.side_width_px;
    const int xa = std::max(0, static_cast<int>(std::floor(std::min(p.x(), q.x()) - side_out)));
    const int xb = std::min(w_ - 1, static_cast<int>(std::ceil(std::max(p.x(), q.x()) + side_out)));
    const int ya = std::max(0, static_cast<int>(std::floor(std::min(p.y(), q.y()) - side_out)));
    const int yb = std::min(h_ - 1, static_cast<int>(std::ceil(std::max(p.y(), q.y()) + side_out)));
    for (int y = ya; y <= yb; ++y) {
      for (int x = xa; x <= xb; ++x) {
        const Eigen::Vector2d r = Eigen::Vector2d(x, y) - p;
        const double t = r.dot(u);
        if (t < 0.0 || t >= len) continue;  // the cell's own length: neighbouring cells do not share pixels
        const double s = u.x() * r.y() - u.y() * r.x();
        const double a = std::abs(s);
        if (a <= o.band_px) c.band_px += 1;
        if (foreign(idx(x, y), bin, a <= o.band_px)) {
          if (mark && a <= o.band_px) band_[idx(x, y)] = 1;  // the model's band all the same (not background)
          continue;
        }
        const double n = counts_[idx(x, y)];
        if (a <= o.band_px) {
          c.on += n;
          c.on_px += 1;
          if (mark) band_[idx(x, y)] = 1;
        } else if (a > side_in && a <= side_out) {
          (s < 0 ? c.left : c.right) += n;
          (s < 0 ? c.left_px : c.right_px) += 1;
        }
      }
    }
    return c;
  }

  // Events per pixel away from every band marked so far (noise and the scene's other structure).
  [[nodiscard]] double background_density() const {
    double events = 0, pixels = 0;
    for (std::size_t i = 0; i < counts_.size(); ++i) {
      if (band_[i]) continue;
      events += counts_[i];
      pixels += 1;
    }
    return pixels > 0 ? events / pixels : 0.0;
  }

 private:
  int w_, h_;
  std::vector<std::uint32_t> counts_;
  std::vector<std::uint8_t> band_;
  std::vector<std::uint16_t> owner_;  // direction bits per pixel (set_owners); empty: every pixel counts
  std::size_t total_{0};
};

struct Cell {
  std::size_t segment{0};
  Eigen::Vector3d P_m{Eigen::Vector3d::Zero()};   // model point at the cell's middle
  Eigen::Vector2d n_px{Eigen::Vector2d::Zero()};  // unit image normal of the cell
  Eigen::Vector2d p_px{Eigen::Vector2d::Zero()};  // the cell's ends in the image
  Eigen::Vector2d q_px{Eigen::Vector2d::Zero()};
  Counts counts;
  double normal_motion_px{0.0};
};

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return m;
}

}  // namespace

int poisson_threshold(double mean, double false_alarm) {
  if (!(mean > 0.0)) return 1;
  // P(X >= k) = 1 - sum_{i<k} p_i; stop at the first k where it is <= false_alarm.
  double p = std::exp(-mean), cdf = 0.0;
  for (int k = 1; k < 100000; ++k) {
    cdf += p;  // P(X <= k-1)
    if (1.0 - cdf <= false_alarm) return k;
    p *= mean / k;
  }
  return 100000;
}

namespace {

// An alternative pose to compare with (T * S) and its motion hint's earlier pose.
struct Alternative {
  camera::Pose T;
  std::optional<camera::Pose> before;
  std::optional<camera::Pose> S;  ///< the model-frame motion (T * S), when T's is the model's symmetry
};

// Which segments a model-frame motion S maps onto a segment (both ends within 0.5 % of the model's extent, as
// model_symmetries), and which segments are such an image: those draw the same image under T and T * S.
void mapped_segments(const camera::LineModel& model, const camera::Pose& S, std::vector<bool>& mapped,
                     std::vector<bool>& image) {
  const auto& segs = model.segments_m;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = Eigen::Vector3d::Constant(-1e300);
  for (const auto& g : segs) {
    lo = lo.cwiseMin(g.a_m).cwiseMin(g.b_m);
    hi = hi.cwiseMax(g.a_m).cwiseMax(g.b_m);
  }
  const double tol = 0.005 * (hi - lo).norm();
  mapped.assign(segs.size(), false);
  image.assign(segs.size(), false);
  for (std::size_t i = 0; i < segs.size(); ++i) {
    const Eigen::Vector3d a = S.apply(segs[i].a_m), b = S.apply(segs[i].b_m);
    for (std::size_t j = 0; j < segs.size(); ++j) {
      if (((a - segs[j].a_m).norm() <= tol && (b - segs[j].b_m).norm() <= tol) ||
          ((a - segs[j].b_m).norm() <= tol && (b - segs[j].a_m).norm() <= tol)) {
        mapped[i] = true;
        image[j] = true;
        break;
      }
    }
  }
}

// The cells of the visible segments of pose T (segments with fewer than min_cells in view dropped), with the
// normal motion from the earlier pose `before` scaled by motion_scale; their bands are marked as the model's when
// `mark`.
// Which cells leave other segments' pixels out (CountImage::foreign): the cells of segments crossed along most of
// their length (a share of at least VerifyOptions::crossing_share of their cells has another segment's band in its
// band or side strips: a fine grid, whose lines are closer than the strips reach); -1 (every pixel counts) for the
// others, whose few crossed cells (junctions, corners) the coverage tests tolerate. The cells of a segment are
// contiguous (build_cells).
std::vector<int> crossing_bins(CountImage& img, const std::vector<Cell>& cells, const VerifyOptions& o) {
  std::vector<int> bins(cells.size(), -1);
  for (std::size_t a = 0; a < cells.size();) {
    std::size_t b = a;
    std::size_t crossed = 0;
    while (b < cells.size() && cells[b].segment == cells[a].segment) {
      const int bin = CountImage::direction_bin(cells[b].q_px - cells[b].p_px);
      const Counts all = img.cell(cells[b].p_px, cells[b].q_px, o, false, -1);
      const Counts own = img.cell(cells[b].p_px, cells[b].q_px, o, false, bin);
      crossed += own.on_px + own.left_px + own.right_px < all.on_px + all.left_px + all.right_px ? 1 : 0;
      ++b;
    }
    if (static_cast<double>(crossed) >= o.crossing_share * static_cast<double>(b - a)) {
      for (std::size_t k = a; k < b; ++k) bins[k] = CountImage::direction_bin(cells[k].q_px - cells[k].p_px);
    }
    a = b;
  }
  return bins;
}

std::vector<Cell> build_cells(CountImage& img, const camera::CameraModel& camera, const camera::LineModel& model,
                              const camera::Pose& T, const VerifyOptions& o, double motion_scale,
                              const camera::Pose* before, bool mark, bool count = true,
                              const std::vector<bool>* segments = nullptr) {
  const auto inside = [&](const Eigen::Vector2d& p) {
    return p.x() >= o.border_px && p.y() >= o.border_px && p.x() <= camera.width - 1 - o.border_px &&
           p.y() <= camera.height - 1 - o.border_px;
  };
  std::vector<Cell> cells;
  for (std::size_t i = 0; i < model.segments_m.size(); ++i) {
    if (segments && !(*segments)[i]) continue;
    const Eigen::Vector3d A = model.segments_m[i].a_m, B = model.segments_m[i].b_m;
    const Eigen::Vector3d Ac = T.apply(A), Bc = T.apply(B);
    if (!(Ac.z() > kNear_m) && !(Bc.z() > kNear_m)) continue;
    // Rough projected length (pinhole) for the number of cells; only pieces in front and inside are kept.
    const double f = 0.5 * (camera.fx + camera.fy);
    const double za = std::max(Ac.z(), kNear_m), zb = std::max(Bc.z(), kNear_m);
    const double len_px = f * (Ac.head<2>() / za - Bc.head<2>() / zb).norm();
    if (!std::isfinite(len_px)) continue;
    const int n = std::clamp(static_cast<int>(std::ceil(len_px / std::max(o.cell_px, 0.5))), 1, 2000);
    std::vector<Cell> mine;
    for (int k = 0; k < n; ++k) {
      const Eigen::Vector3d Pa = A + (B - A) * (static_cast<double>(k) / n);
      const Eigen::Vector3d Pb = A + (B - A) * (static_cast<double>(k + 1) / n);
      const Eigen::Vector3d Pc = T.apply(Pa), Qc = T.apply(Pb);
      if (!(Pc.z() > kNear_m) || !(Qc.z() > kNear_m)) continue;
      const auto p = camera.project(Pc), q = camera.project(Qc);
      if (!p || !q || !inside(*p) || !inside(*q)) continue;
      Cell c;
      c.segment = i;
      c.P_m = 0.5 * (Pa + Pb);
      const Eigen::Vector2d d = *q - *p;
      if (!(d.norm() > 1e-9)) continue;
      c.n_px = Eigen::Vector2d(-d.y(), d.x()).normalized();
      c.p_px = *p;
      c.q_px = *q;
      if (motion_scale > 0.0 && before) {
        const auto m0 = camera.project(before->apply(c.P_m));
        const auto m1 = camera.project(T.apply(c.P_m));
        if (m0 && m1) c.normal_motion_px = std::abs((*m1 - *m0).dot(c.n_px)) * motion_scale;
      }
      mine.push_back(c);
    }
    if (mine.size() < o.min_cells) continue;
    cells.insert(cells.end(), mine.begin(), mine.end());
  }
  if (count) {
    img.set_owners(cells, o.band_px);
    const std::vector<int> bins = crossing_bins(img, cells, o);
    for (std::size_t k = 0; k < cells.size(); ++k)
      cells[k].counts = img.cell(cells[k].p_px, cells[k].q_px, o, mark, bins[k]);
  }
  return cells;
}

bool cell_supported(const Counts& k, int threshold, const VerifyOptions& o) {
  const double on_d = k.on_px > 0 ? k.on / k.on_px : 0.0;
  const double left_d = k.left_px > 0 ? k.left / k.left_px : 0.0;
  const double right_d = k.right_px > 0 ? k.right / k.right_px : 0.0;
  return k.on >= threshold && on_d > o.side_ratio * left_d && on_d > o.side_ratio * right_d;
}

// Distance from point x to the segment a-b.
double segment_distance(const Eigen::Vector2d& x, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d d = b - a;
  const double dd = d.squaredNorm();
  const double t = dd > 0.0 ? std::clamp((x - a).dot(d) / dd, 0.0, 1.0) : 0.0;
  return (x - a - t * d).norm();
}

// The pixels within near_px of any of the cells (a cell's box each).
std::vector<std::uint8_t> near_mask(const std::vector<Cell>& cells, double near_px, int width, int height) {
  std::vector<std::uint8_t> near(static_cast<std::size_t>(width) * height, 0);
  for (const Cell& c : cells) {
    const int xa = std::max(0, static_cast<int>(std::floor(std::min(c.p_px.x(), c.q_px.x()) - near_px)));
    const int xb = std::min(width - 1, static_cast<int>(std::ceil(std::max(c.p_px.x(), c.q_px.x()) + near_px)));
    const int ya = std::max(0, static_cast<int>(std::floor(std::min(c.p_px.y(), c.q_px.y()) - near_px)));
    const int yb = std::min(height - 1, static_cast<int>(std::ceil(std::max(c.p_px.y(), c.q_px.y()) + near_px)));
    for (int y = ya; y <= yb; ++y) {
      for (int x = xa; x <= xb; ++x) {
        if (segment_distance(Eigen::Vector2d(x, y), c.p_px, c.q_px) <= near_px) {
          near[static_cast<std::size_t>(y) * width + x] = 1;
        }
      }
    }
  }
  return near;
}

// Cells of `mine` whose middles (to the pixel) are not in the mask of another pose's cells (near_mask).
std::vector<bool> only_in(const std::vector<Cell>& mine, const std::vector<std::uint8_t>& near, int width, int height) {
  std::vector<bool> out(mine.size(), true);
  for (std::size_t i = 0; i < mine.size(); ++i) {
    const Eigen::Vector2d m = 0.5 * (mine[i].p_px + mine[i].q_px);
    const int x = static_cast<int>(std::lround(m.x())), y = static_cast<int>(std::lround(m.y()));
    if (x >= 0 && y >= 0 && x < width && y < height && near[static_cast<std::size_t>(y) * width + x]) out[i] = false;
  }
  return out;
}

// Log-likelihood of "edges on these cells" against "no edge" (per cell: supported with p, else with alpha).
double cells_log_ratio(const std::vector<bool>& use, const std::vector<bool>& supported, const std::vector<double>& p,
                       double alpha, std::size_t& n, std::size_t& k) {
  double sum = 0.0;
  for (std::size_t i = 0; i < use.size(); ++i) {
    if (!use[i]) continue;
    const double pi = std::clamp(p[i], alpha, 1.0 - alpha);
    ++n;
    if (supported[i]) {
      ++k;
      sum += std::log(pi / alpha);
    } else {
      sum += std::log((1.0 - pi) / (1.0 - alpha));
    }
  }
  return sum;
}

VerifyResult verify_core(EventSpan events, const camera::CameraModel& camera, const camera::LineModel& model,
                         const camera::Pose& T, const VerifyOptions& o, const std::optional<MotionHint>& motion,
                         const std::vector<Alternative>& alternatives, std::vector<PoseComparison>* comparisons,
                         bool compare_always) {
  VerifyResult res;
  if (!T.t_cam_model_m.allFinite() || !T.q_cam_model.coeffs().allFinite()) {
    res.reason = "pose not finite";
    return res;
  }
  CountImage img(events, camera.width, camera.height);
  // Displacement scale: the hint's motion stretched to the window's span.
  double motion_scale = 0.0;
  if (motion && !events.empty() && motion->t_us != motion->before.t_us) {
    const double span = static_cast<double>(events.back().t_us - events.front().t_us);
    motion_scale = span / static_cast<double>(motion->t_us - motion->before.t_us);
  }
  const std::vector<Cell> cells =
      build_cells(img, camera, model, T, o, motion_scale, motion ? &motion->before.pose : nullptr, true);
  // The noise a band can hold: the window's density away from the model, times a band's area.
  const double density = img.background_density();
  double band_px_area = 0.0;
  for (const Cell& c : cells) band_px_area += c.counts.on_px;
  band_px_area = cells.empty() ? 0.0 : band_px_area / static_cast<double>(cells.size());
  res.noise_per_cell = density * band_px_area;
  res.support_threshold = poisson_threshold(res.noise_per_cell, o.false_alarm);

  // Per segment.
  std::vector<SegmentSupport> segs;
  std::vector<bool> supported(cells.size(), false);
  for (std::size_t j = 0; j < cells.size(); ++j) {
    const Cell& c = cells[j];
    if (segs.empty() || segs.back().model_index != c.segment) {
      SegmentSupport s;
      s.model_index = c.segment;
      segs.push_back(s);
    }
    SegmentSupport& s = segs.back();
    ++s.cells;
    s.normal_motion_px += c.normal_motion_px;
    supported[j] = cell_supported(c.counts, res.support_threshold, o);
    if (supported[j]) ++s.supported;
  }
  // What support a true segment can show. The events above noise per cell are measured on the window: the upper
  // median over the segments of (events above noise) per cell (a pose most of whose segments show nothing expects
  // nothing and is refused as unverifiable), or with a motion hint per pixel swept across
  // the segment (contrast / threshold; a segment moving along itself gives none). A segment's expected share of
  // supported cells is then P(Poisson(noise + expected excess) >= threshold); a segment is required when that is
  // at least 1/2, and supported when it shows at least min_segment_coverage x its expected share.
  std::vector<double> rates;
  {
    std::size_t a = 0;
    for (const SegmentSupport& s : segs) {
      double excess = 0.0, swept = 0.0;
      for (std::size_t k = 0; k < s.cells; ++k, ++a) {
        // A cell whose band is partly another segment's (a crossing) collects events on its own share only.
        const double own = cells[a].counts.own_share();
        excess += cells[a].counts.on - res.noise_per_cell * own;
        swept += own * (motion_scale > 0.0 ? o.cell_px * cells[a].normal_motion_px : 1.0);
      }
      if (swept > 0.0) rates.push_back(std::max(excess, 0.0) / swept);
    }
  }
  double rate = 0.0;
  if (!rates.empty()) {
    std::sort(rates.begin(), rates.end());
    rate = rates[rates.size() / 2];
  }
  const auto chance_supported = [&](double excess) {
    const double mean = res.noise_per_cell + excess;  // P(Poisson(mean) >= threshold)
    double p = std::exp(-mean), cdf = 0.0;
    for (int k = 0; k < res.support_threshold; ++k) {
      cdf += p;
      p *= mean / (k + 1);
    }
    return std::clamp(1.0 - cdf, 0.0, 1.0);
  };
  Matrix6d H = Matrix6d::Zero();
  std::vector<Matrix6d> H_segment;  // each supporting segment's share of H (VerifyOptions::leave_one_out)
  const double f = 0.5 * (camera.fx + camera.fy);
  const double sigma_n = o.cell_sigma_px / f;
  const Eigen::Matrix3d R = T.rotation();
  std::size_t j = 0;
  std::vector<double> expected(cells.size(), 0.0);  // each cell's expected share (its segment's)
  struct Unsupported {
    std::size_t first, count;
    double expected_share;
    std::size_t model_index;
  };
  std::vector<Unsupported> unsupported;            // required segments without their support
  std::vector<Eigen::Vector2d> supported_normals;  // image normals of the segments that fix the pose
  for (SegmentSupport& s : segs) {
    s.normal_motion_px /= static_cast<double>(std::max<std::size_t>(s.cells, 1));
    double own = 0.0;  // the segment's mean own share of its bands
    for (std::size_t k = 0; k < s.cells; ++k) own += cells[j + k].counts.own_share();
    own /= static_cast<double>(std::max<std::size_t>(s.cells, 1));
    const double expected_share =
        chance_supported(own * (motion_scale > 0.0 ? rate * o.cell_px * s.normal_motion_px : rate));
    std::fill_n(expected.begin() + static_cast<std::ptrdiff_t>(j), s.cells, expected_share);
    s.required = expected_share >= 0.5 && (motion_scale <= 0.0 || s.normal_motion_px >= o.min_normal_motion_px);
    ++res.segments_judged;
    const double expected_cells = expected_share * static_cast<double>(s.cells);
    // ... and more supported cells than noise alone gives (binomial, false_alarm per cell, ~3 sigma).
    const double n = static_cast<double>(s.cells);
    const double by_noise = n * o.false_alarm + 3.0 * std::sqrt(n * o.false_alarm * (1.0 - o.false_alarm));
    const bool seg_ok = static_cast<double>(s.supported) >= o.min_segment_coverage * expected_cells &&
                        static_cast<double>(s.supported) > by_noise;
    if (s.required) {
      ++res.segments_required;
      res.cells_required += s.cells;
      res.cells_supported += s.supported;
      res.cells_expected += expected_cells;
      if (seg_ok) ++res.segments_supported;
    }
    // Observability from the supported cells of the required segments that are supported along their length
    // (support elsewhere may be clutter the pose happens to cross), one measurement of the edge's position
    // across the cell each.
    const bool counts_for_pose = s.required && seg_ok;
    if (s.required && static_cast<double>(s.supported) <= by_noise) {
      unsupported.push_back({j, s.cells, expected_share, s.model_index});
    }
    if (counts_for_pose) {
      Eigen::Vector2d n_sum = Eigen::Vector2d::Zero();
      for (std::size_t k = 0; k < s.cells; ++k) n_sum += cells[j + k].n_px;
      if (n_sum.norm() > 0.0) supported_normals.push_back(n_sum.normalized());
      if (o.leave_one_out) H_segment.push_back(Matrix6d::Zero());
    }
    for (std::size_t k = 0; k < s.cells; ++k, ++j) {
      if (!supported[j] || !counts_for_pose) continue;
      const Cell& c = cells[j];
      const Eigen::Vector3d Q = R * c.P_m, P = Q + T.t_cam_model_m;
      Eigen::Matrix<double, 2, 3> Jp;
      Jp << 1.0 / P.z(), 0.0, -P.x() / (P.z() * P.z()), 0.0, 1.0 / P.z(), -P.y() / (P.z() * P.z());
      Eigen::Matrix<double, 3, 6> dP;
      dP.leftCols<3>() = -skew(Q);
      dP.rightCols<3>() = Eigen::Matrix3d::Identity();
      // The cell's normal in normalised coordinates ~ the pixel normal (fx ~ fy; distortion is local).
      const Vector6d g = (c.n_px.transpose() * Jp * dP).transpose();
      H.noalias() += g * g.transpose() / (sigma_n * sigma_n);
      if (o.leave_one_out) H_segment.back().noalias() += g * g.transpose() / (sigma_n * sigma_n);
    }
  }
  // A required segment without support whose edge shows beside it, parallel within displaced_max_px: the events
  // of that edge are there, the pose puts it elsewhere. Its cells are moved across the segment in whole pixels
  // (from beyond the band and its side strips, so that the moved band does not count the segment's own pixels) and
  // judged as at the pose, with the same threshold and the same rule for the segment (min_segment_coverage of its
  // expected share, more than noise alone gives); moved cells near any projected model segment are not judged
  // (another segment of the model may run there).
  if (o.displaced_max_px > 0.0 && !unsupported.empty()) {
    const double near_px = o.band_px + o.side_gap_px + o.side_width_px;
    // Every projected piece of the model, short segments too (those with fewer than min_cells cells are not judged
    // but their edges are there all the same).
    VerifyOptions every = o;
    every.min_cells = 1;
    const std::vector<Cell> pieces = build_cells(img, camera, model, T, every, 0.0, nullptr, false, false);
    const std::vector<std::uint8_t> near_model = near_mask(pieces, near_px, camera.width, camera.height);
    const int first_offset = static_cast<int>(std::ceil(2.0 * near_px));
    const double f_px = 0.5 * (camera.fx + camera.fy);
    VerifyOptions plain = o;
    plain.displaced_max_px = 0.0;
    // Whether T moved so that its image shifts by `shift` px (a turn about the camera centre: du = f w_y,
    // dv = -f w_x near the axis) explains the window clearly better (compare_poses, the symmetric alternatives'
    // decision).
    const auto moved_explains_better = [&](const Eigen::Vector2d& shift) {
      const Eigen::Vector3d w(-shift.y() / f_px, shift.x() / f_px, 0.0);
      const Eigen::Quaterniond turn(Eigen::AngleAxisd(w.norm(), w.normalized()));
      const auto moved = [&](const camera::Pose& P) {
        camera::Pose out;
        out.q_cam_model = (turn * P.q_cam_model).normalized();
        out.t_cam_model_m = turn * P.t_cam_model_m;
        return out;
      };
      std::optional<MotionHint> moved_motion;
      if (motion)
        moved_motion = MotionHint{camera::StampedPose{motion->before.t_us, moved(motion->before.pose)}, motion->t_us};
      return compare_poses(events, camera, model, T, moved(T), plain, motion, moved_motion).log_ratio <=
             -symmetry_decision_log_ratio(o);
    };
    for (const Unsupported& u : unsupported) {
      // The segment's events fix only the image shift's component along its normal, so the moves tried per pixel
      // of offset are: straight across, and along each segment that fixes the pose (which that keeps on its
      // events) by as much as lands the empty segment on its edge (a board slid along its sides onto a decoy's
      // parallel edges); not along one nearly parallel to it (more than 2x the offset).
      Eigen::Vector2d n_mean = Eigen::Vector2d::Zero();
      for (std::size_t k = u.first; k < u.first + u.count; ++k) n_mean += cells[k].n_px;
      n_mean.normalize();
      struct Move {
        Eigen::Vector2d direction;
        double per_px;  // the offset across the segment per pixel moved along `direction`
      };
      std::vector<Move> moves{{n_mean, 1.0}};
      for (const Eigen::Vector2d& m : supported_normals) {
        const Eigen::Vector2d along(-m.y(), m.x());
        const double c = along.dot(n_mean);
        if (std::abs(c) >= 0.5) moves.push_back({along, c});
      }
      for (int d = first_offset; d <= static_cast<int>(o.displaced_max_px) && res.displaced_segment < 0; ++d) {
        for (const int sign : {1, -1}) {
          std::size_t judged = 0, shown = 0;
          for (std::size_t k = u.first; k < u.first + u.count; ++k) {
            const Cell& c = cells[k];
            const Eigen::Vector2d shift = static_cast<double>(sign * d) * c.n_px;
            const Eigen::Vector2d p = c.p_px + shift, q = c.q_px + shift, mid = 0.5 * (p + q);
            const int mx = static_cast<int>(std::lround(mid.x())), my = static_cast<int>(std::lround(mid.y()));
            if (mx < o.border_px || my < o.border_px || mx >= camera.width - o.border_px ||
                my >= camera.height - o.border_px ||
                near_model[static_cast<std::size_t>(my) * static_cast<std::size_t>(camera.width) +
                           static_cast<std::size_t>(mx)] != 0) {
              continue;
            }
            ++judged;
            if (cell_supported(img.cell(p, q, o, false), res.support_threshold, o)) ++shown;
          }
          if (judged < o.displaced_min_cells || 2 * judged < u.count) continue;
          const double n = static_cast<double>(judged);
          const double by_noise = n * o.false_alarm + 3.0 * std::sqrt(n * o.false_alarm * (1.0 - o.false_alarm));
          if (static_cast<double>(shown) < o.min_segment_coverage * u.expected_share * n ||
              !(static_cast<double>(shown) > by_noise)) {
            continue;
          }
          // The edge is there: is the pose moved so that it lands on it a better explanation of the window? (An
          // unrelated parallel edge — a monitor's border beside the board's outline — is not: moving the whole
          // model empties its other segments.)
          const double across = static_cast<double>(sign * d);
          std::vector<Eigen::Vector2d> tried;
          for (const Move& m : moves) {
            const Eigen::Vector2d shift = (across / m.per_px) * m.direction;
            if (std::any_of(tried.begin(), tried.end(),
                            [&](const Eigen::Vector2d& s2) { return (s2 - shift).norm() < 1.0; })) {
              continue;  // within a pixel of a move already tried
            }
            tried.push_back(shift);
            if (moved_explains_better(shift)) {
              res.displaced_segment = static_cast<int>(u.model_index);
              res.displaced_px = across;
              break;
            }
          }
          if (res.displaced_segment >= 0) break;
        }
      }
      if (res.displaced_segment >= 0) break;
    }
  }
  res.segments = std::move(segs);
  res.coverage =
      res.cells_required > 0 ? static_cast<double>(res.cells_supported) / static_cast<double>(res.cells_required) : 0.0;
  const double relative =
      res.cells_expected > 0.0 ? static_cast<double>(res.cells_supported) / res.cells_expected : 0.0;
  // Covariance of the pose from the supported cells (depth-scaled eigen-decomposition, as the tracker's).
  const detail::PoseSpread spread = detail::pose_spread(H, std::max(T.t_cam_model_m.norm(), 1e-3));
  res.rotation_std_deg = spread.rotation_deg;
  res.translation_std_m = spread.translation_m;
  // Redundancy (leave_one_out; H_segment is empty otherwise): the same without each supporting segment in turn (the
  // worst). An edge that carries a degree of freedom alone moves the pose by whatever bias it has (unmodelled
  // structure on it) without a residual to show it.
  for (const Matrix6d& H_k : H_segment) {
    const detail::PoseSpread without = detail::pose_spread(H - H_k, std::max(T.t_cam_model_m.norm(), 1e-3));
    res.rotation_std_without_deg = std::max(res.rotation_std_without_deg, without.rotation_deg);
    res.translation_std_without_m = std::max(res.translation_std_without_m, without.translation_m);
  }

  if (res.segments_judged == 0) {
    res.reason = "verification: no model segment in view";
  } else if (res.segments_required == 0) {
    res.reason = motion_scale > 0.0
                     ? "verification: no segment moves across itself enough to show support (nothing to verify)"
                     : "verification: no segment shows support above the noise (nothing to verify)";
  } else if (static_cast<double>(res.segments_supported) <
             o.min_segment_share * static_cast<double>(res.segments_required)) {
    res.reason = fmt::format("verification: {} of {} segments supported along their length (need {:.0f} %)",
                             res.segments_supported, res.segments_required, 100.0 * o.min_segment_share);
  } else if (res.displaced_segment >= 0) {
    res.reason = fmt::format(
        "verification: model segment {} shows no support where the pose puts it, but its edge {:+.0f} px beside it",
        res.displaced_segment, res.displaced_px);
  } else if (relative < o.min_coverage) {
    res.reason = fmt::format(
        "verification: {:.0f} % of the model's cells supported, {:.0f} % of what its edges should show (need {:.0f} "
        "%)",
        100.0 * res.coverage, 100.0 * relative, 100.0 * o.min_coverage);
  } else if (!(res.rotation_std_deg <= o.max_rotation_std_deg) || !(res.translation_std_m <= o.max_translation_std_m)) {
    res.reason = fmt::format(
        "verification: the supported edges do not fix the pose (1 sigma {:.2f} deg / {:.1f} mm; one direction of "
        "motion or too few edges)",
        res.rotation_std_deg, 1000.0 * res.translation_std_m);
  } else if (!(res.rotation_std_without_deg <= o.max_rotation_std_deg) ||
             !(res.translation_std_without_m <= o.max_translation_std_m)) {
    res.reason = fmt::format(
        "verification: one supported edge alone fixes part of the pose (without it 1 sigma {:.2f} deg / {:.1f} mm)",
        res.rotation_std_without_deg, 1000.0 * res.translation_std_without_m);
  } else {
    res.ok = true;
  }

  // The symmetric alternatives, on the cells where they differ from T (only for a pose verified otherwise, or
  // when asked): their cells and expected shares with the same noise threshold and event rate.
  if ((res.ok || compare_always) && !alternatives.empty()) {
    const double alpha = std::clamp(o.false_alarm, 1e-6, 0.5);
    const double near_px = o.band_px + o.side_gap_px + o.side_width_px;
    const std::vector<std::uint8_t> near_mine = near_mask(cells, near_px, camera.width, camera.height);
    for (std::size_t a = 0; a < alternatives.size(); ++a) {
      const Alternative& alt = alternatives[a];
      // The alternative's cells placed first; events are counted only on those where it differs from T. For a
      // symmetry S of the model, the segments S maps onto segments draw exactly T's cells of their images: only
      // the others are placed, and T's cells on those images are shared.
      std::vector<bool> mapped, image;
      if (alt.S) mapped_segments(model, *alt.S, mapped, image);
      std::vector<bool> unmapped(mapped.size());
      for (std::size_t i = 0; i < mapped.size(); ++i) unmapped[i] = !mapped[i];
      std::vector<Cell> other =
          build_cells(img, camera, model, alt.T, o, motion_scale, alt.before ? &*alt.before : nullptr, false, false,
                      alt.S ? &unmapped : nullptr);
      const std::vector<bool> other_only = only_in(other, near_mine, camera.width, camera.height);
      std::vector<bool> mine_only =
          only_in(cells, near_mask(other, near_px, camera.width, camera.height), camera.width, camera.height);
      if (alt.S) {
        for (std::size_t k = 0; k < cells.size(); ++k) mine_only[k] = mine_only[k] && !image[cells[k].segment];
      }
      // The alternative's own crossings: its placed cells and the cells it shares with T (the images).
      {
        std::vector<Cell> drawn = other;
        if (alt.S) {
          for (const Cell& c : cells) {
            if (image[c.segment]) drawn.push_back(c);
          }
        }
        img.set_owners(drawn, o.band_px);
      }
      const std::vector<int> other_bins = crossing_bins(img, other, o);
      std::vector<bool> other_supported(other.size(), false);
      std::vector<double> other_expected(other.size());
      for (std::size_t b = 0; b < other.size();) {
        std::size_t e = b;
        double motion_sum = 0.0;
        while (e < other.size() && other[e].segment == other[b].segment) motion_sum += other[e++].normal_motion_px;
        const double nm = motion_sum / static_cast<double>(e - b);
        const double share = chance_supported(motion_scale > 0.0 ? rate * o.cell_px * nm : rate);
        for (std::size_t k = b; k < e; ++k) {
          if (other_only[k]) {
            other[k].counts = img.cell(other[k].p_px, other[k].q_px, o, false, other_bins[k]);
            other_supported[k] = cell_supported(other[k].counts, res.support_threshold, o);
          }
          other_expected[k] = share;
        }
        b = e;
      }
      PoseComparison cmp;
      const double la = cells_log_ratio(mine_only, supported, expected, alpha, cmp.cells_a_only, cmp.supported_a_only);
      const double lb =
          cells_log_ratio(other_only, other_supported, other_expected, alpha, cmp.cells_b_only, cmp.supported_b_only);
      cmp.log_ratio = la - lb;
      if (comparisons) comparisons->push_back(cmp);
      if (cmp.log_ratio < res.symmetry_log_ratio) {
        res.symmetry_log_ratio = cmp.log_ratio;
        res.symmetry_index = a;
      }
    }
    if (res.ok && res.symmetry_log_ratio <= -symmetry_decision_log_ratio(o)) {
      res.ok = false;
      res.reason = fmt::format(
          "verification: the pose turned by the model's symmetry {} explains the events better (log-likelihood "
          "ratio {:.1f})",
          res.symmetry_index, res.symmetry_log_ratio);
    }
  }
  return res;
}

}  // namespace

double symmetry_decision_log_ratio(const VerifyOptions& options) {
  return std::log(1.0 / std::clamp(options.false_alarm, 1e-6, 0.5));
}

VerifyResult verify_pose(EventSpan events, const camera::CameraModel& camera, const camera::LineModel& model,
                         const camera::Pose& T, const VerifyOptions& o, const std::optional<MotionHint>& motion) {
  std::vector<Alternative> alternatives;
  for (const camera::Pose& S : o.symmetries) {
    alternatives.push_back({T * S, motion ? std::optional<camera::Pose>(motion->before.pose * S) : std::nullopt, S});
  }
  return verify_core(events, camera, model, T, o, motion, alternatives, nullptr, false);
}

PoseComparison compare_poses(EventSpan events, const camera::CameraModel& camera, const camera::LineModel& model,
                             const camera::Pose& A, const camera::Pose& B, const VerifyOptions& o,
                             const std::optional<MotionHint>& motion_a, const std::optional<MotionHint>& motion_b) {
  std::vector<PoseComparison> out;
  const std::vector<Alternative> alternatives{
      {B, motion_b ? std::optional<camera::Pose>(motion_b->before.pose) : std::nullopt, std::nullopt}};
  (void)verify_core(events, camera, model, A, o, motion_a, alternatives, &out, true);
  return out.empty() ? PoseComparison{} : out.front();
}

std::vector<camera::Pose> model_symmetries(const camera::LineModel& model, double min_share, std::size_t max_count) {
  using Eigen::Vector3d;
  const auto& segs = model.segments_m;
  if (segs.empty()) return {};
  Vector3d lo = Vector3d::Constant(1e300), hi = Vector3d::Constant(-1e300);
  double total = 0.0;
  for (const auto& s : segs) {
    lo = lo.cwiseMin(s.a_m).cwiseMin(s.b_m);
    hi = hi.cwiseMax(s.a_m).cwiseMax(s.b_m);
    total += (s.b_m - s.a_m).norm();
  }
  const double tol = 0.005 * (hi - lo).norm();
  if (!(total > 0.0) || !(tol > 0.0)) return {};
  // Corners: a point shared by two non-parallel segments, with the far ends of both.
  struct Corner {
    Vector3d o, a, b;
  };
  std::vector<Corner> corners;
  for (std::size_t i = 0; i < segs.size(); ++i) {
    for (std::size_t j = i + 1; j < segs.size(); ++j) {
      for (int ei = 0; ei < 2; ++ei) {
        for (int ej = 0; ej < 2; ++ej) {
          const Vector3d pi = ei ? segs[i].b_m : segs[i].a_m, qi = ei ? segs[i].a_m : segs[i].b_m;
          const Vector3d pj = ej ? segs[j].b_m : segs[j].a_m, qj = ej ? segs[j].a_m : segs[j].b_m;
          if ((pi - pj).norm() > tol) continue;
          const Vector3d u = (qi - pi).normalized(), v = (qj - pj).normalized();
          if (u.cross(v).norm() < 0.1) continue;
          corners.push_back({pi, qi, qj});
        }
      }
    }
  }
  // The rigid motion taking corner c onto corner d (same arm lengths and angle), from their orthonormal frames.
  const auto frame = [](const Corner& c) {
    Eigen::Matrix3d F;
    const Vector3d x = (c.a - c.o).normalized();
    const Vector3d z = x.cross(c.b - c.o).normalized();
    F.col(0) = x;
    F.col(1) = z.cross(x);
    F.col(2) = z;
    return F;
  };
  const auto coverage = [&](const camera::Pose& S) {
    double covered = 0.0;
    for (const auto& s : segs) {
      const Vector3d a = S.apply(s.a_m), b = S.apply(s.b_m);
      for (const auto& t : segs) {
        if (((a - t.a_m).norm() <= tol && (b - t.b_m).norm() <= tol) ||
            ((a - t.b_m).norm() <= tol && (b - t.a_m).norm() <= tol)) {
          covered += (s.b_m - s.a_m).norm();
          break;
        }
      }
    }
    return covered / total;
  };
  std::vector<std::pair<double, camera::Pose>> found;
  for (const Corner& c : corners) {
    const double la = (c.a - c.o).norm(), lb = (c.b - c.o).norm();
    const double ang = std::acos(std::clamp((c.a - c.o).normalized().dot((c.b - c.o).normalized()), -1.0, 1.0));
    const Eigen::Matrix3d Fc = frame(c);
    for (const Corner& d : corners) {
      if (std::abs((d.a - d.o).norm() - la) > tol || std::abs((d.b - d.o).norm() - lb) > tol) continue;
      const double angd = std::acos(std::clamp((d.a - d.o).normalized().dot((d.b - d.o).normalized()), -1.0, 1.0));
      if (std::abs(angd - ang) > 0.01) continue;
      camera::Pose S;
      const Eigen::Matrix3d R = frame(d) * Fc.transpose();
      S.q_cam_model = Eigen::Quaterniond(R).normalized();
      S.t_cam_model_m = d.o - S.q_cam_model * c.o;
      if (camera::rotation_angle_deg(S, camera::Pose{}) < 1.0 && S.t_cam_model_m.norm() < tol) continue;  // identity
      bool seen = false;
      for (const auto& [share, P] : found) {
        seen = seen || (camera::rotation_angle_deg(S, P) < 1.0 && camera::translation_distance_m(S, P) < tol);
      }
      if (seen) continue;
      const double share = coverage(S);
      if (share >= min_share) found.emplace_back(share, S);
    }
  }
  std::stable_sort(found.begin(), found.end(), [](const auto& l, const auto& r) { return l.first > r.first; });
  std::vector<camera::Pose> out;
  for (const auto& [share, S] : found) {
    if (out.size() >= max_count) break;
    out.push_back(S);
  }
  return out;
}

}  // namespace evpipe::pose
