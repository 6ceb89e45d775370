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
#include <span>
#include <stdexcept>
#include <vector>

#include "evpipe/core/event.hpp"
#include "evpipe/denoise/sphere.hpp"

namespace evpipe::denoise {

/// Per-pixel state of one GridBlockIndex: begin, count, cursor (uint32 each), stamp and stamp count (find_ties).
inline constexpr std::size_t kGridBlockBytesPerPixel = 20;

class GridBlockIndex {
 public:
  GridBlockIndex(const Sphere& sphere, const SensorGeometry& geometry);

  /// Indexes `events` (time-ordered, spanning less than 2²⁹ µs); events outside the sensor are skipped.
  void build(EventSpan events);
  /// One row band of `events`: only the events of rows [query_y_lo, query_y_hi) will be queried, and only the
  /// events at the positions `subset` (increasing; it must hold every event of the rows the band's balls reach,
  /// [query_y_lo − extent, query_y_hi + extent), and may hold others) are looked at, by build() and query().
  /// Disjoint bands of one block can so be indexed and queried by separate instances at the same time, each
  /// seeing only its share. `subset` must stay valid until the next build().
  void build(EventSpan events, std::span<const std::uint32_t> subset, int query_y_lo, int query_y_hi);

  /// For each event events[i], i in [first, last), inside the sensor and the rows given to build(), calls
  /// sink(i, t_us, rho, mask, const std::int32_t* counts, const double* sums_dt) with the statistics of its
  /// ball among the indexed events whose time lies in [t_lo_us, t_hi_us] (rho = Σ counts, mask bit s =
  /// counts[s] > 0). Queries arrive pixel by pixel (raster order), in time order within a pixel.
  /// [first, last) must be all the events of `events` in a time interval.
  template <class Sink>
  void query(std::size_t first, std::size_t last, std::int64_t t_lo_us, std::int64_t t_hi_us, Sink&& sink) {
    constexpr std::int64_t kFar = std::int64_t{1} << 29;
    const auto lo = static_cast<std::int32_t>(std::clamp<std::int64_t>(t_lo_us - base_us_, -kFar, kFar));
    const auto hi = static_cast<std::int32_t>(std::clamp<std::int64_t>(t_hi_us - base_us_, -kFar, kFar));
    find_ties(first, last);
    // Specialised for the paper's ball (9 scanned sites) and for the stream mode's common case, where no
    // clamp can bind.
    const bool clamp = !(lo == -kFar && hi == kFar);
    if (window_sites_.size() == 9) {
      clamp ? query_impl<true, 9>(first, last, lo, hi, sink) : query_impl<false, 9>(first, last, lo, hi, sink);
    } else {
      clamp ? query_impl<true, 0>(first, last, lo, hi, sink) : query_impl<false, 0>(first, last, lo, hi, sink);
    }
  }

 private:
  [[nodiscard]] std::size_t pixel_of(const Event& e) const noexcept {
    return static_cast<std::size_t>((e.y + extent_) * stride_ + (e.x + extent_));
  }
  [[nodiscard]] bool indexed(const Event& e) const noexcept {
    return geometry_.contains(e.x, e.y) && e.y >= index_y_lo_ && e.y < index_y_hi_;
  }
  [[nodiscard]] bool queried(const Event& e) const noexcept { return e.y >= query_y_lo_ && e.y < query_y_hi_; }
  template <bool kClamp, int kWindows, class Sink>
  void query_impl(std::size_t first, std::size_t last, std::int32_t lo_clamp, std::int32_t hi_clamp, Sink& sink);
  /// Counts, for the queries in [first, last), the neighbours at the sites of half-width 0 (same µs only):
  /// those are found among runs of equal timestamps instead of by a window scan per query.
  void find_ties(std::size_t first, std::size_t last);
  template <class Pos>
  void find_ties_in(std::size_t count, Pos&& pos);
  void build_from(EventSpan events, int query_y_lo, int query_y_hi);
  /// Calls f(i) for every position of the events to index, in increasing order.
  template <class F>
  void for_each_position(F&& f) const {
    if (use_subset_) {
      for (const std::uint32_t i : subset_) f(static_cast<std::size_t>(i));
    } else {
      for (std::size_t i = 0; i < events_.size(); ++i) f(i);
    }
  }

  struct Tie {
    std::uint32_t index;  // query position in the span
    std::uint32_t site;
    std::int32_t count;
  };

  SensorGeometry geometry_;
  int extent_;
  int stride_;
  int sites_;
  int row_;                        // scratch row length: sites rounded up to 16 (zero padded)
  std::vector<int> window_sites_;  // sites with half-width > 0 (scanned)
  std::vector<int> tie_sites_;     // sites with half-width 0 (find_ties)
  std::int32_t hw32_[kMaxSphereSites] = {};
  std::ptrdiff_t offset_[kMaxSphereSites] = {};  // pixel-index offset of each site
  EventSpan events_;
  bool use_subset_ = false;
  std::span<const std::uint32_t> subset_;
  std::int64_t base_us_ = 0;
  int query_y_lo_ = 0, query_y_hi_ = 0;          // rows queried (clamped to the sensor)
  int index_y_lo_ = 0, index_y_hi_ = 0;          // rows indexed: the queried ones ± extent_
  std::size_t touched_lo_ = 0, touched_hi_ = 0;  // the queried rows' range of touched_
  // Sparse CSR over the pixels that hold events ("touched", in raster order): pixel p's list is
  // [begin_[p], begin_[p] + count_[p]) followed by a sentinel (INT32_MAX) that stops the 8-wide window
  // counts at the list's end; an untouched pixel points at the shared sentinel at entry 0. Work per block
  // is proportional to its events, not to the sensor.
  std::vector<std::uint32_t> begin_;
  std::vector<std::uint32_t> count_;
  std::vector<std::uint32_t> cursor_;
  std::vector<std::uint64_t> touched_bits_;
  std::vector<std::uint32_t> touched_;
  std::vector<std::int32_t> time_;      // t − base_us_, time-ordered within a pixel
  std::vector<std::uint32_t> index_;    // position in `events`
  std::vector<std::int64_t> prefix_;    // prefix_[k] = Σ time_[0..k) (sentinels cancel in differences)
  std::vector<std::int32_t> q_counts_;  // per-pixel query scratch, query-major rows of row_: counts, Δt sums
  std::vector<double> q_sums_;
  std::vector<std::int32_t> q_rho_;
  std::vector<std::uint64_t> q_mask_;
  std::uint32_t win_lo_[kMaxSphereSites] = {};
  std::uint32_t win_hi_[kMaxSphereSites] = {};
  std::vector<std::uint8_t> has_tie_;  // per query of [first, last)
  std::vector<Tie> ties_;              // sorted by index
  std::vector<std::uint32_t> stamp_;   // per pixel: run that last counted it (find_ties)
  std::vector<std::int32_t> stamp_count_;
  std::uint32_t run_id_ = 0;
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

/// ρ = Σ counts and the occupancy mask (bit s = counts[s] > 0).
inline void density_and_mask(const std::int32_t* counts, int sites, std::int32_t& rho, std::uint64_t& mask) noexcept {
  rho = 0;
  mask = 0;
  for (int s = 0; s < sites; ++s) {
    rho += counts[s];
    mask |= static_cast<std::uint64_t>(counts[s] > 0) << s;
  }
}

// ---------------------------------------------------------------------------------------------------------

namespace detail {

// Lists are time-sorted and end with a sentinel larger than any bound, so the entries below a bound form a
// prefix that stops at the list's end; its length is the number of trailing ones of the 8-entry compare
// mask. Eight entries per step without branches on the data (SSE2, which every x86-64 has, or AVX2 when the
// build targets it; plain C++ elsewhere); a window repeats a step only when all eight entries pass.
inline std::uint32_t below_count(const std::int32_t* x, std::int32_t a) noexcept {
#if defined(__AVX2__)
  const __m256i v = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(x));
  const auto m =
      static_cast<std::uint32_t>(_mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_set1_epi32(a), v))));
#elif defined(__SSE2__)
  const __m128i va = _mm_set1_epi32(a);
  const __m128i v0 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(x));
  const __m128i v1 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(x + 4));
  const auto m = static_cast<std::uint32_t>(_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(va, v0)))) |
                 (static_cast<std::uint32_t>(_mm_movemask_ps(_mm_castsi128_ps(_mm_cmpgt_epi32(va, v1)))) << 4);
#else
  std::uint32_t m = 0;
  for (std::uint32_t k = 0; k < 8; ++k) m |= static_cast<std::uint32_t>(x[k] < a) << k;
#endif
  return static_cast<std::uint32_t>(__builtin_ctz(~m));  // ≤ 8
}
inline std::uint32_t skip_below(const std::int32_t* time, std::uint32_t from, std::int32_t a) noexcept {
  while (true) {
    const std::uint32_t c = below_count(time + from, a);
    from += c;
    if (c < 8) return from;
  }
}

/// Σ of `n` (a multiple of 16, ≥ 16) counts and the mask of the non-zero ones.
inline void sum_and_mask(const std::int32_t* c, int n, std::int32_t& sum, std::uint64_t& mask) noexcept {
#if defined(__SSE2__)
  __m128i acc = _mm_setzero_si128();
  const __m128i zero = _mm_setzero_si128();
  std::uint64_t m = 0;
  for (int k = 0; k < n; k += 16) {
    const __m128i a = _mm_loadu_si128(reinterpret_cast<const __m128i*>(c + k));
    const __m128i b = _mm_loadu_si128(reinterpret_cast<const __m128i*>(c + k + 4));
    const __m128i d = _mm_loadu_si128(reinterpret_cast<const __m128i*>(c + k + 8));
    const __m128i e = _mm_loadu_si128(reinterpret_cast<const __m128i*>(c + k + 12));
    acc = _mm_add_epi32(_mm_add_epi32(acc, _mm_add_epi32(a, b)), _mm_add_epi32(d, e));
    const __m128i ab = _mm_packs_epi32(_mm_cmpgt_epi32(a, zero), _mm_cmpgt_epi32(b, zero));
    const __m128i de = _mm_packs_epi32(_mm_cmpgt_epi32(d, zero), _mm_cmpgt_epi32(e, zero));
    m |= static_cast<std::uint64_t>(static_cast<std::uint32_t>(_mm_movemask_epi8(_mm_packs_epi16(ab, de)))) << k;
  }
  acc = _mm_add_epi32(acc, _mm_shuffle_epi32(acc, 0x4E));
  acc = _mm_add_epi32(acc, _mm_shuffle_epi32(acc, 0xB1));
  sum = _mm_cvtsi128_si32(acc);
  mask = m;
#else
  sum = 0;
  mask = 0;
  for (int k = 0; k < n; ++k) {
    sum += c[k];
    mask |= static_cast<std::uint64_t>(c[k] > 0) << k;
  }
#endif
}

}  // namespace detail

template <bool kClamp, int kWindows, class Sink>
void GridBlockIndex::query_impl(std::size_t first, std::size_t last, std::int32_t lo_clamp, std::int32_t hi_clamp,
                                Sink& sink) {
  const std::int32_t* time = time_.data();
  const std::int64_t* prefix = prefix_.data();
  const auto row = static_cast<std::size_t>(row_);
  const std::size_t nw = kWindows > 0 ? static_cast<std::size_t>(kWindows) : window_sites_.size();
  const int* ws = window_sites_.data();
  const auto lo_index = static_cast<std::uint32_t>(first);
  const auto hi_index = static_cast<std::uint32_t>(last);
  const bool any_tie = !ties_.empty();
  // Raster order: the neighbour lists of consecutive pixels are neighbours in memory.
  for (std::size_t tp = touched_lo_; tp < touched_hi_; ++tp) {
    const std::uint32_t p = touched_[tp];
    // This pixel's queries: a contiguous run of its time-sorted list.
    std::uint32_t qa = begin_[p];
    const std::uint32_t pe = qa + count_[p];
    while (qa < pe && (index_[qa] < lo_index || index_[qa] >= hi_index)) ++qa;
    std::uint32_t qb = qa;
    while (qb < pe && index_[qb] < hi_index) ++qb;
    const std::size_t m = qb - qa;
    if (m == 0) continue;
    if (q_counts_.size() < m * row) {
      q_counts_.assign(m * row, 0);  // the padding stays zero
      q_sums_.assign(m * row, 0.0);
      q_rho_.resize(m);
      q_mask_.resize(m);
    }
    std::int32_t* qc = q_counts_.data();
    double* qs = q_sums_.data();
    // One monotone window per site sweeps the neighbour's list as this pixel's queries advance. Each end resumes
    // where it stopped (a window wider than the 8 entries one compare covers would otherwise rescan from its low
    // end: index alone ~5 % faster); the sites are independent, so their dependency chains overlap.
    for (std::size_t w = 0; w < nw; ++w) {
      win_lo_[w] = win_hi_[w] = begin_[static_cast<std::size_t>(static_cast<std::ptrdiff_t>(p) + offset_[ws[w]])];
    }
    for (std::size_t k = 0; k < m; ++k) {
      const std::int32_t t = time[qa + k];
      std::int32_t* c = qc + k * row;
      double* sm = qs + k * row;
      for (std::size_t w = 0; w < nw; ++w) {
        const int s = ws[w];
        std::int32_t a = t - hw32_[s];
        std::int32_t b = t + hw32_[s];
        if constexpr (kClamp) {
          a = std::max(a, lo_clamp);
          b = std::min(b, hi_clamp);
        }
        const std::uint32_t from_lo = win_lo_[w];
        const std::uint32_t from_hi = win_hi_[w];
        const std::uint32_t c_lo = detail::below_count(time + from_lo, a);
        const std::uint32_t c_hi = detail::below_count(time + from_hi, b + 1);  // |b| < 2²⁹: no overflow
        std::uint32_t lo = from_lo + c_lo;
        std::uint32_t hi = from_hi + c_hi;
        if (c_lo == 8) [[unlikely]]
          lo = detail::skip_below(time, lo, a);
        if (c_hi == 8) [[unlikely]]
          hi = detail::skip_below(time, hi, b + 1);
        win_hi_[w] = hi;
        win_lo_[w] = lo;
        const auto n = static_cast<std::int32_t>(hi - lo);
        c[s] = n;
        sm[s] = static_cast<double>(prefix[hi] - prefix[lo] - std::int64_t{n} * t);  // exact
      }
      for (const int s : tie_sites_) c[s] = 0;  // their Δt sums are 0 by definition
      if (any_tie && has_tie_[index_[qa + k] - lo_index] != 0) {
        const std::uint32_t i = index_[qa + k];
        auto it =
            std::lower_bound(ties_.begin(), ties_.end(), i, [](const Tie& x, std::uint32_t v) { return x.index < v; });
        for (; it != ties_.end() && it->index == i; ++it) c[it->site] = it->count;
      }
      detail::sum_and_mask(c, row_, q_rho_[k], q_mask_[k]);
    }
    for (std::size_t k = 0; k < m; ++k) {
      sink(static_cast<std::size_t>(index_[qa + k]), base_us_ + time[qa + k], q_rho_[k], q_mask_[k],
           static_cast<const std::int32_t*>(qc + k * row), static_cast<const double*>(qs + k * row));
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
