#include "evpipe/denoise/quadric.hpp"

#include <algorithm>
#include <array>
#include <stdexcept>

namespace evpipe::denoise {

namespace {

constexpr int moment_index(int p, int q) {
  // Ordered by total degree, then by q: (0,0) (1,0) (0,1) (2,0) (1,1) (0,2) (3,0) ...
  const int deg = p + q;
  return deg * (deg + 1) / 2 + q;
}

double ipow(int base, int e) {
  double r = 1.0;
  for (int i = 0; i < e; ++i) r *= base;
  return r;
}

}  // namespace

int quadric_design_rank(std::span<const std::pair<int, int>> sites_uv) {
  // Bareiss fraction-free elimination with row pivoting; entries stay minors of the matrix (|φ| ≤ 16 for
  // |u|, |v| ≤ 4, so 6×6 minors are < 2·10⁷ and every product fits int64).
  std::vector<std::array<std::int64_t, 6>> a;
  a.reserve(sites_uv.size());
  for (const auto& [u, v] : sites_uv) {
    a.push_back({1, u, v, std::int64_t{u} * u, std::int64_t{v} * v, std::int64_t{u} * v});
  }
  const std::size_t rows = a.size();
  std::size_t rank = 0;
  std::int64_t prev = 1;
  for (int col = 0; col < 6 && rank < rows; ++col) {
    std::size_t piv = rank;
    while (piv < rows && a[piv][static_cast<std::size_t>(col)] == 0) ++piv;
    if (piv == rows) continue;
    std::swap(a[piv], a[rank]);
    const std::int64_t p = a[rank][static_cast<std::size_t>(col)];
    for (std::size_t i = rank + 1; i < rows; ++i) {
      const std::int64_t f = a[i][static_cast<std::size_t>(col)];
      for (std::size_t j = static_cast<std::size_t>(col) + 1; j < 6; ++j) {
        const std::int64_t num = p * a[i][j] - f * a[rank][j];
        if (num % prev != 0) throw std::logic_error("quadric_design_rank: inexact Bareiss division");
        a[i][j] = num / prev;
      }
      a[i][static_cast<std::size_t>(col)] = 0;
    }
    prev = p;
    ++rank;
  }
  return static_cast<int>(rank);
}

SingularMaskTable::SingularMaskTable(const Sphere& sphere) {
  for (const auto& s : sphere.sites()) uv_.emplace_back(s.dx, s.dy);
  if (uv_.size() <= 16) table_.assign(std::size_t{1} << uv_.size(), std::int8_t{-1});
}

bool SingularMaskTable::compute(std::uint64_t mask) const {
  if (__builtin_popcountll(mask) < 6) return false;
  std::vector<std::pair<int, int>> occupied;
  for (std::size_t s = 0; s < uv_.size(); ++s) {
    if ((mask >> s) & 1U) occupied.push_back(uv_[s]);
  }
  return quadric_design_rank(occupied) == 6;
}

bool SingularMaskTable::cached(std::uint64_t mask) {
  if (const auto it = cache_.find(mask); it != cache_.end()) return it->second;
  if (cache_.size() >= (std::size_t{1} << 20)) cache_.clear();  // bounded memory; recomputing is exact
  const bool r = compute(mask);
  cache_.emplace(mask, r);
  return r;
}

// Canonical rows of the compact layout: C, (±1,0), (0,±1), (1,1) (1,−1) (−1,1) (−1,−1), (±2,0), (0,±2).
constexpr std::array<std::array<int, 2>, 13> kCompactSites = {
    {{0, 0}, {1, 0}, {-1, 0}, {0, 1}, {0, -1}, {1, 1}, {1, -1}, {-1, 1}, {-1, -1}, {2, 0}, {-2, 0}, {0, 2}, {0, -2}}};

// Site index of each canonical position in Sphere's order for its 13- and 9-site balls (r ∈ [2, √5) and
// r ∈ [√2, 2) inclusive); 13 / 9 = the zero entry one past the last site.
constexpr std::array<int, 13> kLayout13 = {0, 12, 11, 6, 5, 4, 7, 8, 3, 10, 9, 2, 1};
constexpr std::array<int, 13> kLayout9 = {0, 8, 7, 4, 3, 2, 5, 6, 1, 9, 9, 9, 9};

QuadricBatch::QuadricBatch(const Sphere& sphere)
    : sites_(sphere.size()), pairs_(sphere.pairs()), inv_lt_(1.0 / static_cast<double>(sphere.lt_us())) {
  compact_ = true;
  for (int k = 0; k < 13; ++k) canonical_[k] = sites_;  // the zero entry
  for (int s = 0; s < sites_; ++s) {
    const auto& site = sphere.sites()[static_cast<std::size_t>(s)];
    bool found = false;
    for (int k = 0; k < 13; ++k) {
      if (kCompactSites[static_cast<std::size_t>(k)][0] == site.dx &&
          kCompactSites[static_cast<std::size_t>(k)][1] == site.dy) {
        canonical_[k] = s;
        found = true;
      }
    }
    compact_ = compact_ && found;
  }
  const auto matches = [&](const std::array<int, 13>& layout, int n) {
    if (sites_ != n) return false;
    for (int k = 0; k < 13; ++k) {
      if (canonical_[k] != (layout[static_cast<std::size_t>(k)] >= n ? sites_ : layout[static_cast<std::size_t>(k)])) {
        return false;
      }
    }
    return true;
  };
  if (compact_ && matches(kLayout13, 13)) layout_ = 13;
  if (compact_ && matches(kLayout9, 9)) layout_ = 9;
  for (int pr = 0; pr < pairs_; ++pr) {
    const auto& s = sphere.sites()[static_cast<std::size_t>(1 + 2 * pr)];
    for (int deg = 0; deg <= 4; ++deg) {
      for (int q = 0; q <= deg; ++q) {
        const int p = deg - q;
        const double coef = ipow(s.dx, p) * ipow(s.dy, q);
        if (coef == 0.0) continue;
        // The antipode (−u, −v) has the same u^p v^q for even p + q and the opposite for odd.
        (deg % 2 == 0 ? even_terms_ : odd_terms_).push_back({moment_index(p, q), pr, coef});
        if (deg <= 2) (deg % 2 == 0 ? even_rhs_terms_ : odd_rhs_terms_).push_back({moment_index(p, q), pr, coef});
      }
    }
  }
}

void QuadricBatch::set(int lane, const std::int32_t* counts, const double* sums_dt) noexcept {
  if (layout_ == 13) {
    set_compact<kLayout13>(lane, counts, sums_dt);
  } else if (layout_ == 9) {
    set_compact<kLayout9>(lane, counts, sums_dt);
  } else if (compact_) {
    // Any other subset of the 13 sites (radius < √2: always singular, so never fitted in practice).
    std::int32_t c[14];
    double sm[14];
    for (int k = 0; k < 13; ++k) {
      c[k] = counts[canonical_[k]];
      sm[k] = sums_dt[canonical_[k]];
    }
    c[13] = 0;
    sm[13] = 0.0;
    set_compact<std::array<int, 13>{0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12}>(lane, c, sm);
  } else {
    set_generic(lane, counts, sums_dt);
  }
}

void QuadricBatch::set_generic(int lane, const std::int32_t* counts, const double* sums_dt) noexcept {
  double m[kMoments] = {};
  double r[kRhs] = {};
  m[0] = counts[0];  // the centre site contributes only to u⁰v⁰
  r[0] = sums_dt[0];
  for (const Term& t : even_terms_) m[t.moment] += t.coef * (counts[1 + 2 * t.pair] + counts[2 + 2 * t.pair]);
  for (const Term& t : odd_terms_) m[t.moment] += t.coef * (counts[1 + 2 * t.pair] - counts[2 + 2 * t.pair]);
  for (const Term& t : even_rhs_terms_) r[t.moment] += t.coef * (sums_dt[1 + 2 * t.pair] + sums_dt[2 + 2 * t.pair]);
  for (const Term& t : odd_rhs_terms_) r[t.moment] += t.coef * (sums_dt[1 + 2 * t.pair] - sums_dt[2 + 2 * t.pair]);
  for (int i = 0; i < kMoments; ++i) m_[i][lane] = m[i];
  for (int i = 0; i < kRhs; ++i) r_[i][lane] = r[i];
}

void QuadricBatch::solve(int n, double* curvature, bool* ok) noexcept {
  constexpr int L = kLanes;
  // Unused lanes repeat lane 0 so that every lane computes something finite.
  for (int l = n; l < L; ++l) {
    for (int i = 0; i < kMoments; ++i) m_[i][l] = m_[i][0];
    for (int i = 0; i < kRhs; ++i) r_[i][l] = r_[i][0];
    for (int i = 0; i < 13; ++i) {
      nc_[i][l] = nc_[i][0];
      sc_[i][l] = sc_[i][0];
    }
  }
  if (compact_) {
    // The moments of the 13-site layout in closed form (canonical rows: C, (±1,0), (0,±1), (1,1) (1,−1)
    // (−1,1) (−1,−1), (±2,0), (0,±2); absent sites hold zeros). Counts are summed in integers; every value
    // is an integer far below 2⁵³, so the result is exact whatever the order of summation.
    for (int l = 0; l < L; ++l) {
      const std::int32_t c = nc_[0][l];
      const std::int32_t ex = nc_[1][l] - nc_[2][l], ex2 = nc_[1][l] + nc_[2][l];
      const std::int32_t ey = nc_[3][l] - nc_[4][l], ey2 = nc_[3][l] + nc_[4][l];
      const std::int32_t d1 = nc_[5][l], d2 = nc_[6][l], d3 = nc_[7][l], d4 = nc_[8][l];  // ++ +− −+ −−
      const std::int32_t sd = (d1 + d2) + (d3 + d4);
      const std::int32_t du = (d1 + d2) - (d3 + d4);   // Σ u·n over the diagonals
      const std::int32_t dv = (d1 - d2) + (d3 - d4);   // Σ v·n
      const std::int32_t duv = (d1 - d2) - (d3 - d4);  // Σ uv·n
      const std::int32_t fx = nc_[9][l] - nc_[10][l], fx2 = nc_[9][l] + nc_[10][l];
      const std::int32_t fy = nc_[11][l] - nc_[12][l], fy2 = nc_[11][l] + nc_[12][l];
      m_[0][l] = c + ex2 + ey2 + sd + fx2 + fy2;  // 1
      m_[1][l] = ex + du + 2 * fx;                // u
      m_[2][l] = ey + dv + 2 * fy;                // v
      m_[3][l] = ex2 + sd + 4 * fx2;              // u²
      m_[4][l] = duv;                             // uv
      m_[5][l] = ey2 + sd + 4 * fy2;              // v²
      m_[6][l] = ex + du + 8 * fx;                // u³
      m_[7][l] = dv;                              // u²v
      m_[8][l] = du;                              // uv²
      m_[9][l] = ey + dv + 8 * fy;                // v³
      m_[10][l] = ex2 + sd + 16 * fx2;            // u⁴
      m_[11][l] = duv;                            // u³v
      m_[12][l] = sd;                             // u²v²
      m_[13][l] = duv;                            // uv³
      m_[14][l] = ey2 + sd + 16 * fy2;            // v⁴
      const double sex = sc_[1][l] - sc_[2][l], sex2 = sc_[1][l] + sc_[2][l];
      const double sey = sc_[3][l] - sc_[4][l], sey2 = sc_[3][l] + sc_[4][l];
      const double e1 = sc_[5][l], e2 = sc_[6][l], e3 = sc_[7][l], e4 = sc_[8][l];
      const double ssd = (e1 + e2) + (e3 + e4);
      const double sdu = (e1 + e2) - (e3 + e4);
      const double sdv = (e1 - e2) + (e3 - e4);
      const double sduv = (e1 - e2) - (e3 - e4);
      const double sfx = sc_[9][l] - sc_[10][l], sfx2 = sc_[9][l] + sc_[10][l];
      const double sfy = sc_[11][l] - sc_[12][l], sfy2 = sc_[11][l] + sc_[12][l];
      r_[0][l] = sc_[0][l] + sex2 + sey2 + ssd + sfx2 + sfy2;
      r_[1][l] = sex + sdu + 2.0 * sfx;
      r_[2][l] = sey + sdv + 2.0 * sfy;
      r_[3][l] = sex2 + ssd + 4.0 * sfx2;
      r_[4][l] = sduv;
      r_[5][l] = sey2 + ssd + 4.0 * sfy2;
    }
  }
  // LDLᵀ of G (G_ij = M[p_i + p_j, q_i + q_j], unknowns [f, d, e, a, b, c]) and G x = r, written out so
  // that the compiler vectorises across lanes. u_ij = L_ij·d_j. Only a, b, c are back-substituted.
  alignas(64) double good[L];  // 1 or 0; double so that the lane loop has one element type and vectorises
  for (int l = 0; l < L; ++l) {
    const double m00 = m_[0][l], m10 = m_[1][l], m01 = m_[2][l], m20 = m_[3][l], m11 = m_[4][l], m02 = m_[5][l];
    const double m30 = m_[6][l], m21 = m_[7][l], m12 = m_[8][l], m03 = m_[9][l];
    const double m40 = m_[10][l], m31 = m_[11][l], m22 = m_[12][l], m13 = m_[13][l], m04 = m_[14][l];
    // G rows (f, d, e, a, b, c) × columns, lower triangle.
    const double g00 = m00;
    const double g10 = m10, g11 = m20;
    const double g20 = m01, g21 = m11, g22 = m02;
    const double g30 = m20, g31 = m30, g32 = m21, g33 = m40;
    const double g40 = m02, g41 = m12, g42 = m03, g43 = m22, g44 = m04;
    const double g50 = m11, g51 = m21, g52 = m12, g53 = m31, g54 = m13, g55 = m22;

    const double d0 = g00, r0 = 1.0 / d0;
    const double l10 = g10 * r0, l20 = g20 * r0, l30 = g30 * r0, l40 = g40 * r0, l50 = g50 * r0;
    const double d1 = g11 - l10 * g10, r1 = 1.0 / d1;
    const double u21 = g21 - l20 * g10, u31 = g31 - l30 * g10, u41 = g41 - l40 * g10, u51 = g51 - l50 * g10;
    const double l21 = u21 * r1, l31 = u31 * r1, l41 = u41 * r1, l51 = u51 * r1;
    const double d2 = g22 - l20 * g20 - l21 * u21, r2 = 1.0 / d2;
    const double u32 = g32 - l30 * g20 - l31 * u21;
    const double u42 = g42 - l40 * g20 - l41 * u21;
    const double u52 = g52 - l50 * g20 - l51 * u21;
    const double l32 = u32 * r2, l42 = u42 * r2, l52 = u52 * r2;
    const double d3 = g33 - l30 * g30 - l31 * u31 - l32 * u32, r3 = 1.0 / d3;
    const double u43 = g43 - l40 * g30 - l41 * u31 - l42 * u32;
    const double u53 = g53 - l50 * g30 - l51 * u31 - l52 * u32;
    const double l43 = u43 * r3, l53 = u53 * r3;
    const double d4 = g44 - l40 * g40 - l41 * u41 - l42 * u42 - l43 * u43, r4 = 1.0 / d4;
    const double u54 = g54 - l50 * g40 - l51 * u41 - l52 * u42 - l53 * u43;
    const double l54 = u54 * r4;
    const double d5 = g55 - l50 * g50 - l51 * u51 - l52 * u52 - l53 * u53 - l54 * u54, r5 = 1.0 / d5;

    const double y0 = r_[0][l];
    const double y1 = r_[1][l] - l10 * y0;
    const double y2 = r_[2][l] - l20 * y0 - l21 * y1;
    const double y3 = r_[3][l] - l30 * y0 - l31 * y1 - l32 * y2;
    const double y4 = r_[5][l] - l40 * y0 - l41 * y1 - l42 * y2 - l43 * y3;             // b pairs with v² = R02
    const double y5 = r_[4][l] - l50 * y0 - l51 * y1 - l52 * y2 - l53 * y3 - l54 * y4;  // c with uv = R11
    const double x5 = y5 * r5;                                                          // c
    const double x4 = y4 * r4 - l54 * x5;                                               // b
    const double x3 = y3 * r3 - l43 * x4 - l53 * x5;                                    // a
    abc_[0][l] = x3 * inv_lt_;
    abc_[1][l] = x4 * inv_lt_;
    abc_[2][l] = x5 * inv_lt_;
    // Relative pivot test: never met for full-rank masks, kept so that a degenerate input cannot produce a
    // curvature from a meaningless factorisation.
    const double worst =
        std::min(std::min(std::min(d0 - 1e-9 * g00, d1 - 1e-9 * g11), std::min(d2 - 1e-9 * g22, d3 - 1e-9 * g33)),
                 std::min(d4 - 1e-9 * g44, d5 - 1e-9 * g55));
    good[l] = worst > 0.0 ? 1.0 : 0.0;
  }
  for (int l = 0; l < n; ++l) {
    curvature[l] = 4.0 * abc_[0][l] * abc_[1][l] - abc_[2][l] * abc_[2][l];
    ok[l] = good[l] != 0.0;
  }
}

QuadricFit fit_quadric(const Sphere& sphere, std::span<const std::int32_t> counts,
                       std::span<const std::int64_t> sums_dt) {
  QuadricFit fit;
  std::uint64_t mask = 0;
  for (int s = 0; s < sphere.size(); ++s) {
    if (counts[static_cast<std::size_t>(s)] > 0) mask |= std::uint64_t{1} << s;
  }
  SingularMaskTable table(sphere);
  if (!table.full_rank(mask)) return fit;
  QuadricBatch batch(sphere);
  std::vector<std::int32_t> c(counts.begin(), counts.end());
  std::vector<double> sums(sums_dt.begin(), sums_dt.end());
  c.resize(static_cast<std::size_t>(sphere.size()) + 1, 0);  // the zero entry set() expects
  sums.resize(static_cast<std::size_t>(sphere.size()) + 1, 0.0);
  batch.set(0, c.data(), sums.data());
  double curv = 0;
  bool ok = false;
  batch.solve(1, &curv, &ok);
  fit.defined = ok;
  fit.a = batch.coefficient(0, 0);
  fit.b = batch.coefficient(1, 0);
  fit.c = batch.coefficient(2, 0);
  fit.curvature = curv;
  return fit;
}

}  // namespace evpipe::denoise
