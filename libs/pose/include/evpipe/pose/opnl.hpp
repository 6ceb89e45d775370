#pragma once
// OPnL (Yu, Xu, Cheng 2020): globally optimal Perspective-n-Line with the CGR parameterisation, solved as a
// polynomial system, from three pre-rotated frames, then refined on line reprojection distances.
// CONTRACT (issue 5 helpers): the names below are used by the initialiser; extend, do not rename.

#include "evpipe/camera/pose.hpp"
#include "evpipe/pose/types.hpp"

#include <span>
#include <string>
#include <vector>

namespace evpipe::pose {

struct OpnlOptions {
  bool refine = true;    ///< Levenberg-Marquardt (Ceres) on line reprojection distances after the algebraic solve
  bool fallback = true;  ///< multi-start LM when the algebraic solve is ill-conditioned or yields nothing cheiral
  // (the implementation adds its thresholds here, documented)
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
};

/// Solves OPnL for n >= 4 correspondences. Never throws for degenerate geometry: ok = false with a message.
[[nodiscard]] OpnlResult solve_opnl(std::span<const LineCorrespondence> lines, const OpnlOptions& options = {});

}  // namespace evpipe::pose
