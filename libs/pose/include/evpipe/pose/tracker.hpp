#pragma once
// ELOPET-style tracking: project the model with the predicted pose, associate events to projected segments,
// robust MM-estimation (Tukey bisquare: S-scale with c = 1.547, then MM with c = 4.685) of the pose.
// CONTRACT (issue 5 helpers): the names below are used by the estimator; extend, do not rename.

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/core/event.hpp"
#include "evpipe/pose/projection.hpp"
#include "evpipe/pose/robust_loss.hpp"
#include "evpipe/pose/types.hpp"
#include "evpipe/pose/verification.hpp"

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

namespace evpipe::pose {

struct TrackerOptions {
  // --- Event window. track_window() uses exactly the events it is given; these two say how the caller (the
  // estimator) should cut windows: the paper uses 30 ms event frames, ELOPET a pose every 10 ms.
  std::int64_t window_us = 30'000;  ///< length of the window handed to track_window()
  std::int64_t step_us = 10'000;    ///< time between successive updates (windows overlap when < window_us)
  std::size_t max_events = 0;       ///< > 0: use at most this many events of a window (uniform stride)

  // --- Projection and association (docs/algorithms.md, "Tracking").
  ProjectionOptions projection;
  AssociationOptions association;  ///< association.gate_px is the gate of the first round
  /// Rounds of (associate, S-scale, IRLS). Round 1 uses association.gate_px around the predicted pose; every
  /// later round re-associates around the pose of the previous one with gate = clamp(min(gate_shrink ×
  /// previous gate, gate_sigma_factor × sigma_S), gate_min_px, previous gate). 2 = re-associate once after
  /// convergence (unless the round stop below applies). From a poor prediction (recovery, a 5 cm / 10 deg prior) use a
  /// wide first gate and more rounds (e.g. gate_px = 40, association_rounds = 6): the gate then halves every round
  /// (coarse to fine).
  int association_rounds = 4;
  /// Stop before association_rounds once a round moved the projected model by less than this (pixels, largest
  /// move of a segment end) and the gate no longer shrinks: re-associating would change nothing that matters.
  /// 0 = always run every round.
  double round_tolerance_px = 0.05;
  /// > 0: before the first round, search image shifts of the projected model within ±coarse_search_px (step
  /// coarse_search_step_px) for the one that puts the most events within 1.5 px of a projected line (a
  /// distance transform of the rendered model), and turn the pose about the camera centre by that shift. For
  /// recovery from a poor prior (the shift is what a rotation/translation error mostly does to the image); off
  /// when tracking from the previous window.
  double coarse_search_px = 0.0;
  double coarse_search_step_px = 2.0;
  /// Recovery from a poor prior: also start from the prediction turned by ±k × recovery_roll_deg
  /// (k = 1..recovery_roll_steps) about the line of sight to the model (an image rotation, which the shift
  /// search cannot absorb) and tilted by ±recovery_tilt_deg about the camera's x and y axes through the model
  /// (out-of-plane turns change a 3D wireframe's appearance; the nearest-segment association then locks onto
  /// neighbouring edges), and keep the best result (healthy first, then the most inliers). 0 = off (tracking).
  double recovery_roll_deg = 0.0;
  int recovery_roll_steps = 0;
  double recovery_tilt_deg = 0.0;
  double gate_shrink = 0.5;
  double gate_sigma_factor = 4.0;
  double gate_min_px = 2.5;
  /// Fit each seen segment's own normal motion over the window (beta_k tau, tau = event time - the pose's time) with
  /// the pose and take it out of its events' residuals: a moving edge's events then lie on its line at the pose's
  /// time instead of in a band v × window wide, and structure moving otherwise beside it (another depth, another
  /// object) no longer averages into the line. Off: one line per segment for the whole window (the paper).
  bool segment_motion = true;

  // --- Robust estimation (paper eqs. 40-44).
  /// Tukey c of the S-scale step. Its b is not an option: b = E_Phi[rho_c_s] (robust_loss.hpp), 0.19950 at 1.547.
  double c_s = loss::kTukeyS;
  int s_max_iterations = 10;
  double c_mm = loss::kTukeyMM;  ///< Tukey c of the MM step
  /// The scale of an edge under background activity (docs/algorithms.md, "Scale under noise"). The S-scale breaks
  /// down once the association holds more background events than edge events (a sparse window's history, raw events
  /// under noise): it then measures the background's spread across the gate, and Tukey's weights at that scale let
  /// the gate's uneven background pull the pose. The associated residuals are a mixture of the edge's (Gaussian) and
  /// the background's (uniform, of the height the events away from the model give: events per pixel there × the
  /// projected model's length); the Gaussian's scale is fitted by EM with the uniform part fixed and, past the
  /// breakdown point (the mixture gives the edge under half the residuals), the IRLS weights use the smaller of it and
  /// the S-scale. The gate, the health tests and the covariance keep the S-scale. Off by default: fits from the truth
  /// stay on the edges (the board at 5 Hz/px raw: 0.4-0.5 deg off instead of up to 5), but in the pipeline it moved
  /// the marginal slow and stop runs both ways and raised the wrong confident poses beside the unseen planar decoys
  /// 23 -> 33-39 (docs/history.md, session 27).
  bool background_scale = false;
  /// The authors' demo-code variant instead (pose.md §7.4/7.5): scale and weights recomputed from the current
  /// residuals at every iteration with c = 4.685 for both passes, weights normalised to sum 1 and squared in
  /// the cost. For A/B comparisons only.
  bool lopet_compatible = false;

  // --- IRLS Levenberg-Marquardt on the 6 pose parameters (so(3) left increment, translation).
  int max_iterations = 20;           ///< per round
  double gradient_tolerance = 1e-9;  ///< stop when max|J^T W r| / sum(W) < this (normalised image units)
  double step_tolerance_rad = 1e-5;  ///< ... or the step is below both of these
  double step_tolerance_m = 1e-5;
  double cost_tolerance = 1e-5;  ///< ... or the robust cost changed by less than this fraction
  double lambda_initial = 1e-4;  ///< LM damping, relative to diag(J^T W J)

  // --- Health (TrackUpdate::healthy).
  double min_inlier_share = 0.05;  ///< inliers / window events
  std::size_t min_inliers = 100;
  double max_sigma_px = 2.0;            ///< largest acceptable S-scale
  std::size_t min_line_inliers = 15;    ///< a projected segment "is seen" with at least this many inliers
  double min_direction_angle_deg = 15;  ///< two seen segments at least this far from parallel are needed
  double max_condition = 1e7;           ///< of J^T W J with translations scaled by the mean depth
  /// A healthy update must also pass verify_pose() (verification.hpp) at its pose: supported along the model,
  /// beating the scene's other structure, all 6 DoF fixed. Off only for A/B comparisons.
  bool verify = true;
  VerifyOptions verification;

  // --- Covariance. The events of one edge are not independent measurements: where an edge runs nearly along a pixel
  // row or column its events fill the same pixels and share one quantisation offset, and its blur and the model's
  // error move them together. sigma^2 (J^T W J)^-1 counts every event; the covariance is scaled by inliers /
  // independent measurements, one per occupied cell along each segment. 0 (default): the cell is the run over which
  // the edge's quantisation is common, 1 / min(|sin|, |cos|) of its image angle (a 45° edge: 1.4 px; one 2° off a
  // pixel axis: 29 px); > 0: cells of that length; < 0: one per seen segment (the default before segment_motion;
  // measured mean NEES, docs/algorithms.md "Covariance").
  double covariance_cell_px = 0.0;
};

struct TrackUpdate {
  camera::Pose T_cam_model;
  Covariance6 covariance{Covariance6::Zero()};
  bool covariance_known{false};
  double sigma_px{0.0};  ///< robust (S) scale of the event-to-line distances, pixels
  /// segment_motion: the fastest normal speed of a seen segment's edge over the events (pixels per second).
  double max_edge_speed_px_s{0.0};
  std::size_t associated{0};  ///< events associated with a projected segment
  std::size_t inliers{0};     ///< associated events with non-zero final weight
  double inlier_share{0.0};   ///< inliers / events in the window
  int iterations{0};
  bool converged{false};
  bool healthy{false};              ///< enough inliers, lines in >= 2 directions, well conditioned
  std::string reason;               ///< why not healthy
  std::size_t segments_visible{0};  ///< projected model segments in the image at the final pose
  std::size_t lines_seen{0};        ///< projected segments with >= min_line_inliers inliers
  double condition{0.0};            ///< condition number of the depth-scaled J^T W J (0 when not computed)
  double gate_px{0.0};              ///< association gate of the last round
  int rounds{0};                    ///< association rounds run
  std::size_t covariance_cells{0};  ///< independent measurements the covariance counts (occupied cells)
  VerifyResult verification;        ///< of the final pose (when the update was otherwise healthy)
};

/// One tracking update on a window of events from the predicted pose. Never throws on degenerate input
/// (empty window, model out of view): healthy = false with a reason, the predicted pose returned.
/// `motion`: the pose at an earlier time (the last tracked one), for the verification's normal-flow test; without
/// it every visible segment must show support.
[[nodiscard]] TrackUpdate track_window(EventSpan events, const camera::CameraModel& camera,
                                       const camera::LineModel& model, const camera::Pose& T_predicted,
                                       const TrackerOptions& options = {},
                                       const std::optional<MotionHint>& motion = std::nullopt);

/// The same with an undistortion table built once for the camera (track_window above keeps one per thread).
[[nodiscard]] TrackUpdate track_window(EventSpan events, const UndistortMap& map, const camera::LineModel& model,
                                       const camera::Pose& T_predicted, const TrackerOptions& options = {},
                                       const std::optional<MotionHint>& motion = std::nullopt);

}  // namespace evpipe::pose
