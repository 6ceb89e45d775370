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
#if defined(__SSE2__)
#include <immintrin.h>
#endif
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
  /// sink(i, t_us, const std::int32_t* counts, const double* sums_dt) with its ball among the indexed events
  /// whose time lies in [t_lo_us, t_hi_us]. Queries arrive pixel by pixel (raster order), in time order
  /// within a pixel. [first, last) must be all the events of `events` in a time interval.
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
  std::vector<std::int32_t> time_;      // t − base_us_, time-ordered within a pixel
  std::vector<std::uint32_t> index_;    // position in `events`
  std::vector<std::int64_t> prefix_;    // prefix_[k] = Σ time_[0..k)
  std::vector<std::int32_t> q_counts_;  // per-pixel query scratch, query-major: counts and Δt sums
  std::vector<double> q_sums_;
  std::int32_t hw32_[kMaxSphereSites] = {};
  std::uint32_t win_lo_[kMaxSphereSites] = {};
  std::uint32_t win_end_[kMaxSphereSites] = {};
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

namespace detail {

// Index of the first entry of [from, end) that is not < a (skip_below) or not ≤ b (skip_not_above), given
// that every entry before `from` is: lists are time-sorted, so the entries that pass form a prefix and the
// answer is `from` plus its length. Eight entries per step, without branches on the data (SSE2, which every
// x86-64 has, or AVX2 when the build targets it; plain C++ elsewhere); the loop repeats only when all eight
// pass, which is rare. Reads up to 7 entries past `end` (the arrays are padded).
inline std::uint32_t prefix_length(std::uint32_t mask, std::uint32_t valid) noexcept {
  mask &= (1U << valid) - 1U;
  return static_cast<std::uint32_t>(__builtin_ctz(~mask));  // mask is a prefix of ones (≤ 8 bits)
}
inline std::uint32_t below_mask(const std::int32_t* x, std::int32_t a) noexcept {
#if defined(__AVX2__)
  const __m256i v = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(x));
  return static_cast<std::uint32_t>(
      _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(a), v))));
#elif defined(__SSE2__)
  const __m128i va = _mm_set1_epi32(a);
  const __m128i v0 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(x));
  const __m128i v1 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(x + 4));
  return static_cast<std::uint32_t>(_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(va, v0)))) |
         (static_cast<std::uint32_t>(_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(va, v1)))) << 4);
#else
  std::uint32_t m = 0;
  for (std::uint32_t k = 0; k < 8; ++k) m |= static_cast<std::uint32_t>(x[k] < a) << k;
  return m;
#endif
}
inline std::uint32_t skip_below(const std::int32_t* time, std::uint32_t from, std::uint32_t end,
                                std::int32_t a) noexcept {
  while (true) {
    const std::uint32_t valid = std::min<std::uint32_t>(8, end - from);
    const std::uint32_t c = prefix_length(below_mask(time + from, a), valid);
    from += c;
    if (c < 8) return from;
  }
}
/// The window [lo, hi) of entries in [a, b1) (b1 = b + 1) of the sorted list [from, end), given that every
/// entry before `from` is < a. Usually one 8-entry load decides both ends.
inline void window(const std::int32_t* time, std::uint32_t from, std::uint32_t end, std::int32_t a, std::int32_t b1,
                   std::uint32_t& lo, std::uint32_t& hi) noexcept {
  const std::uint32_t valid = std::min<std::uint32_t>(8, end - from);
  const std::uint32_t c_lo = prefix_length(below_mask(time + from, a), valid);
  const std::uint32_t c_hi = prefix_length(below_mask(time + from, b1), valid);
  if (c_hi < 8) {  // then c_lo ≤ c_hi < 8 too
    lo = from + c_lo;
    hi = from + c_hi;
    return;
  }
  lo = c_lo < 8 ? from + c_lo : skip_below(time, from + 8, end, a);
  hi = skip_below(time, from + 8, end, b1);
}

}  // namespace detail

template <class Sink>
void GridBlockIndex::query(std::size_t first, std::size_t last, std::int64_t t_lo_us, std::int64_t t_hi_us,
                           Sink&& sink) {
  // Clamps in relative time, kept inside int32 with room for ± a half-width.
  constexpr std::int64_t kFar = std::int64_t{1} << 30;
  const auto lo_clamp = static_cast<std::int32_t>(std::clamp<std::int64_t>(t_lo_us - base_us_, -kFar, kFar));
  const auto hi_clamp = static_cast<std::int32_t>(std::clamp<std::int64_t>(t_hi_us - base_us_, -kFar, kFar));
  const std::int32_t* time = time_.data();
  const std::int64_t* prefix = prefix_.data();
  const auto ns = static_cast<std::size_t>(sites_);
  const auto lo_index = static_cast<std::uint32_t>(first);
  const auto hi_index = static_cast<std::uint32_t>(last);
  // Raster order: the neighbour lists of consecutive pixels are neighbours in memory.
  const std::size_t pixels = start_.size() - 1;
  for (std::size_t p = 0; p < pixels; ++p) {
    // This pixel's queries: a contiguous run of its time-sorted list.
    std::uint32_t qa = start_[p];
    const std::uint32_t pe = start_[p + 1];
    while (qa < pe && (index_[qa] < lo_index || index_[qa] >= hi_index)) ++qa;
    std::uint32_t qb = qa;
    while (qb < pe && index_[qb] < hi_index) ++qb;
    const std::size_t m = qb - qa;
    if (m == 0) continue;
    if (q_counts_.size() < m * ns) {
      q_counts_.resize(m * ns);
      q_sums_.resize(m * ns);
    }
    std::int32_t* qc = q_counts_.data();
    double* qs = q_sums_.data();
    // One monotone window per site sweeps the neighbour's list as this pixel's queries advance; the sites
    // are independent, so their dependency chains overlap.
    for (std::size_t s = 0; s < ns; ++s) {
      const auto q = static_cast<std::size_t>(static_cast<std::ptrdiff_t>(p) + offset_[s]);
      win_lo_[s] = start_[q];
      win_end_[s] = start_[q + 1];
    }
    for (std::size_t k = 0; k < m; ++k) {
      const std::int32_t t = time[qa + k];
      std::int32_t* c = qc + k * ns;
      double* sm = qs + k * ns;
      for (std::size_t s = 0; s < ns; ++s) {
        std::uint32_t lo = 0;
        std::uint32_t hi = 0;
        // b + 1 ≤ 2³⁰ + 1: no overflow.
        detail::window(time, win_lo_[s], win_end_[s], std::max(t - hw32_[s], lo_clamp),
                       std::min(t + hw32_[s], hi_clamp) + 1, lo, hi);
        win_lo_[s] = lo;
        const auto n = static_cast<std::int32_t>(hi - lo);
        c[s] = n;
        sm[s] = static_cast<double>(prefix[hi] - prefix[lo] - std::int64_t{n} * t);  // exact
      }
    }
    for (std::size_t k = 0; k < m; ++k) {
      sink(static_cast<std::size_t>(index_[qa + k]), base_us_ + time[qa + k],
           static_cast<const std::int32_t*>(qc + k * ns), static_cast<const double*>(qs + k * ns));
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
