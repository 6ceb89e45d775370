#pragma once
// Initial pose without given correspondences: detected lines + model + (optional) prior -> hypotheses ->
// RANSAC over minimal sets with OPnL -> the pose that explains the most events.
// CONTRACT (issue 5 helpers): the names below are used by the estimator; extend, do not rename.

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/prior.hpp"
#include "evpipe/core/event.hpp"
#include "evpipe/pose/line_detector.hpp"
#include "evpipe/pose/prior_alignment.hpp"
#include "evpipe/pose/verification.hpp"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

namespace evpipe::pose {

/// When the initialiser searches the pose by direct alignment (InitialiserOptions::direct_alignment).
enum class DirectAlignment { off, on, automatic };

// How it works (docs/algorithms.md, "Automatic correspondences"): for each pseudo-prior (the prior itself, or
// without a prior a set of sampled view directions with a depth guessed from the model's size), the visible
// model segments are projected; pairs of non-parallel detected lines matched to pairs of model segments
// (angle-gated) fix a 2D rotation + shift that aligns the projected model with the image; the detected lines
// consistent with an alignment form its hypothesis set; RANSAC draws minimal sets of 4 correspondences from
// the best sets and solves each with OPnL; every pose inside the prior's tolerance with the model in front of
// the camera is scored by the events it explains; the best poses are re-associated with all detected lines
// and re-solved (OPnL + refinement) on all inliers; the pose explaining the most events wins.
struct InitialiserOptions {
  /// Line detection (its `camera` is set from the camera argument).
  LineDetectorOptions detector;
  /// RANSAC seed: the result is deterministic for a seed.
  std::uint64_t seed = 1;
  /// Lines needed (OPnL's minimum).
  std::size_t min_lines = 4;
  /// Two lines are "parallel" (one direction) below this angle: at least two directions are needed.
  double parallel_deg = 10.0;
  /// Hypotheses: a detected line may match a projected model segment when their image angles differ by at
  /// most min(prior angle tolerance, this) (degrees). Ignored without a prior (any in-plane rotation).
  double max_match_angle_deg = 35.0;
  /// Model segments projected by a pseudo-prior up to this far outside the image are hypothesis candidates
  /// (a far prior shifts the projection by ~f tan(angle error): what it puts outside may be in view).
  double hypothesis_margin_px = 150.0;
  /// With a prior, pseudo-priors: the prior tilted about the camera's x and y axes (through the model's
  /// centre) in steps of prior_step_deg up to min(prior_search_deg, the prior's angle tolerance) each way.
  double prior_step_deg = 15.0;
  double prior_search_deg = 15.0;
  /// The longest this-many detected lines seed the 2D alignments.
  std::size_t seed_lines = 8;
  /// 2D alignment consistency: a detected line agrees with an aligned model segment when the angles differ by
  /// at most consistency_angle_deg and both endpoints lie within consistency_px + consistency_scale x (their
  /// distance from the alignment's anchor) of the segment's line (the alignment ignores scale and perspective).
  double consistency_angle_deg = 8.0;
  double consistency_px = 8.0;
  double consistency_scale = 0.25;
  /// Alignments (best first by consistent line length) that RANSAC draws from, per pseudo-prior.
  std::size_t alignments = 32;
  /// Minimal sets (4 correspondences, >= 2 directions) drawn per alignment, plus one solve on its whole set.
  int draws_per_alignment = 4;
  /// RANSAC stops early (after the current alignment) when a new best pose (by explained events) explains
  /// early_stop_share of the events supporting the detected lines AND early_stop_line_share of that support lies
  /// on lines matching its projected segments (the re-association gates below), and only when at least
  /// early_stop_min_line_fraction x (model segments, in view or not) lines were detected. The event count alone
  /// includes events near the model on no detected line, and a few lines of a large wireframe are matched by wrong
  /// poses too: stopping on less accepted wrong poses (docs/algorithms.md). The stop only saves time: a model
  /// mostly out of view, or early_stop_line_share > 1, searches every alignment.
  double early_stop_share = 0.8;
  double early_stop_line_share = 0.9;
  double early_stop_min_line_fraction = 0.3;
  /// Poses (best support first) re-associated and re-solved on all their inlier correspondences (those that
  /// explain at least half as many events as the best). Two distinct verified ones are compared on the events
  /// (initialise_pose).
  std::size_t refine_candidates = 4;
  /// Re-association at a pose: a detected line is an inlier of a model segment when both its endpoints lie
  /// within inlier_px of the segment's image line and the angle is below inlier_angle_deg.
  double inlier_px = 3.0;
  double inlier_angle_deg = 5.0;
  /// Huber scale (pixels) of the LM refinement in the re-solve on all inliers.
  double refine_huber_px = 1.5;
  /// Re-associate / re-solve rounds.
  int refine_rounds = 3;
  /// Events within this distance (pixels, measured image, distortion included) of a projected model segment
  /// are explained by a pose.
  double support_band_px = 2.0;
  /// The chosen pose must explain at least this share of the events that support the detected lines.
  double min_explained_share = 0.5;
  /// Without a prior: view directions sampled (Fibonacci sphere) as pseudo-priors.
  int view_samples = 48;
  /// The refined candidates are ranked by verify_pose() with these options (verified first, then supported
  /// cells, then explained events).
  VerifyOptions verification;
  /// With a prior, the pose may be searched by aligning the model with the events directly (prior_alignment.hpp): its
  /// best pose and its runner-up are refined by the tracker (track_window with `verification`) and the pose is
  /// accepted only when it verifies and the runner-up, if it verifies too, is clearly worse (compare_poses beyond
  /// symmetry_decision_log_ratio).
  /// automatic (default): instead of the line search, for a model whose lines the correspondences cannot resolve:
  /// more than half of its projected length at the prior lies on segments with a parallel neighbour beside them
  /// closer than consistency_px (crowded_length_share), where one detected line is consistent with two model lines
  /// and a fine grid's poses alias (the evbench board's grid, 5.9 px apart; the same board 55 px wide on the DAVIS346
  /// was tracked 180 mm / 29 deg off from the lines). Other models: the line search alone.
  /// on: the line search, then, when it gives no verified pose, the alignment (without a verified pose from it the
  /// line search's result, verified or not). On every model this cost more wrong confident poses on the clutter
  /// scenes (decoys, a board beside line clutter whose track it started earlier) and 1-2 s per attempt
  /// (docs/history.md). off: the line search alone.
  DirectAlignment direct_alignment = DirectAlignment::automatic;
  PriorAlignmentOptions alignment;
};

struct InitResult {
  bool ok{false};
  std::string message;  ///< why not ok ("3 lines detected, need 4", "no hypothesis within the prior", ...)
  camera::Pose T_cam_model;
  std::size_t lines_detected{0};
  std::size_t correspondences{0};   ///< inlier 2D-3D matches of the chosen pose
  double support_share{0.0};        ///< share of the window's events explained by the chosen pose
  std::size_t explained_events{0};  ///< events within support_band_px of the chosen pose's projected model
  double line_share{0.0};           ///< share of the detected lines' support on lines matching the chosen pose
  std::size_t hypotheses{0};        ///< OPnL solves on minimal sets
  std::size_t pseudo_priors{0};     ///< poses the search started from (1 with a prior)
  bool verified{false};             ///< the pose passed verify_pose() (with a prior, ok implies verified)
  bool direct{false};               ///< found by the direct alignment (InitialiserOptions::direct_alignment)
};

[[nodiscard]] InitResult initialise_pose(EventSpan events, const camera::CameraModel& camera,
                                         const camera::LineModel& model, const std::optional<camera::PosePrior>& prior,
                                         const InitialiserOptions& options = {});

}  // namespace evpipe::pose
