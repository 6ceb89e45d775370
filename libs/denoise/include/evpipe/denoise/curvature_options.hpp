#pragma once
// Options of the paper's density + curvature filter (`curvature`, see curvature.hpp and
// docs/algorithms.md, "Denoising: the paper's curvature filter"). Defaults are the paper's section 4.

#include <cstdint>
#include <string_view>

namespace evpipe::denoise {

/// How the stream is cut into neighbourhoods and curvature populations (blocks of window_us, absolute
/// alignment: block k = [k·window_us, (k+1)·window_us)).
enum class CurvatureMode {
  frames,  ///< independent blocks: a ball holds only events of its own block (the paper's evaluation)
  stream,  ///< full ball across block borders; decided when block end + reach has been seen
  causal,  ///< ball of earlier events only (input order); decided on arrival against the previous block
};

/// Which events of a block's population count as "consistent" (keep_fraction of them are kept).
enum class CurvatureRule {
  median,    ///< smallest |c − median(c)|
  shortest,  ///< the shortest interval of sorted c holding the share
  flattest,  ///< smallest |c|
};

enum class SingularPolicy {
  reject,  ///< rank < 6: curvature undefined, event dropped (counted as curvature_undefined)
  keep,    ///< rank < 6: kept without curvature, not part of the population
};

enum class NeighbourhoodBackend {
  grid,   ///< exact index on the pixel grid and time order (fast)
  flann,  ///< FLANN exact KD-tree radius search (the reference)
};

struct CurvatureOptions {
  double radius_px = 2.0;              ///< r, in (0, 4]
  std::int64_t lt_us = 10'000;         ///< Lt: µs that count like one pixel, ≥ 1
  bool inclusive_radius = true;        ///< ball test ≤ (true) or < (false)
  std::int64_t density_threshold = 5;  ///< ρ_TH; ρ = 1 + other events in the ball; pass iff ρ ≥ ρ_TH
  bool curvature = true;               ///< false = density stage only
  double keep_fraction = 0.8;          ///< share of the population kept, in (0, 1]
  CurvatureRule rule = CurvatureRule::median;
  SingularPolicy singular = SingularPolicy::reject;
  std::int64_t window_us = 30'000;  ///< block length (the paper's event frame)
  CurvatureMode mode = CurvatureMode::stream;
  NeighbourhoodBackend backend = NeighbourhoodBackend::grid;
  bool adaptive = false;                      ///< set ρ_TH per period from the estimated noise rate
  double target_noise_pass = 0.01;            ///< adaptive: largest share of pure-noise events passing density
  std::int64_t adaptive_period_us = 100'000;  // ~9 000 noise events per period at 1 Hz/px
  /// adaptive: the threshold never goes above this (0 = no limit; else ≥ 2). evpipe's pose pipeline uses the
  /// paper's 5: a lower threshold where the noise is low keeps slow edges, a higher one where it is high costs
  /// the tracker more signal than the noise it removes (docs/algorithms.md, "Adaptive threshold").
  std::int64_t adaptive_max_threshold = 0;
};

/// Throws std::invalid_argument ("curvature: <key>=<value>: <why>") for an out-of-range option.
void validate(const CurvatureOptions& options);

std::string_view to_string(CurvatureMode m) noexcept;
std::string_view to_string(CurvatureRule r) noexcept;

}  // namespace evpipe::denoise
