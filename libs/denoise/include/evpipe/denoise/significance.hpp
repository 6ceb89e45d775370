#pragma once
// Significance filter: keeps an event when its support is improbable under background activity (BA) alone, at a
// set false-alarm rate alpha, against the BA rate estimated online from the stream (docs/algorithms.md,
// "Significance filter"). O(1) per event. Decides on arrival what the causal tests keep; with lookahead_us = L > 0
// (default 20 ms) an event they reject is decided at t + L by the joint test and then the edge-surface test
// (make_significance; decision latency L).
//
// Noise model: BA is an independent Poisson process of rate lambda per pixel and polarity-balanced. Up to four
// tests whose false-alarm shares add up to alpha (so that a noise event passes with probability <= alpha): alpha /
// max(2, tests) each for the edge-line test, the optional recency test and the pair (joint look-ahead test,
// edge-surface test), which split theirs in halves when both run; the edge-line test decides by default, the joint
// look-ahead test runs when lookahead_us > 0, the edge-surface test when surface (default), the recency test is
// optional (recency_max_us > 0):
//  * recency (count) test: the ages a_q of the newest event of the 8 neighbours q (own pixel excluded: hot pixels
//    and refractory bursts do not support themselves; each neighbour counts once, so a hot neighbour adds at most
//    1) are i.i.d. Exp(lambda) under noise. Sorted a_(1) <= ... <= a_(8); the event passes when a_(k) <= A_k for
//    some k, A_k being the age at which P(Binomial(8, 1 − exp(−lambda·A_k)) >= k) = alpha / 2 / 8 (Bonferroni over
//    k). Fast edges pass it: their neighbours are a few ms old.
//  * edge-line test: a moving edge crosses pixels p − d and p − 2d (d one of the 8 neighbour steps) at times
//    t − s and t − 2s (constant local speed), with the event's polarity. A direction d matches when a stored event
//    of p − d (age s <= T = 1 / slowest_speed_px_s) and one of p − 2d (age s2) of the same polarity satisfy
//    |s2 − 2s| <= jitter + precision·s. Under noise a direction matches with probability
//    p(U) = 1 − exp(−(lambda²/2)·(jitter·U + precision·U²/2)) within age U; with the directions' smallest matched
//    ages sorted, u_(1) <= ... <= u_(8), the event passes when u_(m) <= U_m for some m, P(Binomial(8, p(U_m)) >= m)
//    = alpha / 2 / 8. Slow edges pass it: their support is sparse but exactly placed in time.
//  * joint (look-ahead) edge-line test: the same half-line test mirrored in time (p + d at t + s, p + 2d at t + 2s,
//    0 < s, s2 <= L) gives 8 more independent half-lines; the 16 smallest matched ages (past and future) sorted,
//    w_(1) <= ..., the event passes when w_(m) <= V_m, P(Binomial(16, p(V_m)) >= m) = alpha / 2 / 16. An edge
//    with one line behind it (an edge entering the view, a corner) and one ahead of it passes.
//  * edge-surface test (surface, default on; slow edges): the plane s(q) = a + g·q fitted to the kept events of the
//    event's 5×5 block within [t − T, t + L] (the newest kept event per pixel; >= 3 of the event's polarity) is the
//    local motion; the block's pixels p + q whose rings hold an event at t + g·q (within jitter + precision·|g·q|)
//    are counted, K, against Poisson((lambda/2)·sum of the slot widths): kept when P(>= K) <= alpha_s (alpha_s:
//    half the look-ahead test's part, all of it when causal). Runs on an event the other tests rejected, with a
//    matched past half-line and the plane's time at p near t.
// lambda: from the events whose 8 neighbours are all older than T0 = 10 ms (rate r0 per pixel·s, which noise
// alone makes lambda·exp(−8·lambda·T0)), updated every rate_period_us with memory rate_memory_us; of its two roots
// the larger (above 12.5 Hz/px) only when the whole event rate reaches it and the share at T1 = 1 ms points to it.
//
// State: per pixel the last `kRing` (4) events (time·2 + polarity, 32 bits relative to a base that moves forward on
// long streams), padded by 2 pixels on every side; allocated in one place (allocate()).
//
// Speed: the edge-line test reads each direction's two rings whole (16 bytes each) and matches all their pairs at
// once (SSE4.1, or AVX2 two directions at a time, chosen at run time from the CPU; the look-ahead's future
// half-lines likewise with SSE4.1), which on time-ordered input is the same test as the scalar walk along the
// rings: the same decisions and scores (the AVX2 kernel: the first two directions one by one, the other six at once;
// the edge-surface test's scan of the kept block likewise, in integer plane sums). The scalar walk remains the
// reference, used for out-of-order input and on other CPUs (EVPIPE_SIGNIFICANCE_KERNEL=scalar|sse4 forces it or
// SSE4.1, for tests and benchmarks).

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "evpipe/core/event.hpp"
#include "evpipe/denoise/filter.hpp"
#include "evpipe/denoise/registry.hpp"

namespace evpipe::denoise {

struct SignificanceOptions {
  double alpha = 5e-4;                      ///< false-alarm rate: share of noise events kept (both tests)
  double slowest_speed_px_s = 2.0;          ///< slowest edge the edge-line test looks for (T = 1 / it)
  double edge_precision_px = 0.1;           ///< edge position precision (crossing-time error = it / speed)
  std::int64_t timing_jitter_us = 2000;     ///< timestamp jitter between neighbouring pixels
  std::int64_t rate_period_us = 10'000;     ///< BA rate (and thresholds) update period
  std::int64_t rate_memory_us = 1'000'000;  ///< BA rate estimate's memory (exponential forgetting)
  /// BA rate assumed before the first measured period closes (T0 + rate_period_us after the first event): the
  /// larger of this and the whole event rate so far (noise is part of it; conservative either way).
  double initial_rate_hz = 10.0;
  bool edge_line = true;            ///< the edge-line test (false: recency test alone)
  std::int64_t recency_max_us = 0;  ///< recency test's longest age (0 = no recency test)
  /// Look-ahead L: an event the causal tests reject waits up to L for its future half-lines (p + d at t + s,
  /// p + 2d at t + 2s), joined with its past ones in one test (0 = causal: decided on arrival). 20 ms: the
  /// pipeline's event -> LCM budget (35 ms p99) minus what the stages after the denoiser add at p99 (~13 ms).
  std::int64_t lookahead_us = 20'000;
  /// true: every event's score is its exact margin. false: the same decisions, cheaper at high noise (the pipeline
  /// runs it so; evdenoise's ROC needs the exact scores): a kept event's score is exact, a dropped one's only a lower
  /// bound of its margin - the causal tests give a rejected event 0 (the vector kernel skips the ranks and
  /// divisions), and an event the look-ahead rejects because even its future candidates' most favourable ages cannot
  /// reach the joint thresholds (Significance::joint_may_pass) is dropped without the full future walk.
  bool exact_scores = true;
  /// Edge-surface test (slow edges): an event the line tests reject is tested against the plane fitted to the
  /// already-kept events of its 5×5 block (the local normal flow), counting the block's pixels whose events lie on
  /// that plane through the event, against the count BA alone gives (docs/algorithms.md, "Edge-surface test").
  bool surface = true;
};

class Significance {
 public:
  static constexpr int kRing = 4;
  static constexpr int kPad = 2;

  Significance(const SensorGeometry& geometry, SignificanceOptions options);
  [[nodiscard]] bool accept(const Event& e) noexcept;
  /// >= 1 exactly when kept: the larger of the recency margin max_k A_k / a_(k) and the edge-line margin
  /// max_m U_m / u_(m) (for a kept event, over the directions examined until the decision was final).
  [[nodiscard]] float last_score() const noexcept { return score_; }
  void reset() noexcept;
  /// noise_rate_hz (current BA estimate), kept_recency, kept_edge_line, line_window_us (U_8).
  [[nodiscard]] std::vector<ReportItem> report() const;

  [[nodiscard]] double rate_hz() const noexcept { return rate_hz_; }
  /// Recency thresholds A_1..A_8 and edge-line thresholds U_1..U_8 (µs) for a BA rate.
  void set_rate(double rate_hz) noexcept;
  /// BA rate (Hz/px) from the rates r0, r1 (per pixel·s) of events without a neighbour event younger than T0 =
  /// 10 ms and T1 = 1 ms, and the rate of all events; zero_count: the events behind r0 (docs/algorithms.md,
  /// "Significance filter": the rate estimate).
  [[nodiscard]] static double rate_from_zero_support(double r0_hz, double r1_hz, double all_hz,
                                                     double zero_count) noexcept;
  [[nodiscard]] const std::array<std::int32_t, 8>& recency_thresholds_us() const noexcept { return recency_us_; }
  [[nodiscard]] const std::array<std::int32_t, 8>& line_thresholds_us() const noexcept { return line_us_; }
  /// Joint (past + future) edge-line thresholds V_1..V_16 (µs); all 0 when lookahead_us = 0.
  [[nodiscard]] const std::array<std::int32_t, 16>& joint_thresholds_us() const noexcept { return joint_us_; }

  // Look-ahead (lookahead_us > 0; SignificanceFilter drives it): after accept() rejected an event, its past
  // half-lines' smallest matched ages (ascending; in direction order when exact_scores is false); later, once every
  // event up to t + L is stamped, joint_ratio() joins them with the future half-lines: max_m V_m / w_(m) over the
  // merged ages (>= 1: keep).
  [[nodiscard]] int past_line_count() const noexcept { return past_n_; }
  [[nodiscard]] const std::array<std::int32_t, 8>& past_line_ages_us() const noexcept { return past_ages_; }
  [[nodiscard]] float joint_ratio(const Event& e, const std::int32_t* past_ages, int past_count) const noexcept;
  /// False only when joint_ratio(e, past_ages, past_count) < 1 for certain, from the 3×3 block alone (the rings of
  /// p + d; p + 2d's are not read): a future half-line's matched s is one of p + d's entries of the event's polarity
  /// with 0 < s <= L and 2s − tol(s) <= L (its p + 2d partner is within L), so each direction's smallest such s (its
  /// candidate) is <= its match, and #{merged ages <= V_m} <= #{past ages <= V_m} + #{candidates <= V_m}. The joint
  /// test passes iff that count reaches m for some m; when the bound's does not, it cannot. past_ages: 8 readable
  /// values (past_line_ages_us()'s array), the first past_count used.
  [[nodiscard]] bool joint_may_pass(const Event& e, const std::int32_t* past_ages, int past_count) const noexcept;
  /// Starts fetching the rings joint_ratio(e, ...) reads first.
  void prefetch_block(const Event& e) const noexcept;

  // Edge-surface test (options.surface): the newest kept event per pixel (mark_kept; accept() marks what it keeps,
  // the look-ahead driver what it keeps later) gives the motion prior. surface_ratio(e, horizon_us) is
  // log P / log alpha_s (>= 1: keep), P the chance of the event's on-plane support under BA, with slots up to
  // t + horizon_us (0 when causal, L at the look-ahead's decision). 0 when the block has too few kept events.
  [[nodiscard]] float surface_ratio(const Event& e, std::int32_t horizon_us) const noexcept;
  void mark_kept(const Event& e) noexcept;
  void count_kept_surface() noexcept { ++kept_surface_; }

 private:
  void allocate();
  void rebase(std::int64_t t_us) noexcept;
  void update_rate(std::int64_t t_us) noexcept;
  /// max_m U_m / u_(m) over the directions' smallest matched ages u, examined until it reaches 1 (kept).
  [[nodiscard]] float edge_lines(std::size_t centre, std::int32_t now, int polarity) noexcept;
  /// The same, walking the rings one entry at a time (the reference; exact on any input order).
  [[nodiscard]] float edge_lines_scalar(std::size_t centre, std::int32_t now, int polarity) noexcept;
  /// The future half-lines' smallest matched ages (ascending) into `ages`; returns how many directions matched.
  int future_lines(std::size_t centre, std::int32_t then, int polarity,
                   std::array<std::int32_t, 8>& ages) const noexcept;
  void set_joint_thresholds() noexcept;
  [[nodiscard]] float surface_ratio_at(std::size_t centre, std::int32_t then, int polarity,
                                       std::int32_t horizon_us) const noexcept;

  SensorGeometry geometry_;
  SignificanceOptions options_;
  std::int64_t stride_;
  std::vector<std::int32_t> ring_;             // kRing per padded pixel, newest first: (t − base)·2 + polarity
  std::vector<std::int32_t> kept_;             // per padded pixel, the newest kept event: (t − base)·2 + polarity
  double surface_alpha_ = 0.0;                 // the edge-surface test's share of alpha
  std::array<double, 25> surface_mu_{};        // K -> largest Poisson mean with P(>= K) <= surface_alpha_ (0: never)
  std::array<double, 25> surface_width_us_{};  // K -> W_K = surface_mu_[K] / (λ/2), µs (set_rate)
  std::int64_t base_us_ = 0;
  bool started_ = false;
  std::int64_t last_t_us_ = 0;  // time of the previous event
  bool ordered_ = true;         // no event older than its predecessor since reset(): the rings are sorted
  static constexpr std::uint8_t kScalar = 0;
  static constexpr std::uint8_t kSse4 = 1;
  static constexpr std::uint8_t kAvx2 = 2;
  std::uint8_t kernel_ = kScalar;  // edge-line kernel (chosen from the CPU at construction)
  std::array<std::int32_t, 8> recency_us_{};
  std::array<std::int32_t, 8> line_us_{};    // U_1..U_8
  std::array<double, 8> quantile_{};         // q_m: P(Binomial(8, q_m) >= m) = alpha / 2 / 8
  std::array<std::int32_t, 16> joint_us_{};  // V_1..V_16
  std::array<double, 16> joint_quantile_{};  // P(Binomial(16, q_m) >= m) = alpha / 2 / 16
  std::int32_t lookahead_us_ = 0;
  std::array<std::int32_t, 8> past_ages_{};
  int past_n_ = 0;
  std::int32_t window_us_ = 0;  // T
  std::int32_t jitter_us_ = 0;
  float precision_ = 0.0F;
  // Rate estimate.
  double rate_hz_ = 0.0;
  std::int64_t period_end_us_ = 0;
  std::int64_t zero_support_ = 0;        // in the current period: no neighbour event younger than T0
  std::int64_t short_zero_support_ = 0;  // ... younger than T1 (picks the root: rate_from_zero_support)
  std::int64_t events_ = 0;              // every event in the current period
  std::int64_t count_from_us_ = 0;       // the counts start T0 after the first event
  // Warm-up, before the first measured period [count_from, count_from + period) closes: the rate is the larger of
  // initial_rate_hz and the whole event rate so far, re-evaluated every kWarmupProbeUs.
  bool rate_measured_ = false;
  std::int64_t start_us_ = 0;  // the first event's time
  std::int64_t first_period_end_us_ = 0;
  std::int64_t warmup_events_ = 0;  // events before count_from_us_
  double zero_acc_ = 0.0;           // forgetting sums
  double short_zero_acc_ = 0.0;
  double events_acc_ = 0.0;
  double time_acc_s_ = 0.0;
  std::uint64_t kept_recency_ = 0;
  std::uint64_t kept_line_ = 0;
  std::uint64_t kept_surface_ = 0;
  float score_ = 0.0F;
};

/// The significance filter as a Filter: PerEventFilter<Significance> when causal (lookahead_us = 0), else events the
/// causal tests reject wait until the first event later than t + L (or finish()) for the joint test; decisions are
/// output in input order. Stream = batch: a decision depends only on the events up to t + L.
std::unique_ptr<Filter> make_significance(const SensorGeometry& geometry, const SignificanceOptions& options);

FilterSpec significance_spec();

}  // namespace evpipe::denoise
