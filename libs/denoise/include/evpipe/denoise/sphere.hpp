#pragma once
// The paper's spherical spatio-temporal neighbourhood (section 3.1) on the integer pixel grid.
//
// An event is the point (x, y, t / Lt); the ball of radius r around event i holds every event j with
//   dx² + dy² + (Δt / Lt)² ≤ r²   ⇔   (dx² + dy²)·Lt² + Δt² ≤ r²·Lt²        (Δt in µs, Lt in µs per pixel)
// The left side is an integer, so the test is exact in int64 against `limit` = the largest integer squared
// distance that is inside (floor(r²Lt²) when inclusive, the largest integer below r²Lt² when strict).
// Because dx, dy are integers the ball is a small set of pixel sites, each with its own largest |Δt|:
// r = 2, Lt = 10⁴ µs gives 13 sites with half-widths 20000 (centre), 17320 (4 edge neighbours), 14142
// (4 diagonals) and 0 µs ((±2,0), (0,±2): only events at the very same µs, and only when inclusive).
//
// Site order (everything indexed by site uses it): the centre first, then antipodal pairs (s, −s) next to
// each other, s being the member with dy < 0 or (dy = 0, dx < 0). Pairs share |Δt| limits, which halves the
// work of building the normal equations (quadric.hpp).

#include <cstdint>
#include <vector>

namespace evpipe::denoise {

/// Largest radius accepted (pixels): keeps the site count ≤ 64 so that an occupancy mask fits a uint64.
inline constexpr double kMaxSphereRadiusPx = 4.0;
/// Largest Lt accepted (µs per pixel): keeps r²Lt² + Δt² exact in a double (FLANN backend) and in int64.
inline constexpr std::int64_t kMaxSphereLtUs = 10'000'000;
inline constexpr int kMaxSphereSites = 64;

struct SphereSite {
  int dx = 0;
  int dy = 0;
  std::int64_t half_width_us = 0;  ///< largest |Δt| inside the ball at this site
};

class Sphere {
 public:
  /// Throws std::invalid_argument when radius_px ∉ (0, 4] or lt_us ∉ [1, 10⁷].
  Sphere(double radius_px, std::int64_t lt_us, bool inclusive);

  [[nodiscard]] double radius_px() const noexcept { return radius_px_; }
  [[nodiscard]] std::int64_t lt_us() const noexcept { return lt_us_; }
  [[nodiscard]] bool inclusive() const noexcept { return inclusive_; }
  /// Largest integer value of (dx² + dy²)·Lt² + Δt² inside the ball.
  [[nodiscard]] std::int64_t limit() const noexcept { return limit_; }
  [[nodiscard]] const std::vector<SphereSite>& sites() const noexcept { return sites_; }
  [[nodiscard]] int size() const noexcept { return static_cast<int>(sites_.size()); }
  /// Number of antipodal pairs: sites 1 + 2p and 2 + 2p are (dx, dy) and (−dx, −dy).
  [[nodiscard]] int pairs() const noexcept { return (size() - 1) / 2; }
  /// Largest |dx| (= largest |dy|) of a site.
  [[nodiscard]] int extent_px() const noexcept { return extent_px_; }
  /// Largest |Δt| of the ball (the centre's half-width): how far in time a decision must look.
  [[nodiscard]] std::int64_t reach_us() const noexcept { return sites_.front().half_width_us; }
  /// Index of the site (dx, dy), −1 when it is outside the ball.
  [[nodiscard]] int site_index(int dx, int dy) const noexcept;
  /// The exact membership test (used by tests; the indexes use the per-site half-widths).
  [[nodiscard]] bool contains(int dx, int dy, std::int64_t dt_us) const noexcept;

 private:
  double radius_px_;
  std::int64_t lt_us_;
  bool inclusive_;
  std::int64_t limit_ = 0;
  int extent_px_ = 0;
  std::vector<SphereSite> sites_;
  std::vector<int> index_;  // (2·extent+1)² lookup, −1 = outside
};

}  // namespace evpipe::denoise
