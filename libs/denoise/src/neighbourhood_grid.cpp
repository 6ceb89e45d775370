#include <algorithm>
#include <cstring>
#include <limits>

#include "evpipe/denoise/filter.hpp"
#include "evpipe/denoise/neighbourhood.hpp"

namespace evpipe::denoise {

GridBlockIndex::GridBlockIndex(const Sphere& sphere, const SensorGeometry& geometry)
    : geometry_(geometry),
      extent_(sphere.extent_px()),
      stride_(geometry.width + 2 * sphere.extent_px()),
      sites_(sphere.size()),
      row_((sphere.size() + 1 + 15) / 16 * 16) {  // at least one zero pad (QuadricBatch::set)
  for (int s = 0; s < sites_; ++s) {
    check_pixel_budget("curvature (grid index)", geometry, kGridBlockBytesPerPixel);
    const auto& site = sphere.sites()[static_cast<std::size_t>(s)];
    hw32_[s] = static_cast<std::int32_t>(site.half_width_us);
    offset_[s] = static_cast<std::ptrdiff_t>(site.dy) * stride_ + site.dx;
    (site.half_width_us > 0 ? window_sites_ : tie_sites_).push_back(s);
  }
  const auto pixels = static_cast<std::size_t>(stride_) * static_cast<std::size_t>(geometry.height + 2 * extent_);
  begin_.assign(pixels, 0);
  count_.assign(pixels, 0);
  cursor_.assign(pixels, 0);
  touched_bits_.assign((pixels + 63) / 64, 0);
}

void GridBlockIndex::build(EventSpan events) {
  use_subset_ = false;
  subset_ = {};
  build_from(events, 0, geometry_.height);
}

void GridBlockIndex::build(EventSpan events, std::span<const std::uint32_t> subset, int query_y_lo, int query_y_hi) {
  use_subset_ = true;
  subset_ = subset;
  build_from(events, query_y_lo, query_y_hi);
}

void GridBlockIndex::build_from(EventSpan events, int query_y_lo, int query_y_hi) {
  events_ = events;
  base_us_ = events.empty() ? 0 : events.front().t_us;
  query_y_lo_ = std::clamp(query_y_lo, 0, geometry_.height);
  query_y_hi_ = std::clamp(query_y_hi, query_y_lo_, geometry_.height);
  index_y_lo_ = query_y_lo_ - extent_;
  index_y_hi_ = query_y_hi_ + extent_;
  for (const std::uint32_t p : touched_) {
    begin_[p] = 0;
    count_[p] = 0;
  }
  touched_.clear();
  for_each_position([&](std::size_t i) {
    const Event& e = events[i];
    if (!indexed(e)) return;
    const std::size_t p = pixel_of(e);
    touched_bits_[p >> 6] |= std::uint64_t{1} << (p & 63);
    ++count_[p];
  });
  // Touched pixels in raster order, each list followed by its sentinel; entry 0 is the shared sentinel.
  std::uint32_t pos = 1;
  for (std::size_t w = 0; w < touched_bits_.size(); ++w) {
    std::uint64_t bits = touched_bits_[w];
    touched_bits_[w] = 0;
    while (bits != 0) {
      const auto p = static_cast<std::uint32_t>((w << 6) + static_cast<std::size_t>(__builtin_ctzll(bits)));
      bits &= bits - 1;
      touched_.push_back(p);
      begin_[p] = pos;
      cursor_[p] = pos;
      pos += count_[p] + 1;
    }
  }
  const std::size_t total = pos;
  time_.resize(total + 8);  // an 8-wide count may read up to 7 entries past the last sentinel
  index_.resize(total);
  prefix_.resize(total + 1);
  for_each_position([&](std::size_t i) {
    const Event& e = events[i];
    if (!indexed(e)) return;
    const std::uint32_t k = cursor_[pixel_of(e)]++;
    time_[k] = static_cast<std::int32_t>(e.t_us - base_us_);
    index_[k] = static_cast<std::uint32_t>(i);
  });
  constexpr std::int32_t kSentinel = std::numeric_limits<std::int32_t>::max();
  time_[0] = kSentinel;
  index_[0] = std::numeric_limits<std::uint32_t>::max();
  for (const std::uint32_t p : touched_) {
    time_[cursor_[p]] = kSentinel;  // cursor_ now points just past the list
    index_[cursor_[p]] = std::numeric_limits<std::uint32_t>::max();
  }
  std::fill(time_.begin() + static_cast<std::ptrdiff_t>(total), time_.end(), kSentinel);
  prefix_[0] = 0;
  for (std::size_t k = 0; k < total; ++k) prefix_[k + 1] = prefix_[k] + time_[k];
  const auto row_start = [&](int y) { return static_cast<std::uint32_t>((y + extent_) * stride_); };
  touched_lo_ = static_cast<std::size_t>(std::lower_bound(touched_.begin(), touched_.end(), row_start(query_y_lo_)) -
                                         touched_.begin());
  touched_hi_ = static_cast<std::size_t>(std::lower_bound(touched_.begin(), touched_.end(), row_start(query_y_hi_)) -
                                         touched_.begin());
}

void GridBlockIndex::find_ties(std::size_t first, std::size_t last) {
  ties_.clear();
  if (tie_sites_.empty()) return;
  has_tie_.assign(last - first, 0);
  if (stamp_.empty()) {
    stamp_.assign(begin_.size(), 0);
    stamp_count_.assign(begin_.size(), 0);
  }
  if (use_subset_) {
    const auto* lo = std::lower_bound(subset_.data(), subset_.data() + subset_.size(), first);
    const auto* hi = std::lower_bound(lo, subset_.data() + subset_.size(), last);
    find_ties_in(static_cast<std::size_t>(hi - lo), [lo](std::size_t k) { return static_cast<std::size_t>(lo[k]); });
  } else {
    find_ties_in(last - first, [first](std::size_t k) { return first + k; });
  }
  // ties_ is sorted by position (runs and their events come in increasing position): query() finds them there.
  for (const Tie& t : ties_) has_tie_[t.index - first] = 1;
}

template <class Pos>
void GridBlockIndex::find_ties_in(std::size_t count, Pos&& pos) {
  std::size_t r0 = 0;
  while (r0 < count) {
    const std::int64_t t = events_[pos(r0)].t_us;
    std::size_t r1 = r0 + 1;
    while (r1 < count && events_[pos(r1)].t_us == t) ++r1;
    if (r1 - r0 >= 2) {
      // A run of equal timestamps: count its events per pixel (stamped by run), then look up each event's
      // half-width-0 sites. Linear in the run's length.
      if (++run_id_ == 0) {  // wrapped: forget old stamps
        std::fill(stamp_.begin(), stamp_.end(), 0U);
        run_id_ = 1;
      }
      for (std::size_t r = r0; r < r1; ++r) {
        const Event& e = events_[pos(r)];
        if (!indexed(e)) continue;
        const std::size_t p = pixel_of(e);
        if (stamp_[p] != run_id_) {
          stamp_[p] = run_id_;
          stamp_count_[p] = 0;
        }
        ++stamp_count_[p];
      }
      for (std::size_t r = r0; r < r1; ++r) {
        const std::size_t i = pos(r);
        if (!indexed(events_[i]) || !queried(events_[i])) continue;
        const auto p = static_cast<std::ptrdiff_t>(pixel_of(events_[i]));
        for (const int s : tie_sites_) {
          const auto q = static_cast<std::size_t>(p + offset_[s]);
          if (stamp_[q] == run_id_) {
            ties_.push_back({static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(s), stamp_count_[q]});
          }
        }
      }
    }
    r0 = r1;
  }
}

GridRingIndex::GridRingIndex(const Sphere& sphere, const SensorGeometry& geometry)
    : geometry_(geometry),
      extent_(sphere.extent_px()),
      stride_(geometry.width + 2 * sphere.extent_px()),
      sites_(sphere.size()),
      reach_us_(sphere.reach_us()) {
  for (const auto& s : sphere.sites()) {
    half_width_.push_back(s.half_width_us);
    offset_.push_back(static_cast<std::ptrdiff_t>(s.dy) * stride_ + s.dx);
  }
  check_pixel_budget("curvature (causal index)", geometry, 41);  // 8 int32 slots + offset, log2, head
  reset();
}

void GridRingIndex::reset() {
  constexpr std::uint8_t kInitialLog2 = 3;  // 8 timestamps per pixel; busy pixels grow
  const auto pixels = static_cast<std::size_t>(stride_) * static_cast<std::size_t>(geometry_.height + 2 * extent_);
  pool_.assign(pixels << kInitialLog2, kNever);
  ring_offset_.resize(pixels);
  for (std::size_t p = 0; p < pixels; ++p) ring_offset_[p] = static_cast<std::uint32_t>(p << kInitialLog2);
  ring_log2_.assign(pixels, kInitialLog2);
  ring_head_.assign(pixels, 0);
  free_.assign(32, {});
  started_ = false;
  base_us_ = 0;
}

void GridRingIndex::rebase(std::int64_t t_us) {
  // Keep relative times in [0, 2³⁰]: shift the origin to just before the oldest time still needed.
  const std::int64_t new_base = t_us - reach_us_ - 1;
  const std::int64_t delta = new_base - base_us_;
  for (auto& v : pool_) {
    const std::int64_t shifted = static_cast<std::int64_t>(v) - delta;
    v = shifted < kNever ? kNever : static_cast<std::int32_t>(shifted);
  }
  base_us_ = new_base;
}

void GridRingIndex::grow(std::size_t pixel) {
  const std::uint8_t log2 = ring_log2_[pixel];
  const std::uint32_t cap = 1U << log2;
  const std::uint32_t new_cap = cap << 1;
  std::uint32_t off = 0;
  auto& fl = free_[static_cast<std::size_t>(log2) + 1];
  if (!fl.empty()) {
    off = fl.back();
    fl.pop_back();
  } else {
    off = static_cast<std::uint32_t>(pool_.size());
    pool_.resize(pool_.size() + new_cap);
  }
  // Oldest first, then "never" in the new slots, so that no stale timestamp is ever read.
  const std::uint32_t old_off = ring_offset_[pixel];
  const std::uint32_t head = ring_head_[pixel] & (cap - 1);
  for (std::uint32_t k = 0; k < cap; ++k) pool_[off + k] = pool_[old_off + ((head + k) & (cap - 1))];
  std::fill_n(pool_.begin() + off + cap, cap, kNever);
  free_[log2].push_back(old_off);
  ring_offset_[pixel] = off;
  ring_log2_[pixel] = static_cast<std::uint8_t>(log2 + 1);
  ring_head_[pixel] = cap;
}

void GridRingIndex::query_and_insert(const Event& e, std::int32_t* counts, std::int64_t* sums_dt) {
  if (!started_) {
    started_ = true;
    base_us_ = e.t_us - reach_us_ - 1;
  }
  if (e.t_us - base_us_ > (std::int64_t{1} << 30)) rebase(e.t_us);
  const auto t = static_cast<std::int32_t>(e.t_us - base_us_);
  const auto p = static_cast<std::size_t>((e.y + extent_) * stride_ + (e.x + extent_));
  const std::int32_t* pool = pool_.data();
  for (int s = 0; s < sites_; ++s) {
    const auto q = static_cast<std::size_t>(static_cast<std::ptrdiff_t>(p) + offset_[s]);
    const std::int32_t* ring = pool + ring_offset_[q];
    const std::uint32_t cap = 1U << ring_log2_[q];
    const auto lo = static_cast<std::int32_t>(t - half_width_[s]);
    std::int32_t n = 0;
    std::int64_t sum = 0;
    for (std::uint32_t k = 0; k < cap; ++k) {
      const std::int32_t v = ring[k];
      const bool in = v >= lo;  // every stored time is ≤ t (time order)
      n += in ? 1 : 0;
      sum += in ? static_cast<std::int64_t>(v - t) : 0;
    }
    counts[s] = n;
    sums_dt[s] = sum;
  }
  counts[0] += 1;  // the event itself, at the centre with Δt = 0
  // Insert: the slot to overwrite holds the oldest time; if a later event could still need it, grow.
  std::uint32_t cap = 1U << ring_log2_[p];
  const std::int32_t oldest = pool_[ring_offset_[p] + (ring_head_[p] & (cap - 1))];
  if (static_cast<std::int64_t>(oldest) >= static_cast<std::int64_t>(t) - reach_us_) {
    grow(p);
    cap <<= 1;
  }
  pool_[ring_offset_[p] + (ring_head_[p] & (cap - 1))] = t;
  ++ring_head_[p];
}

}  // namespace evpipe::denoise
