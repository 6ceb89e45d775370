#pragma once
// Direct model-to-events alignment around a prior (issue 21, real recordings): no detected lines, no
// correspondences. A small target with a fine grid (the evbench board: 57 x 40 px, grid lines 5.9 px apart, one line
// direction moving) gives too few and too one-sided detected lines for OPnL; its events still show the whole model.
//
// The pose is searched coarse to fine over the prior's tolerance, parameterised by what it does to the image: the
// shift of the model centre's image (du, dv, pixels), the turn about the line of sight to the model centre (roll),
// the depth (log scale of the image) and the tilts about the camera's x and y axes through the model centre. Each
// pose is scored by the ridge contrast of the events along its projected segments: the events' occupancy image
// (undistorted pixels, one count per pixel: hot pixels and flicker do not dominate), blurred with sigma, sampled on
// each segment minus the mean of two samples h = max(2.5, 2.5 sigma) to each side across it. Texture, flicker and
// blobs fill the band and its sides alike (contrast ~ 0); an edge under the segment gives the contrast.
//   level 0 (sigma = coarse_sigma_px, coarser where the grid would exceed max_level0_reads): every shift, roll and
//   scale on a grid of steps sized so that the model's image moves by sigma per step, tilts on a coarse grid -> the
//   best `candidates` distinct poses;
//   finer levels (sigma halved down to 1 px): a pattern search per candidate (each parameter +- one step, steps
//   halved when nothing improves).
// The best pose at the finest level is returned with the runner-up that lies more than runner_up_px away from it
// (largest image displacement of the model): the caller refines (tracker) and verifies them, and refuses when the
// events cannot tell them apart (a grid shifted by one line).

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/pose.hpp"
#include "evpipe/camera/prior.hpp"
#include "evpipe/core/event.hpp"

#include <cstddef>
#include <optional>
#include <string>

namespace evpipe::pose {

struct PriorAlignmentOptions {
  /// Blur of the coarsest level (pixels): at most this, and at most half the smallest image distance between two
  /// parallel model segments at the prior (a blur wider than that merges a fine grid's lines into one blob whose
  /// inner segments show no contrast). Each finer level halves it down to 1 px.
  double coarse_sigma_px = 4.0;
  /// Level-0 tilts about the camera's x and y axes: 0, +-coarse_tilt_deg, ... (coarse_tilt_steps each way, within
  /// the prior's angle tolerance). Tilts of a far target hardly change its image: the finer levels fix them.
  double coarse_tilt_deg = 15.0;
  int coarse_tilt_steps = 0;
  /// The search stays inside these even when the prior's tolerance is wider (pixels of centre shift, degrees).
  double max_shift_px = 80.0;
  double max_roll_deg = 45.0;
  /// Distinct level-0 poses refined at the finer levels.
  std::size_t candidates = 24;
  /// The runner-up is the best refined pose whose model image differs from the best one's by more than this.
  double runner_up_px = 2.5;
  /// Sample spacing along a projected segment at sigma = 1 (pixels; coarser levels sample every sigma / 2).
  double sample_px = 1.0;
  /// Work bound of level 0: its poses x their samples. The grid's poses grow as sigma^-4 and their samples as
  /// sigma^-1, so a wide tolerance around a long model at sigma = 1 px meant 10^8 poses (minutes per call); the
  /// coarsest blur grows until the grid fits this (about a second on one core).
  double max_level0_reads = 2e8;
  /// Pattern-search moves per candidate and level (each moves by a step: the level-0 grid is one step apart).
  int max_moves = 50;
};

struct PriorAlignmentResult {
  bool ok{false};
  std::string message;
  camera::Pose T_cam_model;               ///< the best pose
  double score{0.0};                      ///< its ridge contrast at the finest level (occupancy x pixels)
  std::optional<camera::Pose> runner_up;  ///< the best distinct alternative (see above)
  double runner_up_score{0.0};
  std::size_t evaluations{0};  ///< poses scored
};

/// Never throws; ok = false with a message when the window is empty or the model is not in view at the prior.
[[nodiscard]] PriorAlignmentResult align_at_prior(EventSpan events, const camera::CameraModel& camera,
                                                  const camera::LineModel& model, const camera::PosePrior& prior,
                                                  const PriorAlignmentOptions& options = {});

/// The smallest image distance (pixels, undistorted) between two projected model segments that are parallel (within
/// 5 deg) and beside each other at T_cam_model; infinity when no two are. How finely the model's lines lie in the
/// image: what line detection and line correspondences must resolve (a checkerboard's grid, 5.9 px on the evbench
/// board).
[[nodiscard]] double parallel_spacing_px(const camera::CameraModel& camera, const camera::LineModel& model,
                                         const camera::Pose& T_cam_model);

/// The share of the projected model's length (segments in front of the camera) that lies on segments with such a
/// parallel neighbour closer than spacing_px: how much of the model a line search with that resolution cannot tell
/// apart (the evbench board's grid: all of it at 8 px; the roadheader wireframe: a few thin parts).
[[nodiscard]] double crowded_length_share(const camera::CameraModel& camera, const camera::LineModel& model,
                                          const camera::Pose& T_cam_model, double spacing_px);

/// The score align_at_prior gives T_cam_model at blur sigma_px (for tests and diagnostics).
[[nodiscard]] double prior_alignment_score(EventSpan events, const camera::CameraModel& camera,
                                           const camera::LineModel& model, const camera::Pose& T_cam_model,
                                           double sigma_px = 1.0, double sample_px = 1.0);

}  // namespace evpipe::pose
