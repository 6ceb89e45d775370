#pragma once
// The paper's local quadric fit (section 3.2) from per-site neighbour statistics.
//
// Around event i the neighbours are the points (u, v, w) = (dx, dy, Δt / Lt); least squares fits
//   w = a u² + b v² + c uv + d u + e v + f
// and the event's curvature is det of the Hessian, c_i = 4ab − c² (the paper's choice; not divided by
// (1 + d² + e²)²). Since (u, v) takes one value per sphere site, the normal equations XᵀX C = Xᵀw need only
// the per-site neighbour count n_s and the per-site sum of Δt, S_s — both exact integers, so any two
// neighbourhood indexes that agree on (n_s, S_s) agree bit for bit on the fit:
//   XᵀX = Σ_s n_s φ_s φ_sᵀ,   Xᵀw = Σ_s (S_s / Lt) φ_s,   φ = [1, u, v, u², v², uv].
// Both sums are accumulated exactly (small integers in double), then solved by a 6×6 LDLᵀ; only a, b, c
// are back-substituted.
//
// Whether X has rank 6 depends only on which sites are occupied, so it is decided exactly, once per
// occupancy mask, by integer (fraction-free) elimination — no numerical rank threshold.

#include <array>
#include <cstdint>
#include <span>
#include <unordered_map>
#include <utility>
#include <vector>

#include "evpipe/denoise/sphere.hpp"

namespace evpipe::denoise {

/// Exact rank of the design matrix whose rows are φ(u, v) = [1, u, v, u², v², uv] for the given sites
/// (fraction-free Bareiss elimination in int64; exact for |u|, |v| ≤ 4).
int quadric_design_rank(std::span<const std::pair<int, int>> sites_uv);

/// Rank-6 test per occupancy mask (bit s = site s of the sphere holds at least one event of the ball),
/// computed on first use and remembered: a table for ≤ 16 sites, a bounded cache above.
class SingularMaskTable {
 public:
  explicit SingularMaskTable(const Sphere& sphere);
  [[nodiscard]] bool full_rank(std::uint64_t mask) {
    if (!table_.empty()) {
      std::int8_t& v = table_[static_cast<std::size_t>(mask)];
      if (v < 0) v = compute(mask) ? 1 : 0;
      return v != 0;
    }
    return cached(mask);
  }

 private:
  bool compute(std::uint64_t mask) const;
  bool cached(std::uint64_t mask);
  std::vector<std::pair<int, int>> uv_;
  std::vector<std::int8_t> table_;  // −1 unknown, 0 singular, 1 full rank
  std::unordered_map<std::uint64_t, bool> cache_;
};

/// Fits quadrics for up to kLanes events at once: set() reduces an event's per-site statistics to the 15 + 6
/// exact moments of its normal equations, solve() factorises all lanes together (structure of arrays, so
/// the compiler vectorises across events).
class QuadricBatch {
 public:
  static constexpr int kLanes = 8;

  explicit QuadricBatch(const Sphere& sphere);

  /// Lane `lane` gets the event whose ball has n_s = counts[s] events at site s (the event itself included
  /// at the centre) with Δt sum S_s = sums_dt[s] µs (an integer, exact in double). Both arrays must hold a
  /// zero at index sphere.size() (one past the last site).
  void set(int lane, const std::int32_t* counts, const double* sums_dt) noexcept;
  /// Solves lanes [0, n) (they must have full-rank masks). curvature[l] = 4ab − c² in (w = Δt/Lt) units;
  /// ok[l] = false only if the factorisation met a non-positive pivot (not seen for full-rank masks).
  void solve(int n, double* curvature, bool* ok) noexcept;

  /// The fit coefficients [a, b, c] of the last solve, for tests.
  [[nodiscard]] double coefficient(int which, int lane) const noexcept { return abc_[which][lane]; }

 private:
  static constexpr int kMoments = 15;  // M_pq = Σ n u^p v^q, p + q ≤ 4
  static constexpr int kRhs = 6;       // R_pq = Σ S u^p v^q, p + q ≤ 2
  struct Term {
    int moment;
    int pair;
    double coef;
  };
  template <std::array<int, 13> K>
  void set_compact(int lane, const std::int32_t* counts, const double* sums_dt) noexcept {
    for (std::size_t k = 0; k < 13; ++k) {
      nc_[k][lane] = counts[K[k]];
      sc_[k][lane] = sums_dt[K[k]];
    }
  }
  void set_generic(int lane, const std::int32_t* counts, const double* sums_dt) noexcept;

  int sites_;
  int pairs_;
  bool compact_;    // every site within the 13 sites of |u|, |v| ≤ 2, u² + v² ≤ 4 (radius < √5)
  int layout_ = 0;  // compact: 13 or 9 when the sites are in Sphere's order for those sizes, else 0
  double inv_lt_;
  int canonical_[13] = {};                    // compact: the site of each canonical position, or sites_ (a zero entry)
  std::vector<Term> even_terms_, odd_terms_;  // generic path
  std::vector<Term> even_rhs_terms_, odd_rhs_terms_;
  alignas(64) double m_[kMoments][kLanes] = {};  // generic layouts: moments per lane, formed in set()
  alignas(64) double r_[kRhs][kLanes] = {};
  alignas(64) std::int32_t nc_[13][kLanes] = {};  // compact layouts: per-site inputs in canonical order,
  alignas(64) double sc_[13][kLanes] = {};        // reduced to moments across lanes in solve()
  alignas(64) double abc_[3][kLanes] = {};
};

/// One event's fit from its per-site statistics (convenience for tests and diagnostics): nullopt-like
/// `defined = false` when the occupied sites do not give rank 6.
struct QuadricFit {
  bool defined = false;
  double a = 0, b = 0, c = 0;  ///< w = Δt / Lt units
  double curvature = 0;        ///< 4ab − c²
};
QuadricFit fit_quadric(const Sphere& sphere, std::span<const std::int32_t> counts,
                       std::span<const std::int64_t> sums_dt);

}  // namespace evpipe::denoise
