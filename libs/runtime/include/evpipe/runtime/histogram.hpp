#pragma once
// A latency / timing histogram with log-spaced buckets: lock-free record() from one thread, snapshot() with
// percentiles from any other thread.
//
// Buckets (values are unsigned integers, evpipe records nanoseconds): values below 2 * kSubBuckets (64) get one
// bucket each (exact); above, every octave [2^e, 2^(e+1)) is split into kSubBuckets equal buckets, so a bucket
// spans at most 1/32 of its values (relative resolution 3.1 %). Values of 2^47 ns (39 h) and more share the
// last bucket. A percentile is reported as the largest value of its bucket (an upper bound, which is what a
// latency goal needs), clamped to the exact recorded maximum and minimum: data that fits the exact buckets or
// is a single value reads back exactly.

#include <array>
#include <atomic>
#include <cstdint>
#include <vector>

namespace evpipe::runtime {

/// Percentiles of a histogram (same unit as the recorded values; 0 when count is 0).
struct HistogramSummary {
  std::uint64_t count = 0;
  double mean = 0.0;
  std::uint64_t min = 0;
  std::uint64_t p50 = 0;
  std::uint64_t p90 = 0;
  std::uint64_t p99 = 0;
  std::uint64_t max = 0;
};

/// Bucket counts copied out of a Histogram.
class HistogramSnapshot {
 public:
  /// Nearest-rank percentile, q in [0, 1]: the upper bound of the bucket holding the ceil(q * count)-th smallest
  /// value, clamped to [min, max]. 0 when empty.
  [[nodiscard]] std::uint64_t percentile(double q) const noexcept;
  [[nodiscard]] HistogramSummary summary() const noexcept;
  [[nodiscard]] std::uint64_t count() const noexcept { return count_; }
  [[nodiscard]] std::uint64_t max() const noexcept { return max_; }
  [[nodiscard]] std::uint64_t min() const noexcept { return min_; }

 private:
  friend class Histogram;
  std::vector<std::uint64_t> buckets_;
  std::uint64_t count_ = 0;
  std::uint64_t sum_ = 0;
  std::uint64_t min_ = 0;
  std::uint64_t max_ = 0;
};

class Histogram {
 public:
  static constexpr unsigned kSubBucketBits = 5;
  static constexpr std::uint64_t kSubBuckets = std::uint64_t{1} << kSubBucketBits;  // 32 per octave
  static constexpr unsigned kMaxExponent = 47;                                      // last octave [2^47, 2^48)
  static constexpr std::size_t kBuckets = 2 * kSubBuckets + (kMaxExponent - kSubBucketBits) * kSubBuckets;

  /// Bucket index of a value.
  [[nodiscard]] static std::size_t bucket_of(std::uint64_t value) noexcept;
  /// Largest value mapped to a bucket (the value percentiles report).
  [[nodiscard]] static std::uint64_t bucket_upper(std::size_t bucket) noexcept;
  /// Largest value of the bucket `value` falls in: what percentile() reports for it before clamping.
  [[nodiscard]] static std::uint64_t reported(std::uint64_t value) noexcept { return bucket_upper(bucket_of(value)); }

  /// One writer thread only (single-writer counters: a relaxed load + store, no locked instruction).
  void record(std::uint64_t value) noexcept;
  /// Any thread. Buckets are read one by one while the writer may go on, so the copy is not one instant, but each
  /// bucket count is exact and the count/percentiles are computed from the copied buckets only.
  [[nodiscard]] HistogramSnapshot snapshot() const;
  [[nodiscard]] HistogramSummary summary() const { return snapshot().summary(); }

 private:
  std::array<std::atomic<std::uint64_t>, kBuckets> buckets_{};
  std::atomic<std::uint64_t> sum_{0};
  std::atomic<std::uint64_t> min_{UINT64_MAX};
  std::atomic<std::uint64_t> max_{0};
};

}  // namespace evpipe::runtime
