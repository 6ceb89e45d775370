#include "evpipe/denoise/quadric.hpp"

#include <array>
#include <stdexcept>

namespace evpipe::denoise {

namespace {

// Exponents (p, q) of u^p v^q for the unknowns in solve order [f, d, e, a, b, c]: a, b, c last, so that
// back substitution stops after three steps.
constexpr std::array<std::array<int, 2>, 6> kUnknownPq = {{{0, 0}, {1, 0}, {0, 1}, {2, 0}, {0, 2}, {1, 1}}};
constexpr int kMoments = 15;  // p + q ≤ 4
constexpr int kRhs = 6;       // p + q ≤ 2

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

QuadricBatch::QuadricBatch(const Sphere& sphere)
    : sites_(sphere.size()), pairs_(sphere.pairs()), inv_lt_(1.0 / static_cast<double>(sphere.lt_us())) {
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

void QuadricBatch::solve(int n, double* curvature, bool* ok) noexcept {
  constexpr int L = kLanes;
  // Unused lanes repeat lane 0 so that every lane computes something finite.
  for (int l = n; l < L; ++l) {
    for (int s = 0; s < sites_; ++s) {
      n_[s][l] = n_[s][0];
      sum_[s][l] = sum_[s][0];
    }
  }
  alignas(64) double m[kMoments][L];
  alignas(64) double r[kRhs][L];
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
  // All values are integers far below 2⁵³, so these sums are exact whatever the order.
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

  // LDLᵀ of G (G_ij = M[p_i + p_j, q_i + q_j]) and solve G x = r.
  alignas(64) double lo[6][6][L];  // strictly lower factor
  alignas(64) double d[6][L];
  alignas(64) double inv_d[6][L];
  alignas(64) double y[6][L];
  bool good[L];
  for (int l = 0; l < L; ++l) good[l] = true;
  for (int j = 0; j < 6; ++j) {
    const int mjj = moment_index(2 * kUnknownPq[j][0], 2 * kUnknownPq[j][1]);
    for (int l = 0; l < L; ++l) {
      double v = m[mjj][l];
      for (int k = 0; k < j; ++k) v -= lo[j][k][l] * lo[j][k][l] * d[k][l];
      d[j][l] = v;
      good[l] = good[l] && v > 1e-9 * m[mjj][l];
      inv_d[j][l] = 1.0 / v;
    }
    for (int i = j + 1; i < 6; ++i) {
      const int mij = moment_index(kUnknownPq[i][0] + kUnknownPq[j][0], kUnknownPq[i][1] + kUnknownPq[j][1]);
      for (int l = 0; l < L; ++l) {
        double v = m[mij][l];
        for (int k = 0; k < j; ++k) v -= lo[i][k][l] * lo[j][k][l] * d[k][l];
        lo[i][j][l] = v * inv_d[j][l];
      }
    }
  }
  for (int i = 0; i < 6; ++i) {
    const int ri = moment_index(kUnknownPq[i][0], kUnknownPq[i][1]);
    for (int l = 0; l < L; ++l) {
      double v = r[ri][l];
      for (int k = 0; k < i; ++k) v -= lo[i][k][l] * y[k][l];
      y[i][l] = v;
    }
  }
  for (int l = 0; l < L; ++l) {
    const double x5 = y[5][l] * inv_d[5][l];                                        // c
    const double x4 = y[4][l] * inv_d[4][l] - lo[5][4][l] * x5;                     // b
    const double x3 = y[3][l] * inv_d[3][l] - lo[4][3][l] * x4 - lo[5][3][l] * x5;  // a
    const double a = x3 * inv_lt_;
    const double b = x4 * inv_lt_;
    const double c = x5 * inv_lt_;
    abc_[0][l] = a;
    abc_[1][l] = b;
    abc_[2][l] = c;
    if (l < n) {
      curvature[l] = 4.0 * a * b - c * c;
      ok[l] = good[l];
    }
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
  batch.set(0, counts.data(), sums_dt.data());
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
