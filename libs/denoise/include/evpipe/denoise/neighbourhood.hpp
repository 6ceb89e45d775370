#pragma once
// The two neighbourhood indexes of the curvature filter. Both return, per queried event, the statistics of
// its ball per sphere site s: n_s (number of events, the event itself included at the centre) and S_s (sum
// of Δt in µs). These integers are all the fit needs (quadric.hpp), so equal statistics give equal
// decisions.
//
// * GridBlockIndex: per processing block, the events sorted by pixel (counting sort, CSR) with per-pixel
//   time lists and prefix sums of time; queries walk each pixel's events in time order with one monotone
//   [lo, hi) window per site. Exact and O(sites) amortised per event.
// * GridRingIndex: causal (past-only) queries on arrival, with per-pixel rings of recent timestamps.
// * FlannBallIndex: FLANN's exact single KD-tree over (Lt·x, Lt·y, t − t0) in double — squared distances
//   are exact integers there — with a radius search of limit + 0.5 (FLANN accepts dist < radius), i.e.
//   exactly the inclusive-or-strict integer test of Sphere.

#include <algorithm>
#include <cstdint>
#include <limits>
#include <memory>
#include <stdexcept>
#include <vector>

#include "evpipe/core/event.hpp"
#include "evpipe/denoise/sphere.hpp"

namespace evpipe::denoise {

class GridBlockIndex {
 public:
  GridBlockIndex(const Sphere& sphere, const SensorGeometry& geometry);

  /// Indexes `events` (time-ordered, spanning less than 2³¹ µs); events outside the sensor are skipped.
  void build(EventSpan events);

  /// For each event events[i], i in [first, last), inside the sensor, calls
  /// sink(i, const std::int32_t* counts, const std::int64_t* sums_dt) with its ball among the indexed events
  /// whose time lies in [t_lo_us, t_hi_us]. Queries arrive grouped by pixel, in time order within a pixel.
  template <class Sink>
  void query(std::size_t first, std::size_t last, std::int64_t t_lo_us, std::int64_t t_hi_us, Sink&& sink);

 private:
  [[nodiscard]] std::size_t pixel_of(const Event& e) const noexcept {
    return static_cast<std::size_t>((e.y + extent_) * stride_ + (e.x + extent_));
  }

  SensorGeometry geometry_;
  int extent_;
  int stride_;
  int sites_;
  std::vector<std::int64_t> half_width_;
  std::vector<std::ptrdiff_t> offset_;  // pixel-index offset of each site
  EventSpan events_;
  std::int64_t base_us_ = 0;
  std::vector<std::uint32_t> start_;  // CSR: pixel p holds entries [start_[p], start_[p+1])
  std::vector<std::uint32_t> cursor_;
  std::vector<std::int32_t> time_;    // t − base_us_, time-ordered within a pixel
  std::vector<std::uint32_t> index_;  // position in `events`
  std::vector<std::int64_t> prefix_;  // prefix_[k] = Σ time_[0..k)
  std::vector<std::uint32_t> mark_;   // per pixel: last query epoch that listed it
  std::uint32_t epoch_ = 0;
  std::vector<std::uint32_t> active_;
};

class GridRingIndex {
 public:
  GridRingIndex(const Sphere& sphere, const SensorGeometry& geometry);
  void reset();
  /// Ball of `e` among the events inserted before it (Δt ≤ 0, input order), itself counted at the centre;
  /// then inserts e. Events must come in time order and inside the sensor.
  void query_and_insert(const Event& e, std::int32_t* counts, std::int64_t* sums_dt);

 private:
  void rebase(std::int64_t t_us);
  void grow(std::size_t pixel);

  static constexpr std::int32_t kNever = -(1 << 30);  // older than any ball once times are rebased
  SensorGeometry geometry_;
  int extent_;
  int stride_;
  int sites_;
  std::int64_t reach_us_;
  std::vector<std::int64_t> half_width_;
  std::vector<std::ptrdiff_t> offset_;
  std::int64_t base_us_ = 0;
  bool started_ = false;
  std::vector<std::int32_t> pool_;
  std::vector<std::uint32_t> ring_offset_;
  std::vector<std::uint8_t> ring_log2_;
  std::vector<std::uint32_t> ring_head_;          // number of insertions; head & (cap − 1) is the oldest slot
  std::vector<std::vector<std::uint32_t>> free_;  // free ring slots by log2 capacity
};

/// FLANN KD-tree radius search (the reference backend).
class FlannBallIndex {
 public:
  explicit FlannBallIndex(const Sphere& sphere);
  ~FlannBallIndex();
  FlannBallIndex(const FlannBallIndex&) = delete;
  FlannBallIndex& operator=(const FlannBallIndex&) = delete;

  /// Indexes the events of `events` inside the sensor.
  void build(EventSpan events, const SensorGeometry& geometry);
  /// Positions in the built span of the events in the ball of `centre` (itself included if indexed),
  /// unsorted.
  void ball(const Event& centre, std::vector<std::uint32_t>& out) const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Adds the ball members `members` (positions in `events`) of events[i] to per-site statistics, skipping
/// members for which skip(j) is true. Throws std::logic_error if a member is not in the sphere (a backend
/// bug).
template <class Skip>
void accumulate_ball(const Sphere& sphere, EventSpan events, std::size_t i, const std::vector<std::uint32_t>& members,
                     Skip&& skip, std::int32_t* counts, std::int64_t* sums_dt);

// ---------------------------------------------------------------------------------------------------------

template <class Sink>
void GridBlockIndex::query(std::size_t first, std::size_t last, std::int64_t t_lo_us, std::int64_t t_hi_us,
                           Sink&& sink) {
  ++epoch_;
  active_.clear();
  for (std::size_t i = first; i < last; ++i) {
    const Event& e = events_[i];
    if (!geometry_.contains(e.x, e.y)) continue;
    const std::size_t p = pixel_of(e);
    if (mark_[p] != epoch_) {
      mark_[p] = epoch_;
      active_.push_back(static_cast<std::uint32_t>(p));
    }
  }
  const std::int64_t lo_clamp = std::max<std::int64_t>(t_lo_us - base_us_, std::numeric_limits<std::int32_t>::min());
  const std::int64_t hi_clamp = std::min<std::int64_t>(t_hi_us - base_us_, std::numeric_limits<std::int32_t>::max());
  std::int32_t counts[kMaxSphereSites];
  std::int64_t sums[kMaxSphereSites];
  std::uint32_t lo[kMaxSphereSites];
  std::uint32_t hi[kMaxSphereSites];
  std::uint32_t end[kMaxSphereSites];
  const std::int32_t* time = time_.data();
  const std::int64_t* prefix = prefix_.data();
  for (const std::uint32_t p : active_) {
    for (int s = 0; s < sites_; ++s) {
      const auto q = static_cast<std::size_t>(static_cast<std::ptrdiff_t>(p) + offset_[s]);
      lo[s] = hi[s] = start_[q];
      end[s] = start_[q + 1];
    }
    for (std::uint32_t k = start_[p]; k < start_[p + 1]; ++k) {
      const std::uint32_t i = index_[k];
      if (i < first || i >= last) continue;
      const std::int64_t t = time[k];
      for (int s = 0; s < sites_; ++s) {
        const std::int64_t a = std::max(t - half_width_[s], lo_clamp);
        const std::int64_t b = std::min(t + half_width_[s], hi_clamp);
        std::uint32_t l = lo[s];
        while (l < end[s] && time[l] < a) ++l;
        std::uint32_t h = std::max(hi[s], l);
        while (h < end[s] && time[h] <= b) ++h;
        lo[s] = l;
        hi[s] = h;
        const auto n = static_cast<std::int32_t>(h - l);
        counts[s] = n;
        sums[s] = prefix[h] - prefix[l] - static_cast<std::int64_t>(n) * t;
      }
      sink(static_cast<std::size_t>(i), static_cast<const std::int32_t*>(counts),
           static_cast<const std::int64_t*>(sums));
    }
  }
}

template <class Skip>
void accumulate_ball(const Sphere& sphere, EventSpan events, std::size_t i, const std::vector<std::uint32_t>& members,
                     Skip&& skip, std::int32_t* counts, std::int64_t* sums_dt) {
  std::fill_n(counts, sphere.size(), 0);
  std::fill_n(sums_dt, sphere.size(), std::int64_t{0});
  const Event& c = events[i];
  for (const std::uint32_t j : members) {
    if (skip(static_cast<std::size_t>(j))) continue;
    const Event& e = events[j];
    const int s = sphere.site_index(static_cast<int>(e.x) - c.x, static_cast<int>(e.y) - c.y);
    const std::int64_t dt = e.t_us - c.t_us;
    if (s < 0 || dt > sphere.sites()[static_cast<std::size_t>(s)].half_width_us ||
        dt < -sphere.sites()[static_cast<std::size_t>(s)].half_width_us) {
      throw std::logic_error("curvature: radius search returned a point outside the sphere");
    }
    ++counts[s];
    sums_dt[s] += dt;
  }
}

}  // namespace evpipe::denoise
