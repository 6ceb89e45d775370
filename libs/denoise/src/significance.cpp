#include "evpipe/denoise/significance.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include <cstdlib>
#include <string_view>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define EVPIPE_SIGNIFICANCE_X86 1
#endif

namespace evpipe::denoise {

namespace {

constexpr std::int32_t kNeverTime = -(std::int32_t{1} << 29);  // relative time of "no event"
constexpr std::int32_t kNever = kNeverTime * 2;                // stored value
constexpr std::int64_t kRebaseAt = std::int64_t{1} << 29;      // relative µs (about 9 min)
constexpr std::int64_t kKeepOnRebase = std::int64_t{1} << 24;  // history kept exact on a rebase (about 16 s)
constexpr std::int32_t kZeroSupportUs = 10'000;                // T0 of the rate estimator
constexpr std::int32_t kShortZeroSupportUs = 1'000;            // T1 < T0: picks the root (update_rate)
constexpr std::int64_t kWarmupProbeUs = 1'000;                 // warm-up: the whole event rate's update period
constexpr int kNeighbours = 8;
constexpr std::int32_t kAgeCap = std::numeric_limits<std::int32_t>::max() / 4;

/// P(Binomial(n, p) >= k).
double binomial_sf(int n, double p, int k) noexcept {
  if (k <= 0) return 1.0;
  if (k > n) return 0.0;
  if (p <= 0.0) return 0.0;
  if (p >= 1.0) return 1.0;
  double sum = 0.0;
  for (int i = k; i <= n; ++i) {
    const double log_c = std::lgamma(n + 1.0) - std::lgamma(i + 1.0) - std::lgamma(n - i + 1.0);
    sum += std::exp(log_c + i * std::log(p) + (n - i) * std::log1p(-p));
  }
  return std::min(1.0, sum);
}

/// Largest p with P(Binomial(n, p) >= k) <= target (bisection; the tail increases with p).
double binomial_quantile(int n, int k, double target) noexcept {
  double lo = 0.0;
  double hi = 1.0;
  for (int it = 0; it < 60; ++it) {
    const double mid = 0.5 * (lo + hi);
    (binomial_sf(n, mid, k) <= target ? lo : hi) = mid;
  }
  return lo;
}

/// The age U at which a direction's noise-match probability p(U) = 1 − exp(−(λ²/2)(δ₀U + εU²/2)) reaches `p`
/// (docs/algorithms.md eq. 2), capped at T; seconds.
double line_age_s(double p, double rate_hz, double jitter_s, double eps, double T) noexcept {
  if (rate_hz <= 0.0) return T;
  const double pairs = -std::log1p(-p);
  const double c = 2.0 * pairs / (rate_hz * rate_hz);  // jitter·U + eps·U²/2 = c
  const double u_s = eps > 0.0 ? (-jitter_s + std::sqrt(jitter_s * jitter_s + 2.0 * eps * c)) / eps
                               : (jitter_s > 0.0 ? c / jitter_s : T);
  return std::min(u_s, T);
}

/// Sorting network (19 compare-exchanges) for 8 values, on locals so that each exchange is a min and a max.
inline void sort8(std::array<std::int32_t, 8>& v) noexcept {
  std::int32_t a0 = v[0], a1 = v[1], a2 = v[2], a3 = v[3], a4 = v[4], a5 = v[5], a6 = v[6], a7 = v[7];
  const auto cx = [](std::int32_t& x, std::int32_t& y) {
    const std::int32_t lo = std::min(x, y);
    y = std::max(x, y);
    x = lo;
  };
  cx(a0, a2), cx(a1, a3), cx(a4, a6), cx(a5, a7);
  cx(a0, a4), cx(a1, a5), cx(a2, a6), cx(a3, a7);
  cx(a0, a1), cx(a2, a3), cx(a4, a5), cx(a6, a7);
  cx(a2, a4), cx(a3, a5);
  cx(a1, a4), cx(a3, a6);
  cx(a1, a2), cx(a3, a4), cx(a5, a6);
  v = {a0, a1, a2, a3, a4, a5, a6, a7};
}

constexpr std::array<std::int8_t, 8> kDx = {-1, 0, 1, -1, 1, -1, 0, 1};
constexpr std::array<std::int8_t, 8> kDy = {-1, -1, -1, 0, 0, 1, 1, 1};

#if defined(EVPIPE_SIGNIFICANCE_X86)
// The edge-line test's matching, vectorised. Per direction d, both rings in one register each (entries newest
// first; on time-ordered input their ages ascend). The scalar walk (Significance::edge_lines_scalar) finds the
// first entry a of p − d (age s_a <= T, the event's polarity) for which some entry of p − 2d with the polarity has
// its age in [L_a, (2 + ε)s_a + δ₀], L_a being the largest lower bound (2 − ε)s_a' − δ₀ over the entries a' <= a
// it examined (its second pointer never moves back). With ascending ages that is the same as testing the 4×4
// pairs at once and taking the smallest s_a that matched. The decision as counts: u_(m) <= U_m for some m
// (U_m > 0) iff at least m of the matched ages are <= U_m; once it holds the scalar walk stops, and so do these.
// Both return n and the matched ages found[0..n) in direction order.
struct LineArgs {
  const std::int32_t* ring;
  std::int64_t stride;
  std::int64_t centre;
  std::int32_t now;
  int polarity;
  const std::int32_t* line_us;  // U_1..U_8; U_8 is the window T' of the walk
  std::int32_t jitter_us;
  float precision;
  /// false: an event the test rejects gets margin 0 instead of its exact margin (SignificanceOptions::exact_scores;
  /// match_lines_avx2 then skips the ranks and the divisions).
  bool margins = true;
};

constexpr std::int32_t kNoMatch = std::numeric_limits<std::int32_t>::max();

__attribute__((target("sse4.1"))) std::size_t match_ages_sse4(const LineArgs& a,
                                                              std::array<std::int32_t, 9>& found) noexcept {
  const __m128i v_now = _mm_set1_epi32(a.now);
  const __m128i v_pol = _mm_set1_epi32(a.polarity);
  const __m128i v_one = _mm_set1_epi32(1);
  const __m128i v_past_window = _mm_set1_epi32(a.line_us[7] + 1);
  const __m128i v_jitter = _mm_set1_epi32(a.jitter_us);
  const __m128 v_precision = _mm_set1_ps(a.precision);
  const __m128i v_lowest = _mm_set1_epi32(std::numeric_limits<std::int32_t>::min());
  const __m128i v_highest = _mm_set1_epi32(kNoMatch);
  const __m128i u_lo = _mm_loadu_si128(reinterpret_cast<const __m128i*>(a.line_us));
  const __m128i u_hi = _mm_loadu_si128(reinterpret_cast<const __m128i*>(a.line_us + 4));
  const __m128i u_lo1 = _mm_add_epi32(u_lo, v_one);
  const __m128i u_hi1 = _mm_add_epi32(u_hi, v_one);
  // count > m − 1 decides m (m = 1..8); never for U_m <= 0.
  const __m128i need_lo =
      _mm_blendv_epi8(v_highest, _mm_setr_epi32(0, 1, 2, 3), _mm_cmpgt_epi32(u_lo, _mm_setzero_si128()));
  const __m128i need_hi =
      _mm_blendv_epi8(v_highest, _mm_setr_epi32(4, 5, 6, 7), _mm_cmpgt_epi32(u_hi, _mm_setzero_si128()));
  __m128i count_lo = _mm_setzero_si128();
  __m128i count_hi = _mm_setzero_si128();
  std::size_t n = 0;
  for (std::size_t i = 0; i < 8; ++i) {
    const std::int64_t off = kDy[i] * a.stride + kDx[i];
    const __m128i r1 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(a.ring + (a.centre - off) * 4));
    const __m128i r2 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(a.ring + (a.centre - 2 * off) * 4));
    // Ages of p − d, capped just past the window (entries past it are never examined, nor are the ones after).
    const __m128i s1 = _mm_min_epi32(_mm_sub_epi32(v_now, _mm_srai_epi32(r1, 1)), v_past_window);
    const __m128i pol1 = _mm_cmpeq_epi32(_mm_and_si128(r1, v_one), v_pol);
    // Ages of p − 2d; an entry of the other polarity never matches (past every upper bound).
    const __m128i pol2 = _mm_cmpeq_epi32(_mm_and_si128(r2, v_one), v_pol);
    const __m128i s2 = _mm_blendv_epi8(v_highest, _mm_sub_epi32(v_now, _mm_srai_epi32(r2, 1)), pol2);
    // tol = δ₀ + (int)(ε·s), in float as the scalar walk computes it.
    const __m128i tol = _mm_add_epi32(v_jitter, _mm_cvttps_epi32(_mm_mul_ps(v_precision, _mm_cvtepi32_ps(s1))));
    const __m128i twice = _mm_add_epi32(s1, s1);
    const __m128i hi = _mm_add_epi32(twice, tol);
    // L_a: running maximum of the lower bounds of the examined entries (those with the polarity).
    __m128i lo = _mm_blendv_epi8(v_lowest, _mm_sub_epi32(twice, tol), pol1);
    lo = _mm_max_epi32(lo, _mm_alignr_epi8(lo, v_lowest, 12));
    lo = _mm_max_epi32(lo, _mm_alignr_epi8(lo, v_lowest, 8));
    // none: no entry of p − 2d in [L_a, hi_a].
    __m128i b = _mm_shuffle_epi32(s2, 0x00);
    __m128i none = _mm_or_si128(_mm_cmpgt_epi32(lo, b), _mm_cmpgt_epi32(b, hi));
    b = _mm_shuffle_epi32(s2, 0x55);
    none = _mm_and_si128(none, _mm_or_si128(_mm_cmpgt_epi32(lo, b), _mm_cmpgt_epi32(b, hi)));
    b = _mm_shuffle_epi32(s2, 0xAA);
    none = _mm_and_si128(none, _mm_or_si128(_mm_cmpgt_epi32(lo, b), _mm_cmpgt_epi32(b, hi)));
    b = _mm_shuffle_epi32(s2, 0xFF);
    none = _mm_and_si128(none, _mm_or_si128(_mm_cmpgt_epi32(lo, b), _mm_cmpgt_epi32(b, hi)));
    const __m128i valid = _mm_andnot_si128(_mm_or_si128(none, _mm_cmpeq_epi32(s1, v_past_window)), pol1);
    __m128i m = _mm_blendv_epi8(v_highest, s1, valid);  // ages ascend: the first match is the smallest
    m = _mm_min_epi32(m, _mm_shuffle_epi32(m, 0x4E));
    m = _mm_min_epi32(m, _mm_shuffle_epi32(m, 0xB1));  // in every lane
    const std::int32_t age = _mm_cvtsi128_si32(m);
    found[n] = age;
    n += age != kNoMatch ? 1 : 0;
    count_lo = _mm_sub_epi32(count_lo, _mm_cmpgt_epi32(u_lo1, m));
    count_hi = _mm_sub_epi32(count_hi, _mm_cmpgt_epi32(u_hi1, m));
    const __m128i decided = _mm_or_si128(_mm_cmpgt_epi32(count_lo, need_lo), _mm_cmpgt_epi32(count_hi, need_hi));
    if (_mm_movemask_epi8(decided) != 0) break;
  }
  return n;
}

/// Per-lane constants of the AVX2 edge-line kernel.
struct LineConstsAvx2 {
  __m256i now, pol, one, past_window, jitter, lowest, highest;
  __m256 precision;
};

/// Directions i (low half) and i + 1 (high half) of match_ages_sse4's per-direction work: each half holds its
/// direction's smallest matched age (kNoMatch when none) in every lane.
__attribute__((target("avx2"), always_inline)) inline __m256i pair_ages_avx2(const LineArgs& a, const LineConstsAvx2& k,
                                                                             std::size_t i) noexcept {
  const std::int64_t off0 = kDy[i] * a.stride + kDx[i];
  const std::int64_t off1 = kDy[i + 1] * a.stride + kDx[i + 1];
  const auto* ring = a.ring;
  const __m256i r1 = _mm256_set_m128i(_mm_loadu_si128(reinterpret_cast<const __m128i*>(ring + (a.centre - off1) * 4)),
                                      _mm_loadu_si128(reinterpret_cast<const __m128i*>(ring + (a.centre - off0) * 4)));
  const __m256i r2 =
      _mm256_set_m128i(_mm_loadu_si128(reinterpret_cast<const __m128i*>(ring + (a.centre - 2 * off1) * 4)),
                       _mm_loadu_si128(reinterpret_cast<const __m128i*>(ring + (a.centre - 2 * off0) * 4)));
  const __m256i s1 = _mm256_min_epi32(_mm256_sub_epi32(k.now, _mm256_srai_epi32(r1, 1)), k.past_window);
  const __m256i pol1 = _mm256_cmpeq_epi32(_mm256_and_si256(r1, k.one), k.pol);
  const __m256i pol2 = _mm256_cmpeq_epi32(_mm256_and_si256(r2, k.one), k.pol);
  const __m256i s2 = _mm256_blendv_epi8(k.highest, _mm256_sub_epi32(k.now, _mm256_srai_epi32(r2, 1)), pol2);
  const __m256i tol =
      _mm256_add_epi32(k.jitter, _mm256_cvttps_epi32(_mm256_mul_ps(k.precision, _mm256_cvtepi32_ps(s1))));
  const __m256i twice = _mm256_add_epi32(s1, s1);
  const __m256i hi = _mm256_add_epi32(twice, tol);
  __m256i lo = _mm256_blendv_epi8(k.lowest, _mm256_sub_epi32(twice, tol), pol1);
  lo = _mm256_max_epi32(lo, _mm256_alignr_epi8(lo, k.lowest, 12));  // within each half
  lo = _mm256_max_epi32(lo, _mm256_alignr_epi8(lo, k.lowest, 8));
  __m256i b = _mm256_shuffle_epi32(s2, 0x00);
  __m256i none = _mm256_or_si256(_mm256_cmpgt_epi32(lo, b), _mm256_cmpgt_epi32(b, hi));
  b = _mm256_shuffle_epi32(s2, 0x55);
  none = _mm256_and_si256(none, _mm256_or_si256(_mm256_cmpgt_epi32(lo, b), _mm256_cmpgt_epi32(b, hi)));
  b = _mm256_shuffle_epi32(s2, 0xAA);
  none = _mm256_and_si256(none, _mm256_or_si256(_mm256_cmpgt_epi32(lo, b), _mm256_cmpgt_epi32(b, hi)));
  b = _mm256_shuffle_epi32(s2, 0xFF);
  none = _mm256_and_si256(none, _mm256_or_si256(_mm256_cmpgt_epi32(lo, b), _mm256_cmpgt_epi32(b, hi)));
  const __m256i valid = _mm256_andnot_si256(_mm256_or_si256(none, _mm256_cmpeq_epi32(s1, k.past_window)), pol1);
  __m256i m = _mm256_blendv_epi8(k.highest, s1, valid);
  m = _mm256_min_epi32(m, _mm256_shuffle_epi32(m, 0x4E));
  return _mm256_min_epi32(m, _mm256_shuffle_epi32(m, 0xB1));
}

/// One layer of disjoint compare-exchanges on 8 lanes: each lane meets `partner`'s, the lanes in `high` keep the
/// larger value.
template <int High>
__attribute__((target("avx2"), always_inline)) inline __m256i sort_layer_avx2(__m256i v, __m256i partner) noexcept {
  const __m256i p = _mm256_permutevar8x32_epi32(v, partner);
  return _mm256_blend_epi32(_mm256_min_epi32(v, p), _mm256_max_epi32(v, p), High);
}

/// rank += [a_j < a_i] + [a_j == a_i and j < i] for j = i + K (mod 8), lane by lane.
template <int K>
__attribute__((target("avx2"), always_inline)) inline __m256i rank_step_avx2(__m256i a, __m256i rank) noexcept {
  const __m256i other =
      _mm256_permutevar8x32_epi32(a, _mm256_setr_epi32(K & 7, (1 + K) & 7, (2 + K) & 7, (3 + K) & 7, (4 + K) & 7,
                                                       (5 + K) & 7, (6 + K) & 7, (7 + K) & 7));
  // j = i + K − 8 < i exactly in the lanes i >= 8 − K.
  const __m256i before = _mm256_cmpgt_epi32(_mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7), _mm256_set1_epi32(7 - K));
  const __m256i counts =
      _mm256_or_si256(_mm256_cmpgt_epi32(a, other), _mm256_and_si256(_mm256_cmpeq_epi32(a, other), before));
  return _mm256_sub_epi32(rank, counts);
}

/// count_m += (age <= U_m) (u1: U_m + 1, age in every lane).
__attribute__((target("avx2"), always_inline)) inline __m256i add(__m256i count, __m256i u1, __m256i age) noexcept {
  return _mm256_sub_epi32(count, _mm256_cmpgt_epi32(u1, age));
}

/// 1 when count_m > m − 1 for some m (need_m = m − 1, or never).
__attribute__((target("avx2"), always_inline)) inline unsigned decided_avx2(__m256i count, __m256i need) noexcept {
  return _mm256_movemask_epi8(_mm256_cmpgt_epi32(count, need)) != 0 ? 1U : 0U;
}

/// kCompact[mask]: the lanes set in mask, in order, then the unset ones (a permutation that packs the set lanes).
constexpr std::array<std::array<std::uint8_t, 8>, 256> make_compact() noexcept {
  std::array<std::array<std::uint8_t, 8>, 256> table{};
  for (unsigned mask = 0; mask < 256; ++mask) {
    std::size_t n = 0;
    for (std::uint8_t lane = 0; lane < 8; ++lane)
      if ((mask >> lane & 1U) != 0) table[mask][n++] = lane;
    for (std::uint8_t lane = 0; lane < 8; ++lane)
      if ((mask >> lane & 1U) == 0) table[mask][n++] = lane;
  }
  return table;
}
constexpr std::array<std::array<std::uint8_t, 8>, 256> kCompact = make_compact();

/// The matched ages (kNoMatch markers for none) sorted ascending into past, then zeros; past_n: the matches.
__attribute__((target("avx2"), always_inline)) inline void store_sorted_avx2(__m256i v, __m256i highest,
                                                                             std::int32_t* past, int& past_n) noexcept {
  v = sort_layer_avx2<0xCC>(v, _mm256_setr_epi32(2, 3, 0, 1, 6, 7, 4, 5));
  v = sort_layer_avx2<0xF0>(v, _mm256_setr_epi32(4, 5, 6, 7, 0, 1, 2, 3));
  v = sort_layer_avx2<0xAA>(v, _mm256_setr_epi32(1, 0, 3, 2, 5, 4, 7, 6));
  v = sort_layer_avx2<0x30>(v, _mm256_setr_epi32(0, 1, 4, 5, 2, 3, 6, 7));
  v = sort_layer_avx2<0x50>(v, _mm256_setr_epi32(0, 4, 2, 6, 1, 5, 3, 7));
  v = sort_layer_avx2<0x54>(v, _mm256_setr_epi32(0, 2, 1, 4, 3, 6, 5, 7));
  const __m256i matched = _mm256_cmpgt_epi32(highest, v);  // a prefix of the lanes
  past_n = std::popcount(static_cast<unsigned>(_mm256_movemask_ps(_mm256_castsi256_ps(matched))));
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(past), _mm256_and_si256(v, matched));
}

/// The edge-line test with AVX2 (Significance::edge_lines_scalar's decisions and scores): two directions per
/// register (one per 128-bit half), all 8 thresholds in one register. The first two directions are decided one by
/// one (an event with dense support stops there); otherwise the other six are matched at once and the first
/// direction after which the counts "at least m matched ages <= U_m" decide is found from their running sums, the
/// directions after it dropped (the walk stops there). The matched ages are sorted in a register (sort8's network)
/// and the margin max_m U_m / u_(m) taken over them with the walk's float operations. past: the sorted matches, then
/// zeros; returns the margin.
__attribute__((target("avx2"))) float match_lines_avx2(const LineArgs& a, std::int32_t* past, int& past_n) noexcept {
  LineConstsAvx2 k;  // NOLINT(cppcoreguidelines-pro-type-member-init): every field set below
  k.now = _mm256_set1_epi32(a.now);
  k.pol = _mm256_set1_epi32(a.polarity);
  k.one = _mm256_set1_epi32(1);
  k.past_window = _mm256_set1_epi32(a.line_us[7] + 1);
  k.jitter = _mm256_set1_epi32(a.jitter_us);
  k.precision = _mm256_set1_ps(a.precision);
  k.lowest = _mm256_set1_epi32(std::numeric_limits<std::int32_t>::min());
  k.highest = _mm256_set1_epi32(kNoMatch);
  const __m256i u = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(a.line_us));
  const __m256i u1 = _mm256_add_epi32(u, k.one);
  const __m256i need = _mm256_blendv_epi8(k.highest, _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
                                          _mm256_cmpgt_epi32(u, _mm256_setzero_si256()));
  const __m256i lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  const __m256i m01 = pair_ages_avx2(a, k, 0);
  __m256i count = add(_mm256_setzero_si256(), u1, _mm256_permute2x128_si256(m01, m01, 0x00));
  // Decided by the first one or two directions (dense support): one or two matches, no sorting needed.
  const auto margin = [&a](std::size_t m, std::int32_t age) {
    return static_cast<float>(a.line_us[m]) / static_cast<float>(std::max(age, 1));
  };
  if (_mm256_movemask_epi8(_mm256_cmpgt_epi32(count, need)) != 0) {
    const std::int32_t d0 = _mm256_cvtsi256_si32(m01);  // matched (it decided)
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(past), _mm256_setr_epi32(d0, 0, 0, 0, 0, 0, 0, 0));
    past_n = 1;
    return margin(0, d0);
  }
  count = add(count, u1, _mm256_permute2x128_si256(m01, m01, 0x11));
  if (_mm256_movemask_epi8(_mm256_cmpgt_epi32(count, need)) != 0) {
    const std::int32_t d0 = _mm256_cvtsi256_si32(m01);     // kNoMatch or matched
    const std::int32_t d1 = _mm256_extract_epi32(m01, 4);  // matched (it decided)
    const std::int32_t lo = std::min(d0, d1);
    const std::int32_t hi = std::max(d0, d1);
    const bool two = hi != kNoMatch;
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(past), _mm256_setr_epi32(lo, two ? hi : 0, 0, 0, 0, 0, 0, 0));
    past_n = two ? 2 : 1;
    return std::max(margin(0, lo), two ? margin(1, hi) : 0.0F);
  }
  const __m256i m23 = pair_ages_avx2(a, k, 2);
  const __m256i m45 = pair_ages_avx2(a, k, 4);
  const __m256i m67 = pair_ages_avx2(a, k, 6);
  // Ages in direction order: [d0 d2 d4 d6 | d1 d3 d5 d7], then permuted.
  __m256i ages = _mm256_blend_epi32(_mm256_blend_epi32(_mm256_blend_epi32(m01, m23, 0x22), m45, 0x44), m67, 0x88);
  // Running counts after directions 2..7: bit j − 2 set when decided after direction j.
  const __m256i c2 = add(count, u1, _mm256_permute2x128_si256(m23, m23, 0x00));
  const __m256i c3 = add(c2, u1, _mm256_permute2x128_si256(m23, m23, 0x11));
  const __m256i c4 = add(c3, u1, _mm256_permute2x128_si256(m45, m45, 0x00));
  const __m256i c5 = add(c4, u1, _mm256_permute2x128_si256(m45, m45, 0x11));
  const __m256i c6 = add(c5, u1, _mm256_permute2x128_si256(m67, m67, 0x00));
  const __m256i c7 = add(c6, u1, _mm256_permute2x128_si256(m67, m67, 0x11));
  const unsigned decided = decided_avx2(c2, need) | decided_avx2(c3, need) << 1 | decided_avx2(c4, need) << 2 |
                           decided_avx2(c5, need) << 3 | decided_avx2(c6, need) << 4 | decided_avx2(c7, need) << 5;
  const int last = 2 + std::countr_zero(decided | 1U << 5);  // the last direction examined
  ages = _mm256_permutevar8x32_epi32(ages, _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7));
  ages = _mm256_blendv_epi8(ages, k.highest, _mm256_cmpgt_epi32(lane, _mm256_set1_epi32(last)));
  if (!a.margins && decided == 0) {
    // Rejected, and its exact margin not wanted: the matches in direction order, unsorted (the joint test sorts
    // the few that reach it), then zeros.
    const __m256i matched = _mm256_cmpgt_epi32(k.highest, ages);
    const auto mask = static_cast<unsigned>(_mm256_movemask_ps(_mm256_castsi256_ps(matched)));
    const __m256i order =
        _mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(kCompact[mask].data())));
    const __m256i packed = _mm256_permutevar8x32_epi32(_mm256_and_si256(ages, matched), order);
    past_n = std::popcount(mask);
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(past), packed);
    return 0.0F;
  }
  // The margin from each match's rank (its position in ascending order, ties by direction): max U_rank / max(u, 1),
  // the same terms as over the sorted list, without waiting for the sort.
  __m256i rank = _mm256_setzero_si256();
  rank = rank_step_avx2<1>(ages, rank);
  rank = rank_step_avx2<2>(ages, rank);
  rank = rank_step_avx2<3>(ages, rank);
  rank = rank_step_avx2<4>(ages, rank);
  rank = rank_step_avx2<5>(ages, rank);
  rank = rank_step_avx2<6>(ages, rank);
  rank = rank_step_avx2<7>(ages, rank);
  const __m256i valid = _mm256_cmpgt_epi32(k.highest, ages);
  const __m256 ratio = _mm256_and_ps(_mm256_div_ps(_mm256_cvtepi32_ps(_mm256_permutevar8x32_epi32(u, rank)),
                                                   _mm256_cvtepi32_ps(_mm256_max_epi32(ages, k.one))),
                                     _mm256_castsi256_ps(valid));
  store_sorted_avx2(ages, k.highest, past, past_n);
  __m128 r = _mm_max_ps(_mm256_castps256_ps128(ratio), _mm256_extractf128_ps(ratio, 1));
  r = _mm_max_ps(r, _mm_movehl_ps(r, r));
  r = _mm_max_ss(r, _mm_shuffle_ps(r, r, 0x55));
  return _mm_cvtss_f32(r);
}

/// The look-ahead's future half-lines (Significance::future_lines) with SSE4.1: per direction, every entry pair of
/// p + d and p + 2d at once. The scalar loop stops at the first entry not later than the event (s <= 0); with the
/// rings' times descending (time-ordered input) that is the same as masking those entries, and its last match is
/// the smallest s that matched. Returns each direction's smallest matched s (kNoMatch when none).
__attribute__((target("sse4.1"))) void future_ages_sse4(const LineArgs& a, std::int32_t lookahead_us,
                                                        std::array<std::int32_t, 8>& found) noexcept {
  const __m128i v_then = _mm_set1_epi32(a.now);
  const __m128i v_pol = _mm_set1_epi32(a.polarity);
  const __m128i v_one = _mm_set1_epi32(1);
  const __m128i v_zero = _mm_setzero_si128();
  const __m128i v_lookahead = _mm_set1_epi32(lookahead_us);
  const __m128i v_jitter = _mm_set1_epi32(a.jitter_us);
  const __m128 v_precision = _mm_set1_ps(a.precision);
  const __m128i v_highest = _mm_set1_epi32(kNoMatch);
  for (std::size_t i = 0; i < 8; ++i) {
    const std::int64_t off = kDy[i] * a.stride + kDx[i];
    const __m128i r1 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(a.ring + (a.centre + off) * 4));
    const __m128i r2 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(a.ring + (a.centre + 2 * off) * 4));
    const __m128i s1 = _mm_sub_epi32(_mm_srai_epi32(r1, 1), v_then);
    const __m128i s2 = _mm_sub_epi32(_mm_srai_epi32(r2, 1), v_then);
    // 0 < s <= L with the event's polarity.
    const __m128i ok1 =
        _mm_andnot_si128(_mm_cmpgt_epi32(s1, v_lookahead),
                         _mm_and_si128(_mm_cmpgt_epi32(s1, v_zero), _mm_cmpeq_epi32(_mm_and_si128(r1, v_one), v_pol)));
    const __m128i ok2 =
        _mm_andnot_si128(_mm_cmpgt_epi32(s2, v_lookahead),
                         _mm_and_si128(_mm_cmpgt_epi32(s2, v_zero), _mm_cmpeq_epi32(_mm_and_si128(r2, v_one), v_pol)));
    const __m128i tol = _mm_add_epi32(v_jitter, _mm_cvttps_epi32(_mm_mul_ps(v_precision, _mm_cvtepi32_ps(s1))));
    const __m128i twice = _mm_add_epi32(s1, s1);
    // hit_a: some entry b of p + 2d with ok2_b and |s2_b − 2·s1_a| <= tol_a.
    __m128i hit = _mm_setzero_si128();
    __m128i b = _mm_shuffle_epi32(s2, 0x00);
    hit = _mm_or_si128(hit, _mm_andnot_si128(_mm_cmpgt_epi32(_mm_abs_epi32(_mm_sub_epi32(b, twice)), tol),
                                             _mm_shuffle_epi32(ok2, 0x00)));
    b = _mm_shuffle_epi32(s2, 0x55);
    hit = _mm_or_si128(hit, _mm_andnot_si128(_mm_cmpgt_epi32(_mm_abs_epi32(_mm_sub_epi32(b, twice)), tol),
                                             _mm_shuffle_epi32(ok2, 0x55)));
    b = _mm_shuffle_epi32(s2, 0xAA);
    hit = _mm_or_si128(hit, _mm_andnot_si128(_mm_cmpgt_epi32(_mm_abs_epi32(_mm_sub_epi32(b, twice)), tol),
                                             _mm_shuffle_epi32(ok2, 0xAA)));
    b = _mm_shuffle_epi32(s2, 0xFF);
    hit = _mm_or_si128(hit, _mm_andnot_si128(_mm_cmpgt_epi32(_mm_abs_epi32(_mm_sub_epi32(b, twice)), tol),
                                             _mm_shuffle_epi32(ok2, 0xFF)));
    __m128i m = _mm_blendv_epi8(v_highest, s1, _mm_and_si128(hit, ok1));
    m = _mm_min_epi32(m, _mm_shuffle_epi32(m, 0x4E));
    m = _mm_min_epi32(m, _mm_shuffle_epi32(m, 0xB1));
    found[i] = _mm_cvtsi128_si32(m);
  }
}

/// Significance::joint_may_pass with SSE4.1, branch-free: per direction, p + d's smallest s with the event's
/// polarity, 0 < s <= L and 2s − tol(s) <= L (tol as future_ages_sse4 computes it; kNoMatch when none), in every
/// lane; then per m = 1..16 the count of past ages and candidates <= V_m, against m.
__attribute__((target("sse4.1"))) bool joint_may_pass_sse4(const LineArgs& a, std::int32_t lookahead_us,
                                                           const std::int32_t* joint_us, const std::int32_t* past,
                                                           int past_count) noexcept {
  const __m128i v_then = _mm_set1_epi32(a.now);
  const __m128i v_pol = _mm_set1_epi32(a.polarity);
  const __m128i v_one = _mm_set1_epi32(1);
  const __m128i v_zero = _mm_setzero_si128();
  const __m128i v_lookahead = _mm_set1_epi32(lookahead_us);
  const __m128i v_jitter = _mm_set1_epi32(a.jitter_us);
  const __m128 v_precision = _mm_set1_ps(a.precision);
  const __m128i v_highest = _mm_set1_epi32(kNoMatch);
  // x <= V_m  <=>  V_m + 1 > x (V_m <= T, no overflow); an age counts as max(age, 1), as joint_ratio divides.
  const auto* v = reinterpret_cast<const __m128i*>(joint_us);
  const __m128i v0 = _mm_add_epi32(_mm_loadu_si128(v), v_one);
  const __m128i v1 = _mm_add_epi32(_mm_loadu_si128(v + 1), v_one);
  const __m128i v2 = _mm_add_epi32(_mm_loadu_si128(v + 2), v_one);
  const __m128i v3 = _mm_add_epi32(_mm_loadu_si128(v + 3), v_one);
  __m128i c0 = v_zero;
  __m128i c1 = v_zero;
  __m128i c2 = v_zero;
  __m128i c3 = v_zero;
  const auto count = [&](__m128i x) {  // x in every lane
    c0 = _mm_sub_epi32(c0, _mm_cmpgt_epi32(v0, x));
    c1 = _mm_sub_epi32(c1, _mm_cmpgt_epi32(v1, x));
    c2 = _mm_sub_epi32(c2, _mm_cmpgt_epi32(v2, x));
    c3 = _mm_sub_epi32(c3, _mm_cmpgt_epi32(v3, x));
  };
  for (int k = 0; k < past_count; ++k) count(_mm_set1_epi32(std::max(past[k], 1)));
  for (std::size_t i = 0; i < 8; ++i) {
    const std::int64_t off = kDy[i] * a.stride + kDx[i];
    const __m128i r1 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(a.ring + (a.centre + off) * 4));
    const __m128i s1 = _mm_sub_epi32(_mm_srai_epi32(r1, 1), v_then);
    const __m128i ok1 =
        _mm_andnot_si128(_mm_cmpgt_epi32(s1, v_lookahead),
                         _mm_and_si128(_mm_cmpgt_epi32(s1, v_zero), _mm_cmpeq_epi32(_mm_and_si128(r1, v_one), v_pol)));
    // Where ok1 holds 0 < s <= L, so 2s − tol does not overflow (elsewhere its value is masked).
    const __m128i tol = _mm_add_epi32(v_jitter, _mm_cvttps_epi32(_mm_mul_ps(v_precision, _mm_cvtepi32_ps(s1))));
    const __m128i reach = _mm_sub_epi32(_mm_add_epi32(s1, s1), tol);
    const __m128i ok = _mm_andnot_si128(_mm_cmpgt_epi32(reach, v_lookahead), ok1);
    __m128i m = _mm_blendv_epi8(v_highest, s1, ok);
    m = _mm_min_epi32(m, _mm_shuffle_epi32(m, 0x4E));
    m = _mm_min_epi32(m, _mm_shuffle_epi32(m, 0xB1));
    count(m);
  }
  // count_m > m − 1 for some m.
  const __m128i hit = _mm_or_si128(
      _mm_or_si128(_mm_cmpgt_epi32(c0, _mm_setr_epi32(0, 1, 2, 3)), _mm_cmpgt_epi32(c1, _mm_setr_epi32(4, 5, 6, 7))),
      _mm_or_si128(_mm_cmpgt_epi32(c2, _mm_setr_epi32(8, 9, 10, 11)),
                   _mm_cmpgt_epi32(c3, _mm_setr_epi32(12, 13, 14, 15))));
  return _mm_movemask_epi8(hit) != 0;
}

/// The same with AVX2: two directions per register (one per 128-bit half), the 16 thresholds in two registers.
__attribute__((target("avx2"))) bool joint_may_pass_avx2(const LineArgs& a, std::int32_t lookahead_us,
                                                         const std::int32_t* joint_us, const std::int32_t* past,
                                                         int past_count) noexcept {
  const __m256i v_then = _mm256_set1_epi32(a.now);
  const __m256i v_pol = _mm256_set1_epi32(a.polarity);
  const __m256i v_one = _mm256_set1_epi32(1);
  const __m256i v_zero = _mm256_setzero_si256();
  const __m256i v_lookahead = _mm256_set1_epi32(lookahead_us);
  const __m256i v_jitter = _mm256_set1_epi32(a.jitter_us);
  const __m256 v_precision = _mm256_set1_ps(a.precision);
  const __m256i v_highest = _mm256_set1_epi32(kNoMatch);
  const __m256i v_lo = _mm256_add_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(joint_us)), v_one);
  const __m256i v_hi = _mm256_add_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(joint_us + 8)), v_one);
  __m256i c_lo = v_zero;
  __m256i c_hi = v_zero;
  // c += (x <= V_m), x in every lane (a macro: a lambda would not inherit the target attribute).
#define EVPIPE_COUNT_AVX2(x)                                     \
  do {                                                           \
    const __m256i x_ = (x);                                      \
    c_lo = _mm256_sub_epi32(c_lo, _mm256_cmpgt_epi32(v_lo, x_)); \
    c_hi = _mm256_sub_epi32(c_hi, _mm256_cmpgt_epi32(v_hi, x_)); \
  } while (false)
  // The past ages: the first four without a loop (at most four in most events; a trip count that varies from event
  // to event costs a mispredicted branch), any others one by one. Lanes past past_count never count.
  const __m256i lanes = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
  __m256i p = _mm256_max_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(past)), v_one);
  p = _mm256_blendv_epi8(p, v_highest, _mm256_cmpgt_epi32(lanes, _mm256_set1_epi32(past_count - 1)));
  EVPIPE_COUNT_AVX2(_mm256_permutevar8x32_epi32(p, _mm256_setzero_si256()));
  EVPIPE_COUNT_AVX2(_mm256_permutevar8x32_epi32(p, v_one));
  EVPIPE_COUNT_AVX2(_mm256_permutevar8x32_epi32(p, _mm256_set1_epi32(2)));
  EVPIPE_COUNT_AVX2(_mm256_permutevar8x32_epi32(p, _mm256_set1_epi32(3)));
  for (int k = 4; k < past_count; ++k) EVPIPE_COUNT_AVX2(_mm256_set1_epi32(std::max(past[k], 1)));
  for (std::size_t i = 0; i < 8; i += 2) {
    const std::int64_t off0 = kDy[i] * a.stride + kDx[i];
    const std::int64_t off1 = kDy[i + 1] * a.stride + kDx[i + 1];
    const __m256i r1 =
        _mm256_set_m128i(_mm_loadu_si128(reinterpret_cast<const __m128i*>(a.ring + (a.centre + off1) * 4)),
                         _mm_loadu_si128(reinterpret_cast<const __m128i*>(a.ring + (a.centre + off0) * 4)));
    const __m256i s1 = _mm256_sub_epi32(_mm256_srai_epi32(r1, 1), v_then);
    const __m256i ok1 = _mm256_andnot_si256(
        _mm256_cmpgt_epi32(s1, v_lookahead),
        _mm256_and_si256(_mm256_cmpgt_epi32(s1, v_zero), _mm256_cmpeq_epi32(_mm256_and_si256(r1, v_one), v_pol)));
    const __m256i tol =
        _mm256_add_epi32(v_jitter, _mm256_cvttps_epi32(_mm256_mul_ps(v_precision, _mm256_cvtepi32_ps(s1))));
    const __m256i reach = _mm256_sub_epi32(_mm256_add_epi32(s1, s1), tol);
    const __m256i ok = _mm256_andnot_si256(_mm256_cmpgt_epi32(reach, v_lookahead), ok1);
    __m256i m = _mm256_blendv_epi8(v_highest, s1, ok);
    m = _mm256_min_epi32(m, _mm256_shuffle_epi32(m, 0x4E));
    m = _mm256_min_epi32(m, _mm256_shuffle_epi32(m, 0xB1));    // in every lane of each half
    EVPIPE_COUNT_AVX2(_mm256_permute2x128_si256(m, m, 0x00));  // direction i
    EVPIPE_COUNT_AVX2(_mm256_permute2x128_si256(m, m, 0x11));  // direction i + 1
  }
#undef EVPIPE_COUNT_AVX2
  const __m256i hit = _mm256_or_si256(_mm256_cmpgt_epi32(c_lo, _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)),
                                      _mm256_cmpgt_epi32(c_hi, _mm256_setr_epi32(8, 9, 10, 11, 12, 13, 14, 15)));
  return _mm256_movemask_epi8(hit) != 0;
}

#endif

/// The edge-line kernel for this CPU, or the one EVPIPE_SIGNIFICANCE_KERNEL names (scalar, sse4, avx2; for tests
/// and benchmarks: every kernel gives the same decisions and scores). A kernel the CPU lacks falls back to the next.
std::uint8_t pick_kernel(std::uint8_t scalar, std::uint8_t sse4, std::uint8_t avx2) noexcept {
  std::uint8_t best = scalar;
#if defined(EVPIPE_SIGNIFICANCE_X86)
  __builtin_cpu_init();
  if (__builtin_cpu_supports("sse4.1")) best = sse4;
  if (__builtin_cpu_supports("avx2")) best = avx2;
#endif
  const char* want = std::getenv("EVPIPE_SIGNIFICANCE_KERNEL");
  if (want == nullptr) return best;
  const std::string_view w(want);
  if (w == "scalar") return scalar;
  if (w == "sse4") return best == avx2 ? sse4 : best;
  return best;
}

// The edge-surface test's statistics (Significance::surface_ratio_at).

/// log P(Poisson(mu) >= k), k >= 1.
double log_poisson_tail(double mu, int k) noexcept {
  if (mu <= 0.0) return -std::numeric_limits<double>::infinity();
  // P = e^{−mu}·mu^k / k!·(1 + mu/(k+1) + mu²/((k+1)(k+2)) + ...).
  double sum = 1.0;
  double term = 1.0;
  for (int i = k + 1; i < k + 400; ++i) {
    term *= mu / i;
    sum += term;
    if (term < 1e-12 * sum) break;
  }
  return -mu + k * std::log(mu) - std::lgamma(k + 1.0) + std::log(sum);
}

/// Largest mu with P(Poisson(mu) >= k) <= target and mu <= k − 1 (where the Poisson bound of the slot count holds).
double poisson_mean_quantile(int k, double target) noexcept {
  if (k < 2 || !(target > 0.0)) return 0.0;
  const double log_target = std::log(target);
  double lo = 0.0;
  double hi = k - 1.0;
  if (log_poisson_tail(hi, k) <= log_target) return hi;
  for (int it = 0; it < 80; ++it) {
    const double mid = 0.5 * (lo + hi);
    (log_poisson_tail(mid, k) <= log_target ? lo : hi) = mid;
  }
  return lo;
}

/// Least-squares plane s = a + gx·dx + gy·dy from the sums of n points (dx, dy integers, s in µs); a ridge on the
/// gradient when the points are collinear (then the gradient across their line is 0). False when n < 3.
struct PlaneSums {
  std::int64_t n = 0, sx = 0, sy = 0, sxx = 0, sxy = 0, syy = 0, ss = 0, sxs = 0, sys = 0;
  void add(std::int64_t x, std::int64_t y, std::int64_t s, std::int64_t sign) noexcept {
    n += sign, sx += sign * x, sy += sign * y, sxx += sign * x * x, sxy += sign * x * y, syy += sign * y * y;
    ss += sign * s, sxs += sign * x * s, sys += sign * y * s;
  }
};

bool fit_plane(const PlaneSums& p, double& a, double& gx, double& gy) noexcept {
  if (p.n < 3) return false;
  const auto cn = static_cast<double>(p.n);
  const auto sx = static_cast<double>(p.sx);
  const auto sy = static_cast<double>(p.sy);
  const auto ss = static_cast<double>(p.ss);
  // Centred: the gradient from the 2×2 system, then a.
  const double cxx = static_cast<double>(p.sxx) - sx * sx / cn;
  const double cxy = static_cast<double>(p.sxy) - sx * sy / cn;
  const double cyy = static_cast<double>(p.syy) - sy * sy / cn;
  const double cxs = static_cast<double>(p.sxs) - sx * ss / cn;
  const double cys = static_cast<double>(p.sys) - sy * ss / cn;
  double rxx = cxx;
  double ryy = cyy;
  double det = cxx * cyy - cxy * cxy;
  if (det < 1e-6 * (cxx + cyy) * (cxx + cyy)) {  // collinear: minimum-norm gradient
    const double ridge = 1e-6 * (cxx + cyy) + 1e-12;
    rxx += ridge;
    ryy += ridge;
    det = rxx * ryy - cxy * cxy;
  }
  if (!(det > 0.0)) return false;
  gx = (ryy * cxs - cxy * cys) / det;
  gy = (rxx * cys - cxy * cxs) / det;
  a = (ss - gx * sx - gy * sy) / cn;
  return true;
}

/// The edge-surface test's motion prior from the 5×5 block of kept events around a pixel: the points (dx, dy, s)
/// with s = t_kept − t in [−T, horizon], the event's polarity, own pixel excluded. Point (dx, dy) is bit and index
/// (dy + 2)·8 + dx + 2 of mask and s.
struct KeptBlock {  // NOLINT(cppcoreguidelines-pro-type-member-init): s is read only where mask is set
  PlaneSums sums;
  std::uint64_t mask = 0;
  std::int32_t oldest = 0;         // max |s| over the points (0 when none)
  std::array<std::int32_t, 40> s;  // NOLINT(cppcoreguidelines-pro-type-member-init): read only where mask is set
};

/// One point's test (the reference; scan_kept_avx2 computes the same lane by lane).
inline bool kept_point(std::int32_t v, std::int32_t s, int polarity, std::int32_t window_us,
                       std::int32_t horizon_us) noexcept {
  return (v != kNever) & ((v & 1) == polarity) & (s >= -window_us) & (s <= horizon_us);
}

void scan_kept_scalar(const std::int32_t* centre, std::int64_t stride, std::int32_t then, int polarity,
                      std::int32_t window_us, std::int32_t horizon_us, KeptBlock& out) noexcept {
  for (int dy = -2; dy <= 2; ++dy) {
    const std::int32_t* row = centre + dy * stride;
    for (int dx = -2; dx <= 2; ++dx) {
      const std::int32_t v = row[dx];
      const std::int32_t s = (v >> 1) - then;
      if (!kept_point(v, s, polarity, window_us, horizon_us) || (dx == 0 && dy == 0)) continue;
      const auto i = static_cast<std::size_t>(dy + 2) * 8 + static_cast<std::size_t>(dx + 2);
      out.mask |= std::uint64_t{1} << i;
      out.s[i] = s;
      out.oldest = std::max(out.oldest, std::abs(s));
      out.sums.add(dx, dy, s, 1);
    }
  }
}

#if defined(EVPIPE_SIGNIFICANCE_X86)
/// The same with AVX2: a row of the block per register (5 of 8 lanes; kept_ is padded so that the 3 lanes past the
/// last row's end stay inside it), per-lane sums over the rows, the plane sums from them in 64 bits.
__attribute__((target("avx2"))) void scan_kept_avx2(const std::int32_t* centre, std::int64_t stride, std::int32_t then,
                                                    int polarity, std::int32_t window_us, std::int32_t horizon_us,
                                                    KeptBlock& out) noexcept {
  const __m256i v_never = _mm256_set1_epi32(kNever);
  const __m256i v_one = _mm256_set1_epi32(1);
  const __m256i v_pol = _mm256_set1_epi32(polarity);
  const __m256i v_then = _mm256_set1_epi32(then);
  const __m256i v_oldest = _mm256_set1_epi32(-window_us);
  const __m256i v_horizon = _mm256_set1_epi32(horizon_us);
  const __m256i lanes = _mm256_setr_epi32(-1, -1, -1, -1, -1, 0, 0, 0);
  const __m256i centre_lanes = _mm256_setr_epi32(-1, -1, 0, -1, -1, 0, 0, 0);
  // Per lane (dx): the count, Σ dy, Σ dy², Σ s, Σ dy·s, max |s| of the points.
  __m256i n = _mm256_setzero_si256();
  __m256i ny = n, nyy = n, ss = n, ys = n, oldest = n;
  std::uint64_t mask = 0;
  for (int dy = -2; dy <= 2; ++dy) {
    const __m256i v = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(centre + dy * stride - 2));
    const __m256i s = _mm256_sub_epi32(_mm256_srai_epi32(v, 1), v_then);
    __m256i ok = _mm256_andnot_si256(_mm256_cmpeq_epi32(v, v_never), dy == 0 ? centre_lanes : lanes);
    ok = _mm256_and_si256(ok, _mm256_cmpeq_epi32(_mm256_and_si256(v, v_one), v_pol));
    ok = _mm256_andnot_si256(_mm256_or_si256(_mm256_cmpgt_epi32(v_oldest, s), _mm256_cmpgt_epi32(s, v_horizon)), ok);
    const __m256i sm = _mm256_and_si256(s, ok);
    const __m256i dy_v = _mm256_set1_epi32(dy);
    const __m256i one = _mm256_and_si256(ok, v_one);
    n = _mm256_add_epi32(n, one);
    ny = _mm256_add_epi32(ny, _mm256_mullo_epi32(one, dy_v));
    nyy = _mm256_add_epi32(nyy, _mm256_mullo_epi32(one, _mm256_set1_epi32(dy * dy)));
    ss = _mm256_add_epi32(ss, sm);
    ys = _mm256_add_epi32(ys, _mm256_mullo_epi32(sm, dy_v));
    oldest = _mm256_max_epi32(oldest, _mm256_abs_epi32(sm));
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(out.s.data() + static_cast<std::ptrdiff_t>(dy + 2) * 8), s);
    mask |= static_cast<std::uint64_t>(static_cast<std::uint32_t>(_mm256_movemask_ps(_mm256_castsi256_ps(ok))))
            << ((dy + 2) * 8);
  }
  out.mask = mask;
  if (std::popcount(mask) < 3) {  // no fit: only the count matters
    out.sums.n = std::popcount(mask);
    return;
  }
  // |s| <= max(T, horizon) <= 1e8 µs: the per-lane sums over 5 rows fit 32 bits, the totals are taken in 64.
  std::array<std::int32_t, 8> a_n{}, a_ny{}, a_nyy{}, a_ss{}, a_ys{}, a_old{};
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(a_n.data()), n);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(a_ny.data()), ny);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(a_nyy.data()), nyy);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(a_ss.data()), ss);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(a_ys.data()), ys);
  _mm256_storeu_si256(reinterpret_cast<__m256i*>(a_old.data()), oldest);
  PlaneSums& p = out.sums;
  for (std::size_t l = 0; l < 5; ++l) {
    const std::int64_t dx = static_cast<std::int64_t>(l) - 2;
    p.n += a_n[l], p.sx += dx * a_n[l], p.sy += a_ny[l], p.sxx += dx * dx * a_n[l], p.sxy += dx * a_ny[l];
    p.syy += a_nyy[l], p.ss += a_ss[l], p.sxs += dx * a_ss[l], p.sys += a_ys[l];
    out.oldest = std::max(out.oldest, a_old[l]);
  }
}
#endif
}  // namespace

Significance::Significance(const SensorGeometry& geometry, SignificanceOptions options)
    : geometry_(geometry), options_(options), stride_(geometry.width + 2 * kPad) {
  window_us_ = static_cast<std::int32_t>(std::clamp(1e6 / options_.slowest_speed_px_s, 1.0, 1e8));
  jitter_us_ = static_cast<std::int32_t>(std::clamp<std::int64_t>(options_.timing_jitter_us, 0, 100'000'000));
  precision_ = static_cast<float>(options_.edge_precision_px);
  lookahead_us_ = options_.edge_line
                      ? static_cast<std::int32_t>(std::clamp<std::int64_t>(options_.lookahead_us, 0, 10'000'000))
                      : 0;
  // alpha is split over the tests that run, at least in halves (the causal edge-line test keeps alpha / 2 whether
  // or not the optional recency and look-ahead tests run; with all three, alpha / 3 each). The edge-surface test
  // shares the look-ahead test's part (half each when both run; the whole part in the causal filter), so the
  // edge-line test's thresholds do not depend on it.
  const bool surface = options_.edge_line && options_.surface;
  const int tests = 1 + (options_.recency_max_us > 0 ? 1 : 0) + (lookahead_us_ > 0 || surface ? 1 : 0);
  const double share = options_.alpha / std::max(2, tests);
  const double joint_share = lookahead_us_ > 0 ? (surface ? share / 2 : share) : 0.0;
  surface_alpha_ = surface ? (lookahead_us_ > 0 ? share / 2 : share) : 0.0;
  for (std::size_t k = 0; k < surface_mu_.size(); ++k) {
    surface_mu_[k] = poisson_mean_quantile(static_cast<int>(k), surface_alpha_);
  }
  // Both causal tests' per-m quantiles depend on alpha only: P(Binomial(8, q_m) >= m) = share / 8.
  for (int m = 1; m <= kNeighbours; ++m) {
    quantile_[static_cast<std::size_t>(m - 1)] = binomial_quantile(kNeighbours, m, share / kNeighbours);
  }
  // The joint test's 16 half-lines (8 past, 8 future): P(Binomial(16, q_m) >= m) = joint_share / 16.
  for (int m = 1; m <= 2 * kNeighbours; ++m) {
    joint_quantile_[static_cast<std::size_t>(m - 1)] =
        lookahead_us_ > 0 ? binomial_quantile(2 * kNeighbours, m, joint_share / (2 * kNeighbours)) : 0.0;
  }
  static_assert(kRing == 4, "the vector kernels hold one ring in 4 lanes");
  kernel_ = pick_kernel(kScalar, kSse4, kAvx2);
  check_pixel_budget("significance", geometry, sizeof(std::int32_t) * kRing);
  allocate();
  reset();
}

void Significance::allocate() {
  // The filter's only per-pixel allocation (kRing · 4 bytes per padded pixel).
  ring_.resize(static_cast<std::size_t>(stride_ * (geometry_.height + 2 * kPad) * kRing));
  // kept_: one per padded pixel, and 8 more (never written) that the vector scan of the block's last row may read.
  kept_.resize(options_.edge_line && options_.surface
                   ? static_cast<std::size_t>(stride_ * (geometry_.height + 2 * kPad)) + 8
                   : 0);
}

void Significance::reset() noexcept {
  std::fill(ring_.begin(), ring_.end(), kNever);
  std::fill(kept_.begin(), kept_.end(), kNever);
  started_ = false;
  base_us_ = 0;
  last_t_us_ = 0;
  ordered_ = true;
  rate_measured_ = false;
  start_us_ = 0;
  first_period_end_us_ = 0;
  warmup_events_ = 0;
  zero_support_ = 0;
  short_zero_support_ = 0;
  events_ = 0;
  zero_acc_ = 0.0;
  short_zero_acc_ = 0.0;
  events_acc_ = 0.0;
  time_acc_s_ = 0.0;
  kept_recency_ = 0;
  kept_line_ = 0;
  kept_surface_ = 0;
  score_ = 0.0F;
  set_rate(options_.initial_rate_hz);
}

void Significance::set_rate(double rate_hz) noexcept {
  rate_hz_ = std::max(0.0, rate_hz);
  // Recency: Bonferroni over k = 1..8.
  for (int k = 1; k <= kNeighbours; ++k) {
    const double p = quantile_[static_cast<std::size_t>(k - 1)];
    double a_us = rate_hz_ > 0.0 ? -std::log1p(-p) / rate_hz_ * 1e6 : static_cast<double>(kAgeCap);
    a_us = std::min(a_us, static_cast<double>(std::min<std::int64_t>(kAgeCap, options_.recency_max_us)));
    recency_us_[static_cast<std::size_t>(k - 1)] = static_cast<std::int32_t>(a_us);
  }
  // Edge line: a direction matches within age U with probability p(U) = 1 − exp(−pairs(U)) under noise,
  // pairs(U) = (lambda² / 2)·(jitter·U + precision·U² / 2) (each polarity at lambda / 2). U_m solves
  // p(U_m) = the Binomial(8, ·) quantile for m at alpha / 2 / 8, capped at T.
  const double T = window_us_ * 1e-6;
  const double jitter_s = jitter_us_ * 1e-6;
  const double eps = options_.edge_precision_px;
  for (int m = 1; m <= kNeighbours; ++m) {
    double u_s = 0.0;
    if (options_.edge_line) {
      const double p = quantile_[static_cast<std::size_t>(m - 1)];
      const double pairs = -std::log1p(-p);
      if (rate_hz_ <= 0.0) {
        u_s = T;
      } else {
        const double c = 2.0 * pairs / (rate_hz_ * rate_hz_);  // jitter·U + eps·U²/2 = c
        u_s = eps > 0.0 ? (-jitter_s + std::sqrt(jitter_s * jitter_s + 2.0 * eps * c)) / eps
                        : (jitter_s > 0.0 ? c / jitter_s : T);
        u_s = std::min(u_s, T);
      }
    }
    line_us_[static_cast<std::size_t>(m - 1)] = static_cast<std::int32_t>(u_s * 1e6);
  }
  set_joint_thresholds();
  // Edge-surface test: the largest total slot width W_K (µs) with P(Poisson((λ/2)·W_K) >= K) <= alpha_s.
  for (std::size_t k = 0; k < surface_width_us_.size(); ++k) {
    surface_width_us_[k] = rate_hz_ > 0.0 ? surface_mu_[k] / (0.5 * rate_hz_) * 1e6
                                          : (surface_mu_[k] > 0.0 ? std::numeric_limits<double>::max() : 0.0);
  }
}

void Significance::set_joint_thresholds() noexcept {
  // The same match probability p(V) per half-line as the causal test (a future half-line is the past one mirrored
  // in time: p + d at t + s, p + 2d at t + 2s), 16 independent half-lines (disjoint pixels or disjoint times).
  for (std::size_t m = 0; m < joint_us_.size(); ++m) {
    joint_us_[m] = options_.edge_line && lookahead_us_ > 0
                       ? static_cast<std::int32_t>(line_age_s(joint_quantile_[m], rate_hz_, jitter_us_ * 1e-6,
                                                              options_.edge_precision_px, window_us_ * 1e-6) *
                                                   1e6)
                       : 0;
  }
}

void Significance::update_rate(std::int64_t t_us) noexcept {
  const double pixels = static_cast<double>(geometry_.width) * geometry_.height;
  if (!rate_measured_) {
    // Warm-up: no period has counted zero-support events yet (none can have a neighbour T0 old before count_from).
    // Noise is part of every event, so the whole event rate so far bounds it: at 100+ Hz/px the assumed
    // initial_rate_hz alone would let the first periods' noise through.
    if (t_us < first_period_end_us_) {
      const double span_s = static_cast<double>(t_us - start_us_) * 1e-6;
      const double all = static_cast<double>(warmup_events_ + events_) / (span_s * pixels);
      set_rate(std::max(options_.initial_rate_hz, all));
      period_end_us_ = std::min(t_us + kWarmupProbeUs, first_period_end_us_);
      return;
    }
    rate_measured_ = true;
    period_end_us_ = first_period_end_us_;  // the first measured period: [count_from, count_from + period)
  }
  // Close every period up to t_us (periods without events count as periods without zero-support events).
  const double period_s = static_cast<double>(options_.rate_period_us) * 1e-6;
  const double keep = std::exp(-static_cast<double>(options_.rate_period_us) /
                               static_cast<double>(std::max<std::int64_t>(1, options_.rate_memory_us)));
  while (t_us >= period_end_us_) {
    zero_acc_ = zero_acc_ * keep + static_cast<double>(zero_support_);
    short_zero_acc_ = short_zero_acc_ * keep + static_cast<double>(short_zero_support_);
    events_acc_ = events_acc_ * keep + static_cast<double>(events_);
    time_acc_s_ = time_acc_s_ * keep + period_s;
    zero_support_ = 0;
    short_zero_support_ = 0;
    events_ = 0;
    period_end_us_ += options_.rate_period_us;
    if (t_us - period_end_us_ > options_.rate_memory_us * 20) {  // long silence: forget, restart the periods
      zero_acc_ = 0.0;
      short_zero_acc_ = 0.0;
      events_acc_ = 0.0;
      time_acc_s_ = 0.0;
      period_end_us_ = t_us + options_.rate_period_us;
      return;
    }
  }
  const double r0 = zero_acc_ / (time_acc_s_ * pixels);        // zero-support events per pixel·s (T0)
  const double r1 = short_zero_acc_ / (time_acc_s_ * pixels);  // ... with the shorter T1
  const double all = events_acc_ / (time_acc_s_ * pixels);     // every event, per pixel·s
  set_rate(rate_from_zero_support(r0, r1, all, zero_acc_));
}

double Significance::rate_from_zero_support(double r0, double r1, double all, double zero_count) noexcept {
  // Noise alone: r(T) = lambda·exp(−8·lambda·T) events per pixel·s have no neighbour event younger than T. For r0 =
  // r(T0) below its maximum 1 / (8·T0·e) two rates give it, lambda_1 <= 1 / (8·T0) <= lambda_2 (at or above it:
  // the maximiser 1 / (8·T0)). lambda_2 is possible only when the sensor's whole event rate `all` reaches it (noise
  // is part of it), and then the share at the shorter T1 tells the roots apart: r1 / r0 = exp(8·lambda·(T0 − T1)),
  // lambda_12 = ln(r1 / r0) / (8·(T0 − T1)); the root nearer to it (in ratio) is taken. Below 1 / (8·T0) = 12.5
  // Hz/px of events in all, lambda_1 always (the estimator as it was). "Reaches" allows lambda_2's statistical
  // error, 3 sigma: d(lambda_2) / lambda_2 = (dr0 / r0) / (8·lambda_2·T0 − 1) <= 3 / sqrt(zero_count) there.
  const double c = kNeighbours * kZeroSupportUs * 1e-6;
  if (!(r0 > 0.0)) return 0.0;
  if (r0 * c * std::exp(1.0) >= 1.0) return 1.0 / c;
  // lambda_1 by fixed-point iteration from r0 (increases monotonically to it).
  double small = r0;
  for (int it = 0; it < 200; ++it) {
    const double next = r0 * std::exp(c * small);
    if (std::abs(next - small) <= 1e-9 * next) {
      small = next;
      break;
    }
    small = next;
  }
  const double c1 = kNeighbours * kShortZeroSupportUs * 1e-6;
  if (!(all > 1.0 / c) || !(r1 > r0)) return small;
  const double from_ratio = std::log(r1 / r0) / (c - c1);
  // lambda_2 by the iteration lambda = ln(lambda / r0) / c from a start above 1 / c (a contraction there, slope
  // 1 / (c·lambda) < 1: it moves monotonically to lambda_2 from either side).
  double large = std::max(from_ratio, 2.0 / c);
  for (int it = 0; it < 200; ++it) {
    const double next = std::log(large / r0) / c;
    if (std::abs(next - large) <= 1e-9 * next) {
      large = next;
      break;
    }
    large = next;
  }
  if (!(large <= all * (1.0 + 3.0 / std::sqrt(std::max(zero_count, 1.0))))) return small;
  return std::abs(std::log(from_ratio / large)) < std::abs(std::log(from_ratio / small)) ? large : small;
}

void Significance::rebase(std::int64_t t_us) noexcept {
  const std::int64_t shift = (t_us - base_us_) - kKeepOnRebase;
  for (auto* values : {&ring_, &kept_}) {
    for (auto& v : *values) {
      if (v == kNever) continue;
      const std::int64_t time = static_cast<std::int64_t>(v >> 1) - shift;
      v = time < kNeverTime / 2 ? kNever : static_cast<std::int32_t>(time * 2 + (v & 1));
    }
  }
  base_us_ += shift;
}

float Significance::edge_lines_scalar(std::size_t centre, std::int32_t now, int polarity) noexcept {
  const std::int32_t window = line_us_[7];
  std::array<std::int32_t, 8> sorted{};  // matched ages so far, ascending
  int n = 0;
  float ratio = 0.0F;
  for (std::size_t i = 0; i < 8; ++i) {
    const std::int64_t off = kDy[i] * stride_ + kDx[i];
    const std::int32_t* r1 = ring_.data() + (static_cast<std::int64_t>(centre) - off) * kRing;
    const std::int32_t* r2 = ring_.data() + (static_cast<std::int64_t>(centre) - 2 * off) * kRing;
    // Two pointers: the window [(2 − ε)s − δ₀, (2 + ε)s + δ₀] only moves later as s grows (entries newest first),
    // so r2 is walked once per direction: at most 2·kRing steps.
    std::int32_t found = kAgeCap;
    int b = 0;
    for (int a = 0; a < kRing && b < kRing; ++a) {
      const std::int32_t v1 = r1[a];
      const std::int32_t s1 = now - (v1 >> 1);
      if (s1 > window) break;  // newest first: the rest is older
      if ((v1 & 1) != polarity) continue;
      const std::int32_t tol = jitter_us_ + static_cast<std::int32_t>(precision_ * static_cast<float>(s1));
      const std::int32_t lo = 2 * s1 - tol;
      const std::int32_t hi = 2 * s1 + tol;
      while (b < kRing && now - (r2[b] >> 1) < lo) ++b;
      for (int j = b; j < kRing; ++j) {
        const std::int32_t v2 = r2[j];
        if (now - (v2 >> 1) > hi) break;
        if ((v2 & 1) == polarity) {
          found = s1;
          break;
        }
      }
      if (found != kAgeCap) break;
    }
    if (found == kAgeCap) continue;
    // Insert, then test u_(m) <= U_m over the matches so far: once it holds for some m it holds for the full
    // sorted list too (its m-th smallest can only be smaller), so the decision is final.
    int j = n++;
    for (; j > 0 && sorted[static_cast<std::size_t>(j - 1)] > found; --j) {
      sorted[static_cast<std::size_t>(j)] = sorted[static_cast<std::size_t>(j - 1)];
    }
    sorted[static_cast<std::size_t>(j)] = found;
    bool decided = false;
    for (int m = 0; m < n; ++m) {
      const auto mu = static_cast<std::size_t>(m);
      decided |= line_us_[mu] > 0 && sorted[mu] <= line_us_[mu];  // the same as the ratio below reaching 1
    }
    if (decided) break;
  }
  past_ages_ = sorted;  // all the past matches when not decided (the look-ahead joins them with the future ones)
  past_n_ = n;
  for (int m = 0; m < n; ++m) {
    const auto mu = static_cast<std::size_t>(m);
    ratio = std::max(ratio, static_cast<float>(line_us_[mu]) / static_cast<float>(std::max(sorted[mu], 1)));
  }
  return ratio;
}

float Significance::edge_lines(std::size_t centre, std::int32_t now, int polarity) noexcept {
  if (kernel_ == kScalar || !ordered_) return edge_lines_scalar(centre, now, polarity);
  std::array<std::int32_t, 9> found;  // NOLINT(cppcoreguidelines-pro-type-member-init): matched ages, found[0..n)
  std::size_t n = 0;
#if defined(EVPIPE_SIGNIFICANCE_X86)
  const LineArgs args{ring_.data(), stride_,    static_cast<std::int64_t>(centre),
                      now,          polarity,   line_us_.data(),
                      jitter_us_,   precision_, options_.exact_scores};
  if (kernel_ == kAvx2) return match_lines_avx2(args, past_ages_.data(), past_n_);
  n = match_ages_sse4(args, found);
#endif
  // The margin max_m U_m / u_(m) over the matches examined, with the scalar walk's float operations; few matches
  // (the common case) need no sorting network.
  const auto margin = [this](std::size_t m, std::int32_t u) {
    return static_cast<float>(line_us_[m]) / static_cast<float>(std::max(u, 1));
  };
  // The look-ahead's past half-lines: the matches ascending, then zeros (as the scalar walk leaves them).
  past_ages_ = {};
  past_n_ = static_cast<int>(n);
  if (n == 0) return 0.0F;
  if (n == 1) {
    past_ages_[0] = found[0];
    return margin(0, found[0]);
  }
  if (n == 2) {
    past_ages_[0] = std::min(found[0], found[1]);
    past_ages_[1] = std::max(found[0], found[1]);
    return std::max(margin(0, past_ages_[0]), margin(1, past_ages_[1]));
  }
  std::array<std::int32_t, 8> sorted{};  // the matches, then no-match markers (sorted last)
  sorted.fill(std::numeric_limits<std::int32_t>::max());
  std::copy_n(found.begin(), n, sorted.begin());
  sort8(sorted);
  std::copy_n(sorted.begin(), n, past_ages_.begin());
  float ratio = 0.0F;
  for (std::size_t m = 0; m < n; ++m) {
    ratio = std::max(ratio, margin(m, sorted[m]));
  }
  return ratio;
}

bool Significance::accept(const Event& e) noexcept {
  if (!geometry_.contains(e.x, e.y)) {
    score_ = 0.0F;
    return false;
  }
  if (!started_) {
    started_ = true;
    base_us_ = e.t_us;
    last_t_us_ = e.t_us;
    start_us_ = e.t_us;
    count_from_us_ = e.t_us + kZeroSupportUs;  // before that no event can have a neighbour T0 old
    first_period_end_us_ = count_from_us_ + options_.rate_period_us;
    period_end_us_ = std::min(e.t_us + kWarmupProbeUs, first_period_end_us_);
  }
  ordered_ = ordered_ && e.t_us >= last_t_us_;
  last_t_us_ = e.t_us;
  if (e.t_us >= period_end_us_) update_rate(e.t_us);
  if (e.t_us - base_us_ >= kRebaseAt) rebase(e.t_us);
  const auto now = static_cast<std::int32_t>(e.t_us - base_us_);
  const auto centre = static_cast<std::size_t>((e.y + kPad) * stride_ + (e.x + kPad));
  const std::int32_t* ring = ring_.data();
  const auto s = static_cast<std::int64_t>(stride_);
  const std::int64_t c = static_cast<std::int64_t>(centre);
  // The 5×5 block's rings (5 rows of 5·kRing·4 bytes): start every cache line now, the tests below read them in
  // an order that jumps between rows.
  for (std::int64_t dy = -2; dy <= 2; ++dy) {
    const char* row = reinterpret_cast<const char*>(ring + (c + dy * s - 2) * kRing);
    __builtin_prefetch(row);
    __builtin_prefetch(row + 5 * kRing * sizeof(std::int32_t) - 1);
  }
  // The 8 neighbours' newest events (entry 0 of their rings); the youngest of them: max of (t − base)·2 + polarity,
  // halved (the shift keeps the order).
  constexpr std::ptrdiff_t kTwoRings = std::ptrdiff_t{2} * kRing;
  const std::int32_t* up = ring + (c - s - 1) * kRing;
  const std::int32_t* mid = ring + (c - 1) * kRing;
  const std::int32_t* down = ring + (c + s - 1) * kRing;
  const std::int32_t youngest =
      std::max(std::max(std::max(up[0], up[kRing]), std::max(up[kTwoRings], mid[0])),
               std::max(std::max(mid[kTwoRings], down[0]), std::max(down[kRing], down[kTwoRings])));
  const std::int32_t newest = std::min(kAgeCap, now - (youngest >> 1));  // the smallest neighbour age
  if (e.t_us >= count_from_us_) {
    zero_support_ += newest > kZeroSupportUs ? 1 : 0;
    short_zero_support_ += newest > kShortZeroSupportUs ? 1 : 0;
    ++events_;
  } else {
    ++warmup_events_;
  }
  float ratio = 0.0F;
  if (options_.recency_max_us > 0) {
    const std::array<std::int64_t, 8> nb = {c - s - 1, c - s, c - s + 1, c - 1, c + 1, c + s - 1, c + s, c + s + 1};
    std::array<std::int32_t, 8> age{};
    for (std::size_t i = 0; i < 8; ++i) age[i] = std::min(kAgeCap, now - (ring[nb[i] * kRing] >> 1));
    sort8(age);
    for (std::size_t k = 0; k < 8; ++k) {
      ratio = std::max(ratio, static_cast<float>(recency_us_[k]) / static_cast<float>(std::max(age[k], 1)));
    }
  }
  bool keep = ratio >= 1.0F;
  float score = ratio;
  past_n_ = 0;
  const int polarity = e.polarity ? 1 : 0;
  if (keep) {
    ++kept_recency_;
  } else if (options_.edge_line && newest <= line_us_[7]) {  // else no direction has an entry within U_8
    const float line = edge_lines(centre, now, polarity);
    score = std::max(score, line);
    keep = line >= 1.0F;
    kept_line_ += keep ? 1 : 0;
  }
  // The edge-surface test, for an event with at least one matched past half-line (an event on an edge surface with
  // kept events around it has one; noise in an edge's wake has none - and gating a test only lowers its false-alarm
  // rate). Causal: now; with the look-ahead: at t + L, after the joint test (SignificanceFilter::decide_before).
  if (!keep && lookahead_us_ == 0 && !kept_.empty() && past_n_ > 0) {
    const float surface = surface_ratio_at(centre, now, polarity, 0);
    score = std::max(score, surface);
    keep = surface >= 1.0F;
    kept_surface_ += keep ? 1 : 0;
  }
  if (keep && !kept_.empty()) kept_[centre] = std::max(kept_[centre], now * 2 + polarity);
  score_ = keep || options_.exact_scores ? score : 0.0F;  // every kernel alike (LineArgs::margins)
  // Stamp the event into its pixel's ring (newest first), kept or not.
  std::int32_t* own = ring_.data() + centre * kRing;
#if defined(EVPIPE_SIGNIFICANCE_X86)
  const __m128i older = _mm_slli_si128(_mm_loadu_si128(reinterpret_cast<const __m128i*>(own)), 4);
  _mm_storeu_si128(reinterpret_cast<__m128i*>(own), _mm_or_si128(older, _mm_cvtsi32_si128(now * 2 + polarity)));
#else
  std::copy_backward(own, own + kRing - 1, own + kRing);
  own[0] = now * 2 + polarity;
#endif
  return keep;
}

void Significance::prefetch_block(const Event& e) const noexcept {
  if (!geometry_.contains(e.x, e.y)) return;
  const std::int64_t c = (e.y + kPad) * stride_ + (e.x + kPad);
  for (std::int64_t dy = -1; dy <= 1; ++dy) {  // the 3×3 block (p + d); p + 2d is read only after a match
    const char* row = reinterpret_cast<const char*>(ring_.data() + (c + dy * stride_ - 1) * kRing);
    __builtin_prefetch(row);
    __builtin_prefetch(row + std::size_t{3} * kRing * sizeof(std::int32_t) - 1);
  }
  if (!kept_.empty()) {  // the edge-surface test's kept events (5×5 block: 5 rows of 20 bytes, 32 read)
    for (std::int64_t dy = -2; dy <= 2; ++dy) {
      const char* row = reinterpret_cast<const char*>(kept_.data() + c + dy * stride_ - 2);
      __builtin_prefetch(row);
      __builtin_prefetch(row + 8 * sizeof(std::int32_t) - 1);  // the vector scan reads 8
    }
  }
}

int Significance::future_lines(std::size_t centre, std::int32_t then, int polarity,
                               std::array<std::int32_t, 8>& ages) const noexcept {
  // Direction d: p + d fired at then + s and p + 2d at then + s2 with |s2 − 2s| <= δ₀ + ε·s, both of the event's
  // polarity, 0 < s, s2 <= L (the rings hold nothing later than then + L when this runs). Smallest such s.
  static constexpr std::array<std::int8_t, 8> kDx = {-1, 0, 1, -1, 1, -1, 0, 1};
  static constexpr std::array<std::int8_t, 8> kDy = {-1, -1, -1, 0, 0, 1, 1, 1};
  int n = 0;
#if defined(EVPIPE_SIGNIFICANCE_X86)
  if (kernel_ != kScalar && ordered_) {
    std::array<std::int32_t, 8> found{};
    const LineArgs args{ring_.data(), stride_,   static_cast<std::int64_t>(centre), then, polarity, line_us_.data(),
                        jitter_us_,   precision_};
    future_ages_sse4(args, lookahead_us_, found);
    for (const std::int32_t f : found) {
      if (f == std::numeric_limits<std::int32_t>::max()) continue;
      int j = n++;
      for (; j > 0 && ages[static_cast<std::size_t>(j - 1)] > f; --j) {
        ages[static_cast<std::size_t>(j)] = ages[static_cast<std::size_t>(j - 1)];
      }
      ages[static_cast<std::size_t>(j)] = f;
    }
    return n;
  }
#endif
  for (std::size_t i = 0; i < 8; ++i) {
    const std::int64_t off = kDy[i] * stride_ + kDx[i];
    const std::int32_t* r1 = ring_.data() + (static_cast<std::int64_t>(centre) + off) * kRing;
    const std::int32_t* r2 = ring_.data() + (static_cast<std::int64_t>(centre) + 2 * off) * kRing;
    std::int32_t found = kAgeCap;
    for (int a = 0; a < kRing; ++a) {  // newest first: s decreases
      const std::int32_t v1 = r1[a];
      const std::int32_t s1 = (v1 >> 1) - then;
      if (s1 <= 0) break;
      if (s1 > lookahead_us_ || (v1 & 1) != polarity) continue;
      const std::int32_t tol = jitter_us_ + static_cast<std::int32_t>(precision_ * static_cast<float>(s1));
      for (int b = 0; b < kRing; ++b) {
        const std::int32_t v2 = r2[b];
        const std::int32_t s2 = (v2 >> 1) - then;
        if (s2 <= 0) break;
        if (s2 <= lookahead_us_ && (v2 & 1) == polarity && std::abs(s2 - 2 * s1) <= tol) {
          found = s1;
          break;
        }
      }
    }
    if (found == kAgeCap) continue;
    int j = n++;
    for (; j > 0 && ages[static_cast<std::size_t>(j - 1)] > found; --j) {
      ages[static_cast<std::size_t>(j)] = ages[static_cast<std::size_t>(j - 1)];
    }
    ages[static_cast<std::size_t>(j)] = found;
  }
  return n;
}

float Significance::joint_ratio(const Event& e, const std::int32_t* past_ages, int past_count) const noexcept {
  if (lookahead_us_ <= 0 || !options_.edge_line || !geometry_.contains(e.x, e.y)) return 0.0F;
  const auto centre = static_cast<std::size_t>((e.y + kPad) * stride_ + (e.x + kPad));
  std::array<std::int32_t, 8> future{};
  const int nf = future_lines(centre, static_cast<std::int32_t>(e.t_us - base_us_), e.polarity ? 1 : 0, future);
  // The past ages ascending (they are unless exact_scores is false: match_lines_avx2 then leaves a rejected event's
  // matches in direction order); insertion sort, no move when sorted.
  std::array<std::int32_t, 8> past{};
  const auto np = static_cast<std::size_t>(std::clamp(past_count, 0, 8));
  std::copy_n(past_ages, np, past.begin());
  for (std::size_t i = 1; i < np; ++i) {
    const std::int32_t x = past[i];
    std::size_t j = i;
    for (; j > 0 && past[j - 1] > x; --j) past[j] = past[j - 1];
    past[j] = x;
  }
  // Merge the two ascending lists; the ratio max_m V_m / w_(m) over the merged ages.
  float ratio = 0.0F;
  std::size_t i = 0;
  std::size_t j = 0;
  const auto n_future = static_cast<std::size_t>(nf);
  for (std::size_t m = 0; i < np || j < n_future; ++m) {
    const bool take_past = j >= n_future || (i < np && past[i] <= future[j]);
    const std::int32_t w = take_past ? past[i++] : future[j++];
    ratio = std::max(ratio, static_cast<float>(joint_us_[m]) / static_cast<float>(std::max(w, 1)));
  }
  return ratio;
}

bool Significance::joint_may_pass(const Event& e, const std::int32_t* past_ages, int past_count) const noexcept {
  if (lookahead_us_ <= 0 || !options_.edge_line || !geometry_.contains(e.x, e.y)) return false;  // joint_ratio: 0
  const auto centre = static_cast<std::int64_t>((e.y + kPad) * stride_ + (e.x + kPad));
  const auto then = static_cast<std::int32_t>(e.t_us - base_us_);
  const int polarity = e.polarity ? 1 : 0;
#if defined(EVPIPE_SIGNIFICANCE_X86)
  if (kernel_ != kScalar) {
    const LineArgs args{ring_.data(), stride_, centre, then, polarity, line_us_.data(), jitter_us_, precision_};
    return kernel_ == kAvx2 ? joint_may_pass_avx2(args, lookahead_us_, joint_us_.data(), past_ages, past_count)
                            : joint_may_pass_sse4(args, lookahead_us_, joint_us_.data(), past_ages, past_count);
  }
#endif
  // The same count, one entry at a time (a superset of what future_lines examines on any input order).
  std::array<int, 16> count{};
  const auto add = [&](std::int32_t x) {
    for (std::size_t m = 0; m < count.size(); ++m) count[m] += std::max(x, 1) <= joint_us_[m] ? 1 : 0;
  };
  for (int k = 0; k < past_count; ++k) add(past_ages[k]);
  for (std::size_t i = 0; i < 8; ++i) {
    const std::int64_t off = kDy[i] * stride_ + kDx[i];
    const std::int32_t* r1 = ring_.data() + (centre + off) * kRing;
    std::int32_t best = kAgeCap;
    for (int a = 0; a < kRing; ++a) {
      const std::int32_t s1 = (r1[a] >> 1) - then;
      if (s1 <= 0 || s1 > lookahead_us_ || (r1[a] & 1) != polarity) continue;
      const std::int32_t tol = jitter_us_ + static_cast<std::int32_t>(precision_ * static_cast<float>(s1));
      if (2 * s1 - tol <= lookahead_us_) best = std::min(best, s1);
    }
    if (best != kAgeCap) add(best);
  }
  for (std::size_t m = 0; m < count.size(); ++m) {
    if (count[m] >= static_cast<int>(m) + 1) return true;
  }
  return false;
}

// ---- Edge-surface test (slow edges; docs/algorithms.md, "Edge-surface test") ----

void Significance::mark_kept(const Event& e) noexcept {
  if (kept_.empty() || !geometry_.contains(e.x, e.y)) return;
  const auto centre = static_cast<std::size_t>((e.y + kPad) * stride_ + (e.x + kPad));
  const auto v = static_cast<std::int32_t>((e.t_us - base_us_) * 2 + (e.polarity ? 1 : 0));
  kept_[centre] = std::max(kept_[centre], v);
}

float Significance::surface_ratio(const Event& e, std::int32_t horizon_us) const noexcept {
  if (kept_.empty() || !geometry_.contains(e.x, e.y)) return 0.0F;
  const auto centre = static_cast<std::size_t>((e.y + kPad) * stride_ + (e.x + kPad));
  return surface_ratio_at(centre, static_cast<std::int32_t>(e.t_us - base_us_), e.polarity ? 1 : 0, horizon_us);
}

float Significance::surface_ratio_at(std::size_t centre, std::int32_t then, int polarity,
                                     std::int32_t horizon_us) const noexcept {
  // The motion prior: the kept events of the 5×5 block (own pixel excluded) of the event's polarity within
  // [t − T, t + horizon]; their plane s(q) = a + g·q (s relative to t, µs) gives the local normal flow. The scan
  // gives their integer plane sums (order-free: every kernel the same fit), a bit per point and their times.
  KeptBlock block;
#if defined(EVPIPE_SIGNIFICANCE_X86)
  if (kernel_ == kAvx2) {
    scan_kept_avx2(kept_.data() + centre, stride_, then, polarity, window_us_, horizon_us, block);
  } else {
    scan_kept_scalar(kept_.data() + centre, stride_, then, polarity, window_us_, horizon_us, block);
  }
#else
  scan_kept_scalar(kept_.data() + centre, stride_, then, polarity, window_us_, horizon_us, block);
#endif
  const PlaneSums& sums = block.sums;
  if (sums.n < 3) return 0.0F;
  const auto c = static_cast<std::int64_t>(centre);
  double a = 0.0;
  double gx = 0.0;
  double gy = 0.0;
  if (!fit_plane(sums, a, gx, gy)) return 0.0F;
  // The kept events fill their own slots only if the event is on their plane: the plane's time at p, a, within
  // the widest tolerance among them. Otherwise their slots are empty (K comes from other events alone), which the
  // test would not keep with fewer slots than kept points; skipped without reading the rings.
  const double eps = options_.edge_precision_px;
  if (std::abs(a) > jitter_us_ + eps * block.oldest) return 0.0F;
  // Once more without the points off the plane by more than the edge tolerance δ(|g·q|) (a kept noise event,
  // another crossing), if three remain.
  PlaneSums inliers = sums;
  for (std::uint64_t bits = block.mask; bits != 0; bits &= bits - 1) {
    const auto i = static_cast<std::size_t>(__builtin_ctzll(bits));
    const int dx = static_cast<int>(i % 8) - 2;
    const int dy = static_cast<int>(i / 8) - 2;
    const double tau = gx * dx + gy * dy;
    const std::int32_t si = block.s[i];
    if (std::abs(si - a - tau) > jitter_us_ + eps * std::abs(tau)) inliers.add(dx, dy, si, -1);
  }
  if (inliers.n < sums.n && inliers.n >= 3) {
    double a2 = 0.0;
    double gx2 = 0.0;
    double gy2 = 0.0;
    if (fit_plane(inliers, a2, gx2, gy2)) gx = gx2, gy = gy2;
  }
  // Slots: if the event lies on that surface, p + q fires at t + τ_q, τ_q = g·q, within δ(|τ_q|) = δ₀ + ε|τ_q|,
  // with its polarity. Under BA a slot holds such an event by chance with probability <= (λ/2)·w_q (w_q its
  // window inside [t − T, t + horizon]); the count K of filled slots is then bounded by Poisson((λ/2)·Σ w_q).
  const double cap = 4.0 * window_us_;  // |τ| beyond T: no slot (and no int overflow)
  std::int64_t width_us = 0;
  int k = 0;
  for (int dy = -2; dy <= 2; ++dy) {
    for (int dx = -2; dx <= 2; ++dx) {
      if (dx == 0 && dy == 0) continue;
      const double tau_d = gx * dx + gy * dy;
      if (!(std::abs(tau_d) <= cap)) continue;
      const auto tau = static_cast<std::int32_t>(std::floor(tau_d + 0.5));
      const std::int32_t tol = jitter_us_ + static_cast<std::int32_t>(precision_ * static_cast<float>(std::abs(tau)));
      const std::int32_t lo = std::max(tau - tol, -window_us_);
      const std::int32_t hi = std::min(tau + tol, horizon_us);
      if (hi <= lo) continue;
      width_us += hi - lo;
      const std::int32_t* r = ring_.data() + (c + dy * stride_ + dx) * kRing;
      bool filled = false;
      for (int j = 0; j < kRing; ++j) {
        const std::int32_t v = r[j];
        const std::int32_t s = (v >> 1) - then;
        filled |= v != kNever && (v & 1) == polarity && s >= lo && s <= hi;
      }
      k += filled ? 1 : 0;
    }
  }
  // Kept when P(Poisson((λ/2)·W) >= K) <= alpha_s, i.e. W <= W_K (set_rate); the margin W_K / W.
  const double most = surface_width_us_[static_cast<std::size_t>(k)];
  if (!(most > 0.0)) return 0.0F;
  return static_cast<float>(std::min(most / static_cast<double>(std::max<std::int64_t>(width_us, 1)),
                                     static_cast<double>(std::numeric_limits<float>::max())));
}

namespace {

/// Look-ahead driver: every event enters a FIFO (one slot, reused: a ring that only grows, to the events of one
/// look-ahead span); an event the causal tests reject is decided once the first event later than t + L arrives
/// (or at finish), with Significance::joint_ratio; decided events leave the FIFO's front in input order.
class SignificanceFilter final : public Filter {
 public:
  SignificanceFilter(const SensorGeometry& geometry, const SignificanceOptions& options)
      : impl_(geometry, options), lookahead_us_(options.lookahead_us), exact_scores_(options.exact_scores) {}

  [[nodiscard]] std::string_view name() const noexcept override { return "significance"; }
  void push(EventSpan events, Decisions& out) override {
    out.keep.reserve(out.keep.size() + size_ + events.size());
    out.score.reserve(out.score.size() + size_ + events.size());
    for (std::size_t i = 0; i < events.size(); ++i) {
      const Event& e = events[i];
      decide_before(e.t_us - lookahead_us_);
      if ((i & (kReleaseEvery - 1)) == 0) release(out);  // decided events leave in input order, a block at a time
      const bool keep = impl_.accept(e);
      const float score = impl_.last_score();
      if (size_ == 0 && keep) {  // nothing waits: out at once
        out.keep.push_back(1);
        out.score.push_back(score);
        continue;
      }
      Entry& slot = append();
      slot.event = e;
      slot.score = score;
      slot.state = keep ? kKeep : kPending;
      slot.past_n = static_cast<std::uint8_t>(keep ? 0 : impl_.past_line_count());
      if (!keep) slot.past = impl_.past_line_ages_us();
    }
    release(out);
  }
  void finish(Decisions& out) override {
    decide_before(std::numeric_limits<std::int64_t>::max());
    release(out);
  }
  void reset() override {
    impl_.reset();
    head_ = size_ = next_ = 0;
  }
  [[nodiscard]] std::size_t pending() const noexcept override { return size_; }
  [[nodiscard]] std::int64_t latency_us() const noexcept override { return lookahead_us_; }
  [[nodiscard]] bool has_score() const noexcept override { return true; }
  [[nodiscard]] std::vector<ReportItem> report() const override {
    auto r = impl_.report();
    r.push_back({"kept_lookahead", static_cast<double>(kept_joint_)});
    if (!exact_scores_) r.push_back({"lookahead_bound_drops", static_cast<double>(bound_drops_)});
    return r;
  }

 private:
  static constexpr std::size_t kPrefetchAhead = 4;
  static constexpr std::size_t kReleaseEvery = 256;
  static constexpr std::uint8_t kPending = 0;
  static constexpr std::uint8_t kKeep = 1;
  static constexpr std::uint8_t kDrop = 2;
  struct Entry {
    Event event;
    float score = 0.0F;
    std::uint8_t state = kPending;
    std::uint8_t past_n = 0;
    std::array<std::int32_t, 8> past{};
  };

  Entry& at(std::size_t i) noexcept { return fifo_[(head_ + i) & mask_]; }
  Entry& append() {
    if (size_ == fifo_.size()) {  // grow (power of two), unrolling the ring
      std::vector<Entry> bigger(std::max<std::size_t>(1024, 2 * fifo_.size()));
      for (std::size_t i = 0; i < size_; ++i) bigger[i] = at(i);
      fifo_.swap(bigger);
      mask_ = fifo_.size() - 1;
      head_ = 0;
    }
    return at(size_++);
  }
  /// Decides every waiting event with t_us < `bound` (= the new event's time − L): the rings then hold exactly the
  /// events up to its t + L.
  void decide_before(std::int64_t bound) noexcept {
    for (; next_ < size_; ++next_) {
      Entry& x = at(next_);
      if (x.event.t_us >= bound) break;
      // The rings it reads were last touched up to L ago: start fetching those of the events decided next.
      if (next_ + kPrefetchAhead < size_) impl_.prefetch_block(at(next_ + kPrefetchAhead).event);
      if (x.state != kPending) continue;
      if (!exact_scores_ && !impl_.joint_may_pass(x.event, x.past.data(), x.past_n)) {
        x.state = kDrop;  // joint_ratio < 1 for certain: the same decision (the score stays the causal one)
        ++bound_drops_;
        if (x.past_n > 0) decide_surface(x);  // the edge-surface test still gets its say
        if (x.state == kKeep) impl_.mark_kept(x.event);
        continue;
      }
      const float joint = impl_.joint_ratio(x.event, x.past.data(), x.past_n);
      x.score = std::max(x.score, joint);
      x.state = joint >= 1.0F ? kKeep : kDrop;
      kept_joint_ += joint >= 1.0F ? 1 : 0;
      if (x.state == kDrop && x.past_n > 0) decide_surface(x);  // (the gate: Significance::accept)
      if (x.state == kKeep) impl_.mark_kept(x.event);
    }
  }
  /// The edge-surface test of a waiting event the joint test rejected (the rings and kept events up to t + L).
  void decide_surface(Entry& x) noexcept {
    const float surface = impl_.surface_ratio(x.event, static_cast<std::int32_t>(lookahead_us_));
    x.score = std::max(x.score, surface);
    if (surface < 1.0F) return;
    x.state = kKeep;
    impl_.count_kept_surface();
  }
  void release(Decisions& out) {
    while (size_ > 0) {
      const Entry& x = at(0);
      if (x.state == kPending) break;
      out.keep.push_back(x.state == kKeep ? 1 : 0);
      out.score.push_back(x.score);
      head_ = (head_ + 1) & mask_;
      --size_;
      next_ = next_ > 0 ? next_ - 1 : 0;
    }
  }

  Significance impl_;
  std::int64_t lookahead_us_;
  bool exact_scores_;
  std::vector<Entry> fifo_;
  std::size_t mask_ = 0;  // fifo_.size() − 1
  std::size_t head_ = 0;
  std::size_t size_ = 0;
  std::size_t next_ = 0;  // first entry not examined by decide_before
  std::uint64_t kept_joint_ = 0;
  std::uint64_t bound_drops_ = 0;  // pending events the bound dropped (exact_scores = false)
};

}  // namespace

std::unique_ptr<Filter> make_significance(const SensorGeometry& geometry, const SignificanceOptions& options) {
  if (options.lookahead_us > 0 && options.edge_line) return std::make_unique<SignificanceFilter>(geometry, options);
  return std::make_unique<PerEventFilter<Significance>>("significance", geometry, options);
}

std::vector<ReportItem> Significance::report() const {
  return {{"noise_rate_hz", rate_hz_},
          {"kept_recency", static_cast<double>(kept_recency_)},
          {"kept_edge_line", static_cast<double>(kept_line_)},
          {"kept_surface", static_cast<double>(kept_surface_)},
          {"line_window_us", static_cast<double>(line_us_[7])}};
}

FilterSpec significance_spec() {
  return {"significance",
          "keeps events whose support is improbable under the estimated BA rate (false-alarm rate alpha); look-ahead "
          "lookahead_us (0: causal)",
          [](Params& p, const SensorGeometry& g) -> std::unique_ptr<Filter> {
            SignificanceOptions o;
            o.alpha = p.real("alpha", o.alpha, "false-alarm rate: share of background-activity events kept");
            p.require_range("alpha", o.alpha, 0.0, 0.5, true, false);
            o.slowest_speed_px_s = p.real("slowest_speed_px_s", o.slowest_speed_px_s,
                                          "slowest edge speed the edge-line test looks for (window = 1 / it)");
            p.require_range("slowest_speed_px_s", o.slowest_speed_px_s, 0.01, 1e6);
            o.edge_precision_px = p.real("edge_precision_px", o.edge_precision_px,
                                         "edge position precision in pixels (crossing-time tolerance = it / speed)");
            p.require_range("edge_precision_px", o.edge_precision_px, 0.0, 1.0);
            o.timing_jitter_us =
                p.integer("timing_jitter_us", o.timing_jitter_us, "timestamp jitter between neighbouring pixels (us)");
            p.require_range("timing_jitter_us", static_cast<double>(o.timing_jitter_us), 0.0, 1e6);
            o.rate_period_us =
                p.integer("rate_period_us", o.rate_period_us, "background-activity rate update period (us)");
            p.require_positive("rate_period_us", static_cast<double>(o.rate_period_us));
            o.rate_memory_us =
                p.integer("rate_memory_us", o.rate_memory_us, "memory of the background-activity rate estimate (us)");
            p.require_positive("rate_memory_us", static_cast<double>(o.rate_memory_us));
            o.initial_rate_hz = p.real("initial_rate_hz", o.initial_rate_hz,
                                       "background-activity rate (Hz/px) assumed until the first period closes");
            p.require_range("initial_rate_hz", o.initial_rate_hz, 0.0, 1e4);
            o.recency_max_us = p.integer("recency_max_us", o.recency_max_us,
                                         "longest neighbour age the recency test uses (us; 0 = no recency test)");
            p.require_range("recency_max_us", static_cast<double>(o.recency_max_us), 0.0, 1e9);
            o.edge_line = p.boolean("edge_line", o.edge_line, "edge-line test for slow edges (false: recency only)");
            o.surface = p.boolean("surface", o.surface,
                                  "edge-surface test against the plane of nearby kept events (slow edges)");
            o.lookahead_us = p.integer("lookahead_us", o.lookahead_us,
                                       "look-ahead for the joint past + future edge-line test (us; 0 = causal)");
            p.require_range("lookahead_us", static_cast<double>(o.lookahead_us), 0.0, 1e6);
            o.exact_scores = p.boolean("exact_scores", o.exact_scores,
                                       "exact score for every event (false: the look-ahead drops events its bound "
                                       "rejects without the full walk, keeping their causal score; same decisions)");
            return make_significance(g, o);
          }};
}

}  // namespace evpipe::denoise
