#include "evpipe/runtime/histogram.hpp"

#include <algorithm>
#include <bit>
#include <cmath>

namespace evpipe::runtime {

std::size_t Histogram::bucket_of(std::uint64_t value) noexcept {
  if (value < 2 * kSubBuckets) return static_cast<std::size_t>(value);
  const unsigned e = static_cast<unsigned>(std::bit_width(value)) - 1;  // value in [2^e, 2^(e+1)), e >= 6
  if (e > kMaxExponent) return kBuckets - 1;
  const unsigned shift = e - kSubBucketBits;                 // bucket width 2^shift
  const std::uint64_t sub = (value >> shift) - kSubBuckets;  // in [0, kSubBuckets)
  return static_cast<std::size_t>(2 * kSubBuckets + (e - kSubBucketBits - 1) * kSubBuckets + sub);
}

std::uint64_t Histogram::bucket_upper(std::size_t bucket) noexcept {
  if (bucket < 2 * kSubBuckets) return bucket;
  if (bucket >= kBuckets - 1) return UINT64_MAX;
  const std::size_t k = bucket - 2 * kSubBuckets;
  const unsigned e = static_cast<unsigned>(k / kSubBuckets) + kSubBucketBits + 1;
  const std::uint64_t sub = k % kSubBuckets;
  const unsigned shift = e - kSubBucketBits;
  return ((kSubBuckets + sub + 1) << shift) - 1;
}

void Histogram::record(std::uint64_t value) noexcept {
  auto& b = buckets_[bucket_of(value)];
  b.store(b.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
  sum_.store(sum_.load(std::memory_order_relaxed) + value, std::memory_order_relaxed);
  if (value < min_.load(std::memory_order_relaxed)) min_.store(value, std::memory_order_relaxed);
  if (value > max_.load(std::memory_order_relaxed)) max_.store(value, std::memory_order_relaxed);
}

HistogramSnapshot Histogram::snapshot() const {
  HistogramSnapshot s;
  s.buckets_.resize(kBuckets);
  for (std::size_t i = 0; i < kBuckets; ++i) {
    s.buckets_[i] = buckets_[i].load(std::memory_order_relaxed);
    s.count_ += s.buckets_[i];
  }
  s.sum_ = sum_.load(std::memory_order_relaxed);
  s.max_ = max_.load(std::memory_order_relaxed);
  const std::uint64_t mn = min_.load(std::memory_order_relaxed);
  s.min_ = s.count_ == 0 || mn == UINT64_MAX ? 0 : mn;
  return s;
}

std::uint64_t HistogramSnapshot::percentile(double q) const noexcept {
  if (count_ == 0) return 0;
  q = std::clamp(q, 0.0, 1.0);
  const auto rank = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::ceil(q * static_cast<double>(count_))));
  std::uint64_t seen = 0;
  for (std::size_t i = 0; i < buckets_.size(); ++i) {
    seen += buckets_[i];
    if (seen >= rank) return std::clamp(Histogram::bucket_upper(i), min_, std::max(min_, max_));
  }
  return max_;
}

HistogramSummary HistogramSnapshot::summary() const noexcept {
  HistogramSummary r;
  r.count = count_;
  if (count_ == 0) return r;
  r.mean = static_cast<double>(sum_) / static_cast<double>(count_);
  r.min = min_;
  r.p50 = percentile(0.50);
  r.p90 = percentile(0.90);
  r.p99 = percentile(0.99);
  r.max = max_;
  return r;
}

}  // namespace evpipe::runtime
