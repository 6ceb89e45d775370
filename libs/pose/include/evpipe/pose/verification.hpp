#pragma once
// Verification of a pose against a window of events (issue 21): a pose is only reported as tracking when the
// events show the model there, not merely when most events lie near some of its segments.
//
// Each visible model segment (in front of the camera, inside the image; no hidden-line removal: the model is a
// wireframe and evsim renders every segment too) is split into cells of about cell_px along its projection. A
// cell is SUPPORTED when
//   - its band (|distance| <= band_px) holds at least k events, k the smallest count that the window's noise
//     density (events per pixel away from every band: sensor noise AND the scene's other structure) reaches
//     with probability <= false_alarm (Poisson), and
//   - the band's event density beats both side strips beside it (the same model shifted by a few pixels across
//     the segment) by side_ratio: a straight edge concentrates its events on the line, texture, flicker or a
//     crossing edge fill the band and its sides alike.
// A segment only fires when the target moves across it: with a motion hint (the pose at an earlier time) a
// segment whose predicted normal motion over the window is below min_normal_motion_px is not required (it cannot
// have support). The pose is VERIFIED when the required segments are supported along their length (per segment
// and over the model), and the supported cells fix all 6 DoF (the covariance of the pose from one measurement
// per supported cell, cell_sigma_px each, within the bounds): a single direction of moving edges (tilt only) or
// too few supported cells cannot verify a pose, whatever the residuals say. A required segment without support whose
// edge is seen beside it (its cells moved across it by up to displaced_max_px show the support it lacks, away from
// every other projected segment) refutes the pose when the pose moved by that offset explains the window better
// (compare_poses): the edge's events are there, the pose puts it elsewhere.
//
// Symmetric alternatives (issue 21, "never a confident wrong pose"): a model with a partial symmetry (the board's
// outline, the roadheader's body box) has poses T * S (S a rigid motion of the model frame that maps most of its
// segments onto segments) whose image shares most cells with T's; only the cells one of them has and the other
// does not (the discriminating cells) tell them apart. compare_poses() scores both on those cells with the same
// cell model as above (a cell of an edge is supported with its expected share p, a cell without one with the
// false-alarm rate) and returns the log-likelihood ratio. verify_pose() refuses T when one of
// VerifyOptions::symmetries explains the window clearly better (ratio below -log(1/false_alarm)); the initialiser
// also refuses a pose whose alternative it cannot rule out (|ratio| below that) unless a prior excludes it.

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/pose.hpp"
#include "evpipe/core/event.hpp"

#include <cstddef>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

namespace evpipe::pose {

struct VerifyOptions {
  double cell_px = 4.0;        ///< cell length along a projected segment (pixels)
  double band_px = 1.5;        ///< events within this distance of the cell's segment count for it
  double side_gap_px = 0.5;    ///< the side strips start this far beyond the band ...
  double side_width_px = 1.5;  ///< ... and are this wide, one on each side
  double side_ratio = 1.5;     ///< a supported band's event density exceeds each side strip's by this factor
  /// A segment whose cells meet another projected segment's band (in their band or side strips) in at least this
  /// share judges its cells on its own pixels only: a crossing grid line's events explain those pixels as much as
  /// this segment (a fine grid: a small board's lines 5.9 px apart fill every side strip). A segment crossed in fewer
  /// cells (junctions and corners of a sparse model) counts every pixel. > 1: never.
  double crossing_share = 0.5;
  /// P(noise alone reaches a cell's support threshold); a segment must also hold more supported cells than
  /// noise alone gives at this rate (binomial, 3 sigma).
  double false_alarm = 0.05;
  double border_px = 2.0;     ///< cells closer than this to the image border are not judged
  std::size_t min_cells = 3;  ///< a segment with fewer cells in view is not judged
  /// With a motion hint a segment is required when it moves at least this far across itself over the window and
  /// its expected events above noise per cell (the window's measured events per pixel swept) are at least twice
  /// the support threshold.
  double min_normal_motion_px = 0.1;
  /// A required segment is supported when it shows this share of the supported cells a true edge with its
  /// motion would show (Poisson, the window's measured events per pixel swept).
  double min_segment_coverage = 0.5;
  double min_segment_share = 0.5;  ///< this share of the required segments must be supported (a majority) ...
  double min_coverage = 0.35;      ///< ... and the model this share of its expected supported cells
  /// Observability: the pose from one measurement per supported cell (cell_sigma_px each, the position of an edge
  /// in a cell) must have 1-sigma errors below these.
  /// The wrong-pose threshold itself (20 mm / 2 deg) at 1 sigma: support that leaves more fixes nothing. (2 or
  /// 3 sigma inside it refuses most windows of the planar target beyond 0.8 m, whose tilt is weakly observable.)
  double cell_sigma_px = 1.0;
  /// A required segment without support whose edge is seen beside it (the segment's cells moved across it by
  /// 2 x (band + side strips) up to this many pixels show the support it lacks) refutes the pose when the pose moved
  /// by that offset explains the window better (compare_poses, the symmetric alternatives' decision). 0: off.
  double displaced_max_px = 15.0;
  /// ... judged on at least this many moved cells (a short edge finds parallel clutter beside it by chance: the
  /// bars beside the roadheader's 18 px cutting-head edges refuted true poses at 3 cells).
  std::size_t displaced_min_cells = 6;
  double max_rotation_std_deg = 2.0;
  double max_translation_std_m = 0.02;
  /// Redundancy (`pose.require_redundancy`, off): the bounds above must also hold without any one supported
  /// segment, so that no single edge carries a degree of freedom alone. Measured on the unseen seeds: wrong
  /// confident poses 35 -> 1, confident poses -32 % (docs/history.md, session 20).
  bool leave_one_out = false;
  /// Model-frame rigid motions S (T_model_model') to compare the pose T with T * S (model_symmetries(); the
  /// estimator fills them from its model). Empty: no comparison.
  std::vector<camera::Pose> symmetries;
};

/// The target's motion over the window: the pose it had `before` (camera::StampedPose) and the time of the pose
/// verified; the window's events span [t_first, t_last] (the displacement is scaled to that span).
struct MotionHint {
  camera::StampedPose before;
  std::int64_t t_us{0};
};

struct SegmentSupport {
  std::size_t model_index{0};
  std::size_t cells{0};
  std::size_t supported{0};
  double normal_motion_px{0.0};  ///< mean |motion across the segment| over the window (0 without a hint)
  bool required{false};
};

struct VerifyResult {
  bool ok{false};
  std::string reason;  ///< why not verified (empty when ok)
  std::size_t segments_judged{0};
  std::size_t segments_required{0};
  std::size_t segments_supported{0};  ///< required segments with min_segment_coverage
  std::size_t cells_required{0};
  std::size_t cells_supported{0};  ///< supported cells of required segments
  double cells_expected{0.0};      ///< supported cells a true pose would show (expected, required segments)
  double coverage{0.0};            ///< cells_supported / cells_required
  double noise_per_cell{0.0};      ///< expected noise events in a cell's band
  int support_threshold{0};        ///< events a band needs
  double rotation_std_deg{0.0};    ///< from the supported cells (infinity when not all DoF are fixed)
  int displaced_segment{-1};       ///< a required segment whose edge is seen beside it (model index), else -1
  double displaced_px{0.0};        ///< ... and where (pixels along the cell normal)
  double translation_std_m{0.0};
  /// The largest rotation_std_deg / translation_std_m without one of the supporting segments (0 unless
  /// VerifyOptions::leave_one_out).
  double rotation_std_without_deg{0.0};
  double translation_std_without_m{0.0};
  std::vector<SegmentSupport> segments;
  /// The lowest log-likelihood ratio of T against T * S over VerifyOptions::symmetries (+infinity without any),
  /// and the index of that S.
  double symmetry_log_ratio{std::numeric_limits<double>::infinity()};
  std::size_t symmetry_index{0};
};

/// Log-likelihood ratio of pose A against pose B on a window (> 0: A explains it better): over the cells of A that
/// B has nowhere near (farther than the side strips) and those of B that A has nowhere near, each cell supported
/// (the test of verify_pose) with its edge's expected share p (clamped to [false_alarm, 1 - false_alarm]) under the
/// hypothesis that draws it and with false_alarm under the other. Motion hints as for verify_pose (the hint of B:
/// the earlier pose of A moved by the same model-frame motion). Noise density and event rate are measured at A.
struct PoseComparison {
  double log_ratio{0.0};
  std::size_t cells_a_only{0}, supported_a_only{0};
  std::size_t cells_b_only{0}, supported_b_only{0};
};
[[nodiscard]] PoseComparison compare_poses(EventSpan events, const camera::CameraModel& camera,
                                           const camera::LineModel& model, const camera::Pose& A, const camera::Pose& B,
                                           const VerifyOptions& options = {},
                                           const std::optional<MotionHint>& motion_a = std::nullopt,
                                           const std::optional<MotionHint>& motion_b = std::nullopt);

/// Rigid motions S of the model frame (not the identity) that map segments covering at least min_share of the
/// model's total length onto segments (both ends within 0.5 % of the model's extent): the partial symmetries
/// (candidates from pairs of congruent corners; at most max_count, most coverage first). The board's 180 deg turns
/// about its three axes; the roadheader's body box turned about its centre.
[[nodiscard]] std::vector<camera::Pose> model_symmetries(const camera::LineModel& model, double min_share = 0.5,
                                                         std::size_t max_count = 8);

/// The decision level of the comparisons: log(1 / false_alarm) (odds of 20 : 1 at the default 5 %).
[[nodiscard]] double symmetry_decision_log_ratio(const VerifyOptions& options);

/// Verifies T_cam_model on a window of events (pixel coordinates of the camera). Never throws.
[[nodiscard]] VerifyResult verify_pose(EventSpan events, const camera::CameraModel& camera,
                                       const camera::LineModel& model, const camera::Pose& T_cam_model,
                                       const VerifyOptions& options = {},
                                       const std::optional<MotionHint>& motion = std::nullopt);

/// Smallest k with P(Poisson(mean) >= k) <= false_alarm (k >= 1).
[[nodiscard]] int poisson_threshold(double mean, double false_alarm);

}  // namespace evpipe::pose
