#pragma once
// OPnL (Yu, Xu, Cheng 2020): globally optimal Perspective-n-Line with the CGR parameterisation, solved as a
// polynomial system, from three pre-rotated frames, then refined on line reprojection distances.
// CONTRACT (issue 5 helpers): the names below are used by the initialiser; extend, do not rename.

#include "evpipe/camera/pose.hpp"
#include "evpipe/pose/line_refine.hpp"
#include "evpipe/pose/types.hpp"

#include <span>
#include <string>
#include <vector>

namespace evpipe::pose {

struct OpnlOptions {
  bool refine = true;    ///< Levenberg-Marquardt (Ceres) on line reprojection distances after the algebraic solve
  bool fallback = true;  ///< multi-start LM when the algebraic solve is ill-conditioned or yields nothing cheiral
  /// false skips the polynomial solve: the 24-start LM alone (for comparisons and tests; implies fallback).
  bool algebraic = true;
  /// An eigenvalue solution is real when |Im s| <= imag_tol · (1 + |s|) (s = CGR vector); Newton then polishes
  /// its real part, so a lenient value only adds candidates that the line cost ranks.
  double imag_tol{1e-4};
  int newton_steps{2};  ///< Newton steps on ∇J = 0 per real solution
  /// Candidates are cheiral when every model endpoint is at depth > this (m).
  double min_depth_m{0.0};
  /// The fallback also runs when the refined RMS line distance exceeds this (normalised image units; default
  /// ≈ 4 px at f = 800, 1.2 px at f = 243). Set it to ~2-3 × the expected σ_px / f when σ is known.
  double fallback_rms_n{5e-3};
  /// Candidates closer than this (rotation rad and relative translation) are merged (the three pre-rotated
  /// solves find the same minima).
  double duplicate_tol{1e-6};
  RefineOptions refine_options{};   ///< for the final refinement
  int fallback_max_iterations{30};  ///< LM iterations per start of the 24-start fallback
};

struct OpnlCandidate {
  camera::Pose T_cam_model;
  double cost{0.0};  ///< geometric line cost, normalised image units squared (sum over endpoints)
};

struct OpnlResult {
  bool ok{false};
  std::string message;                    ///< why not ok (e.g. "n = 3 < 4 lines", "all lines parallel")
  camera::Pose T_cam_model;               ///< best candidate (refined when options.refine)
  double rms_n{0.0};                      ///< RMS endpoint-to-line distance of the result, normalised image units
  std::vector<OpnlCandidate> candidates;  ///< every real, cheiral candidate, best first
  bool used_fallback{false};
  int macaulay_rank_min{0};  ///< smallest rank of the three 105×120 Macaulay matrices (93 = generic)
  int robust_solves{0};      ///< pre-rotated solves whose elimination template was ill-conditioned (QR path)
};

/// Solves OPnL for n >= 4 correspondences. Never throws for degenerate geometry: ok = false with a message.
[[nodiscard]] OpnlResult solve_opnl(std::span<const LineCorrespondence> lines, const OpnlOptions& options = {});

}  // namespace evpipe::pose
