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

QuadricBatch::QuadricBatch(const Sphere& sphere)
    : sites_(sphere.size()), pairs_(sphere.pairs()), inv_lt_(1.0 / static_cast<double>(sphere.lt_us())) {
  compact_ = true;
  for (int s = 0; s < sites_; ++s) {
    const auto& site = sphere.sites()[static_cast<std::size_t>(s)];
    int row = -1;
    for (int k = 0; k < 13; ++k) {
      if (kCompactSites[static_cast<std::size_t>(k)][0] == site.dx &&
          kCompactSites[static_cast<std::size_t>(k)][1] == site.dy)
        row = k;
    }
    if (row < 0) compact_ = false;
    slot_[s] = row;
  }
  if (!compact_) {
    for (int s = 0; s < sites_; ++s) slot_[s] = s;
  }
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

void QuadricBatch::moments_compact(double (&m)[kMoments][kLanes], double (&r)[kRhs][kLanes]) const noexcept {
  // The moments of the 13-site layout in closed form (absent sites have zero rows). All terms are small
  // integers, so the result equals any other summation order exactly.
  for (int l = 0; l < kLanes; ++l) {
    const double c = n_[0][l];
    const double ex = n_[1][l] - n_[2][l], ex2 = n_[1][l] + n_[2][l];
    const double ey = n_[3][l] - n_[4][l], ey2 = n_[3][l] + n_[4][l];
    const double sd = (n_[5][l] + n_[6][l]) + (n_[7][l] + n_[8][l]);
    const double du = (n_[5][l] + n_[6][l]) - (n_[7][l] + n_[8][l]);   // Σ u·n over the diagonals
    const double dv = (n_[5][l] - n_[6][l]) + (n_[7][l] - n_[8][l]);   // Σ v·n
    const double duv = (n_[5][l] - n_[6][l]) - (n_[7][l] - n_[8][l]);  // Σ uv·n
    const double fx = n_[9][l] - n_[10][l], fx2 = n_[9][l] + n_[10][l];
    const double fy = n_[11][l] - n_[12][l], fy2 = n_[11][l] + n_[12][l];
    m[0][l] = c + ex2 + ey2 + sd + fx2 + fy2;  // 1
    m[1][l] = ex + du + 2.0 * fx;              // u
    m[2][l] = ey + dv + 2.0 * fy;              // v
    m[3][l] = ex2 + sd + 4.0 * fx2;            // u²
    m[4][l] = duv;                             // uv
    m[5][l] = ey2 + sd + 4.0 * fy2;            // v²
    m[6][l] = ex + du + 8.0 * fx;              // u³
    m[7][l] = dv;                              // u²v
    m[8][l] = du;                              // uv²
    m[9][l] = ey + dv + 8.0 * fy;              // v³
    m[10][l] = ex2 + sd + 16.0 * fx2;          // u⁴
    m[11][l] = duv;                            // u³v
    m[12][l] = sd;                             // u²v²
    m[13][l] = duv;                            // uv³
    m[14][l] = ey2 + sd + 16.0 * fy2;          // v⁴
    const double sc = sum_[0][l];
    const double sex = sum_[1][l] - sum_[2][l], sex2 = sum_[1][l] + sum_[2][l];
    const double sey = sum_[3][l] - sum_[4][l], sey2 = sum_[3][l] + sum_[4][l];
    const double ssd = (sum_[5][l] + sum_[6][l]) + (sum_[7][l] + sum_[8][l]);
    const double sdu = (sum_[5][l] + sum_[6][l]) - (sum_[7][l] + sum_[8][l]);
    const double sdv = (sum_[5][l] - sum_[6][l]) + (sum_[7][l] - sum_[8][l]);
    const double sduv = (sum_[5][l] - sum_[6][l]) - (sum_[7][l] - sum_[8][l]);
    const double sfx = sum_[9][l] - sum_[10][l], sfx2 = sum_[9][l] + sum_[10][l];
    const double sfy = sum_[11][l] - sum_[12][l], sfy2 = sum_[11][l] + sum_[12][l];
    r[0][l] = sc + sex2 + sey2 + ssd + sfx2 + sfy2;
    r[1][l] = sex + sdu + 2.0 * sfx;
    r[2][l] = sey + sdv + 2.0 * sfy;
    r[3][l] = sex2 + ssd + 4.0 * sfx2;
    r[4][l] = sduv;
    r[5][l] = sey2 + ssd + 4.0 * sfy2;
  }
}

void QuadricBatch::moments_generic(double (&m)[kMoments][kLanes], double (&r)[kRhs][kLanes]) const noexcept {
  constexpr int L = kLanes;
  for (int l = 0; l < L; ++l) {
    for (int k = 0; k < kMoments; ++k) m[k][l] = 0.0;
    for (int k = 0; k < kRhs; ++k) r[k][l] = 0.0;
    m[0][l] = n_[0][l];  // the centre site contributes only to u⁰v⁰
    r[0][l] = sum_[0][l];
  }
  alignas(64) double pe[kMaxSphereSites / 2][L];
  alignas(64) double po[kMaxSphereSites / 2][L];
  alignas(64) double se[kMaxSphereSites / 2][L];
  alignas(64) double so[kMaxSphereSites / 2][L];
  for (int pr = 0; pr < pairs_; ++pr) {
    for (int l = 0; l < L; ++l) {
      pe[pr][l] = n_[1 + 2 * pr][l] + n_[2 + 2 * pr][l];
      po[pr][l] = n_[1 + 2 * pr][l] - n_[2 + 2 * pr][l];
      se[pr][l] = sum_[1 + 2 * pr][l] + sum_[2 + 2 * pr][l];
      so[pr][l] = sum_[1 + 2 * pr][l] - sum_[2 + 2 * pr][l];
    }
  }
  for (const Term& t : even_terms_) {
    for (int l = 0; l < L; ++l) m[t.moment][l] += t.coef * pe[t.pair][l];
  }
  for (const Term& t : odd_terms_) {
    for (int l = 0; l < L; ++l) m[t.moment][l] += t.coef * po[t.pair][l];
  }
  for (const Term& t : even_rhs_terms_) {
    for (int l = 0; l < L; ++l) r[t.moment][l] += t.coef * se[t.pair][l];
  }
  for (const Term& t : odd_rhs_terms_) {
    for (int l = 0; l < L; ++l) r[t.moment][l] += t.coef * so[t.pair][l];
  }
}

void QuadricBatch::solve(int n, double* curvature, bool* ok) noexcept {
  constexpr int L = kLanes;
  // Unused lanes repeat lane 0 so that every lane computes something finite.
  const int rows = compact_ ? 13 : sites_;
  for (int l = n; l < L; ++l) {
    for (int s = 0; s < rows; ++s) {
      n_[s][l] = n_[s][0];
      sum_[s][l] = sum_[s][0];
    }
  }
  alignas(64) double m[kMoments][L];
  alignas(64) double r[kRhs][L];
  if (compact_) {
    moments_compact(m, r);
  } else {
    moments_generic(m, r);
  }

  // LDLᵀ of G (G_ij = M[p_i + p_j, q_i + q_j], unknowns [f, d, e, a, b, c]) and G x = r, written out so
  // that the compiler vectorises across lanes. u_ij = L_ij·d_j. Only a, b, c are back-substituted.
  alignas(64) double good[L];  // 1 or 0; double so that the lane loop has one element type and vectorises
  for (int l = 0; l < L; ++l) {
    const double m00 = m[0][l], m10 = m[1][l], m01 = m[2][l], m20 = m[3][l], m11 = m[4][l], m02 = m[5][l];
    const double m30 = m[6][l], m21 = m[7][l], m12 = m[8][l], m03 = m[9][l];
    const double m40 = m[10][l], m31 = m[11][l], m22 = m[12][l], m13 = m[13][l], m04 = m[14][l];
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

    const double y0 = r[0][l];
    const double y1 = r[1][l] - l10 * y0;
    const double y2 = r[2][l] - l20 * y0 - l21 * y1;
    const double y3 = r[3][l] - l30 * y0 - l31 * y1 - l32 * y2;
    const double y4 = r[5][l] - l40 * y0 - l41 * y1 - l42 * y2 - l43 * y3;             // b pairs with v² = R02
    const double y5 = r[4][l] - l50 * y0 - l51 * y1 - l52 * y2 - l53 * y3 - l54 * y4;  // c with uv = R11
    const double x5 = y5 * r5;                                                         // c
    const double x4 = y4 * r4 - l54 * x5;                                              // b
    const double x3 = y3 * r3 - l43 * x4 - l53 * x5;                                   // a
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
  std::vector<double> sums(sums_dt.begin(), sums_dt.end());
  batch.set(0, counts.data(), sums.data());
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
