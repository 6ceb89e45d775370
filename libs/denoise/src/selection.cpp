#include "evpipe/denoise/selection.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>

namespace evpipe::denoise {

double ConsistencyRegion::consistency(double c) const noexcept {
  if (!valid) return 0.0;
  const double dist = std::abs(c - centre);
  if (half_width <= 0.0) return dist == 0.0 ? 0.999 : 0.0;
  return 0.999 / (1.0 + dist / half_width);
}

std::size_t keep_count(std::size_t n, double keep_fraction) noexcept {
  if (n == 0) return 0;
  const double k = std::ceil(keep_fraction * static_cast<double>(n) - 1e-9);
  if (!(k >= 1.0)) return 1;
  return std::min(n, static_cast<std::size_t>(k));
}

namespace {

// Order-preserving integer image of a double (no NaN; −0 is folded into +0, which compares equal to it).
inline std::uint64_t order_key(double v) noexcept {
  const double w = v + 0.0;  // −0 + 0 = +0
  std::uint64_t b = 0;
  std::memcpy(&b, &w, sizeof b);
  const std::uint64_t flip = (std::uint64_t{0} - (b >> 63)) | (std::uint64_t{1} << 63);
  return b ^ flip;
}

// The value of rank k (0-based) of `v`, i.e. what nth_element would put at position k. Large populations
// are narrowed first by two 11-bit radix histograms of order_key (branch-free passes), so nth_element only
// runs on the few values that share rank k's 22 leading key bits; the value found is the same.
double kth_smallest(std::span<const double> v, std::size_t k, std::vector<double>& scratch) {
  constexpr std::size_t kRadixFrom = 4096;  // below this nth_element on a copy is as fast
  if (v.size() < kRadixFrom) {
    scratch.assign(v.begin(), v.end());
    std::nth_element(scratch.begin(), scratch.begin() + static_cast<std::ptrdiff_t>(k), scratch.end());
    return scratch[k];
  }
  constexpr int kBits = 11;
  constexpr std::size_t kBins = std::size_t{1} << kBits;
  std::array<std::uint32_t, kBins> hist{};
  const auto pick = [&](std::size_t& rank) {
    std::size_t b = 0;
    while (rank >= hist[b]) rank -= hist[b++];
    return static_cast<std::uint64_t>(b);
  };
  for (const double x : v) ++hist[order_key(x) >> (64 - kBits)];
  std::size_t rank = k;
  const std::uint64_t top = pick(rank);
  hist.fill(0);
  for (const double x : v) {
    const std::uint64_t key = order_key(x);
    hist[(key >> (64 - 2 * kBits)) & (kBins - 1)] += (key >> (64 - kBits)) == top ? 1U : 0U;
  }
  const std::uint64_t prefix = (top << kBits) | pick(rank);
  scratch.clear();
  for (const double x : v) {
    if ((order_key(x) >> (64 - 2 * kBits)) == prefix) scratch.push_back(x);
  }
  std::nth_element(scratch.begin(), scratch.begin() + static_cast<std::ptrdiff_t>(rank), scratch.end());
  return scratch[rank];
}

// Keeps the k smallest keys, ties at the cut by index; returns the largest kept key. Selection on a plain
// copy of the keys (nth_element), then one pass in index order, so ties go to the earlier index.
double keep_smallest(std::span<const double> key, std::size_t k, std::vector<std::uint8_t>& keep,
                     std::vector<double>& scratch) {
  const std::size_t n = key.size();
  const double cut = kth_smallest(key, k - 1, scratch);
  std::size_t below = 0;
  for (std::size_t i = 0; i < n; ++i) below += key[i] < cut ? 1 : 0;
  std::size_t ties = k - below;  // how many keys equal to `cut` are kept, first come first served
  for (std::size_t i = 0; i < n; ++i) {
    const bool tie = key[i] == cut && ties > 0;
    ties -= tie ? 1 : 0;
    keep[i] = (key[i] < cut || tie) ? 1 : 0;
  }
  return cut;
}

double median_of(std::span<const double> values, std::vector<double>& v) {
  const std::size_t n = values.size();
  const double upper = kth_smallest(values, n / 2, v);
  if (n % 2 == 1) return upper;
  // The value of rank n/2 − 1: `upper` again if enough values equal it, else the largest value below it.
  std::size_t below = 0;
  double lower = -std::numeric_limits<double>::infinity();
  for (const double x : values) {
    below += x < upper ? 1 : 0;
    lower = x < upper && x > lower ? x : lower;
  }
  if (below < n / 2) lower = upper;
  return lower + (upper - lower) / 2.0;  // no overflow for huge values of equal sign
}

}  // namespace

ConsistencyRegion select_consistent(std::span<const double> values, double keep_fraction, CurvatureRule rule,
                                    std::vector<std::uint8_t>& keep) {
  ConsistencyRegion region;
  const std::size_t n = values.size();
  keep.assign(n, 0);
  if (n == 0) return region;
  const std::size_t k = keep_count(n, keep_fraction);
  region.valid = true;
  if (rule == CurvatureRule::shortest) {
    std::vector<std::uint32_t> idx(n);
    std::iota(idx.begin(), idx.end(), 0U);
    std::sort(idx.begin(), idx.end(), [&](std::uint32_t a, std::uint32_t b) {
      return values[a] < values[b] || (values[a] == values[b] && a < b);
    });
    std::size_t best = 0;
    double best_width = values[idx[k - 1]] - values[idx[0]];
    for (std::size_t s = 1; s + k <= n; ++s) {
      const double w = values[idx[s + k - 1]] - values[idx[s]];
      if (w < best_width) {
        best_width = w;
        best = s;
      }
    }
    for (std::size_t j = best; j < best + k; ++j) keep[idx[j]] = 1;
    region.interval = true;
    region.lo = values[idx[best]];
    region.hi = values[idx[best + k - 1]];
    region.centre = region.lo + (region.hi - region.lo) / 2.0;
    region.half_width = (region.hi - region.lo) / 2.0;
    return region;
  }
  thread_local std::vector<double> scratch;
  thread_local std::vector<double> dist;
  const double centre = rule == CurvatureRule::median ? median_of(values, scratch) : 0.0;
  dist.resize(n);
  for (std::size_t i = 0; i < n; ++i) dist[i] = std::abs(values[i] - centre);
  const double half = keep_smallest(dist, k, keep, scratch);
  region.centre = centre;
  region.half_width = half;
  region.lo = centre - half;
  region.hi = centre + half;
  return region;
}

}  // namespace evpipe::denoise
