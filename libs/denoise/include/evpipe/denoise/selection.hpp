#pragma once
// "Keep the share of events with consistent curvature" (paper section 3.2): which ⌈f·n⌉ of a population's
// curvature values are kept, by rule (median / shortest / flattest, see curvature_options.hpp).
// Ties at the cut go to the earlier value (lower index), so the result is deterministic.

#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "evpipe/denoise/curvature_options.hpp"

namespace evpipe::denoise {

/// The interval of curvature values a rule accepted: every kept value lies in [lo, hi]. The causal mode
/// judges a block's events against the previous block's region.
struct ConsistencyRegion {
  bool valid = false;
  bool interval = false;  ///< shortest rule: [lo, hi]; else |c − centre| ≤ half_width
  double lo = 0.0;
  double hi = 0.0;
  double centre = 0.0;      ///< median (median rule), 0 (flattest) or the midpoint (shortest)
  double half_width = 0.0;  ///< largest kept distance from the centre

  /// Exactly the test the selection applied to the values it kept (ties at the cut aside).
  [[nodiscard]] bool contains(double c) const noexcept {
    if (!valid) return false;
    return interval ? (c >= lo && c <= hi) : std::abs(c - centre) <= half_width;
  }
  /// In [0, 1): 0.999 at the centre, falling as 0.999 / (1 + |c − centre| / half_width). Part of the score.
  [[nodiscard]] double consistency(double c) const noexcept;
};

/// ⌈f·n⌉ (with a 1e-9 tolerance so that 0.8·10 is 8, not 9), at least 1 when n > 0, at most n.
std::size_t keep_count(std::size_t n, double keep_fraction) noexcept;

/// Sets keep[i] = 1 for the kept values (keep is resized to values.size()) and returns the region.
/// Linear time (nth_element) for median and flattest, a sort for shortest.
ConsistencyRegion select_consistent(std::span<const double> values, double keep_fraction, CurvatureRule rule,
                                    std::vector<std::uint8_t>& keep);

}  // namespace evpipe::denoise
