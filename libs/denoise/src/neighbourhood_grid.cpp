#include <cstring>
#include <limits>

#include "evpipe/denoise/neighbourhood.hpp"

namespace evpipe::denoise {

GridBlockIndex::GridBlockIndex(const Sphere& sphere, const SensorGeometry& geometry)
    : geometry_(geometry),
      extent_(sphere.extent_px()),
      stride_(geometry.width + 2 * sphere.extent_px()),
      sites_(sphere.size()) {
  for (const auto& s : sphere.sites()) {
    hw32_[half_width_.size()] = static_cast<std::int32_t>(s.half_width_us);
    half_width_.push_back(s.half_width_us);
    offset_.push_back(static_cast<std::ptrdiff_t>(s.dy) * stride_ + s.dx);
  }
  const auto pixels = static_cast<std::size_t>(stride_) * static_cast<std::size_t>(geometry.height + 2 * extent_);
  start_.assign(pixels + 1, 0);
  cursor_.assign(pixels, 0);
}

void GridBlockIndex::build(EventSpan events) {
  events_ = events;
  base_us_ = events.empty() ? 0 : events.front().t_us;
  std::fill(start_.begin(), start_.end(), 0U);
  std::size_t n = 0;
  for (const Event& e : events) {
    if (!geometry_.contains(e.x, e.y)) continue;
    ++start_[pixel_of(e) + 1];
    ++n;
  }
  for (std::size_t p = 1; p < start_.size(); ++p) start_[p] += start_[p - 1];
  std::memcpy(cursor_.data(), start_.data(), cursor_.size() * sizeof(std::uint32_t));
  // Padding: the 8-wide window counts read up to 7 entries past a list's end.
  time_.resize(n + 8);
  std::fill(time_.begin() + static_cast<std::ptrdiff_t>(n), time_.end(), std::numeric_limits<std::int32_t>::max());
  index_.resize(n);
  prefix_.resize(n + 1);
  for (std::size_t i = 0; i < events.size(); ++i) {
    const Event& e = events[i];
    if (!geometry_.contains(e.x, e.y)) continue;
    const std::uint32_t k = cursor_[pixel_of(e)]++;
    time_[k] = static_cast<std::int32_t>(e.t_us - base_us_);
    index_[k] = static_cast<std::uint32_t>(i);
  }
  prefix_[0] = 0;
  for (std::size_t k = 0; k < n; ++k) prefix_[k + 1] = prefix_[k] + time_[k];
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
