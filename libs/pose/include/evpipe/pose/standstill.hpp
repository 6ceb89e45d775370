#pragma once
// Standstill evidence for a held pose (docs/algorithms.md, "Holding"): is a window's event activity near the
// projected model explained by the sensor's noise alone (the target is still), or is there an excess (it moves)
// or structured activity elsewhere that the model does not explain (it may have gone)?
//
// The model is projected once with the held pose. Every pixel is classed by its distance to the projected edges:
// `near` (<= band_px: where a still edge that starts to move makes its first events), `ring` (<= gate_px, the
// tracker's association gate: events of edges that moved off), `far` (> far_px: background, where the noise rate
// is measured), and the margin between ring and far (ignored). Under the noise model (background activity,
// Poisson, uniform over the sensor) the counts in near and ring have the expectation rate x area x time, with the
// rate measured in `far` over the whole hold; the test is the Poisson upper tail. Structured activity elsewhere is
// tested per 16 x 16 px cell on its far pixels, counting distinct pixels (a hot pixel counts once), with a
// Bonferroni correction over the cells.

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/pose.hpp"
#include "evpipe/core/event.hpp"
#include "evpipe/pose/projection.hpp"

#include <cstddef>
#include <cstdint>
#include <vector>

namespace evpipe::pose {

struct StandstillOptions {
  double band_px = 3.0;   ///< events within this of a projected edge are `near` (the first events of a restart)
  double gate_px = 10.0;  ///< ... within this, `ring` (events the tracker would associate: the edge moved off)
  double far_px = 20.0;   ///< events further than this from every edge are background
  /// The noise rate is measured on the background within this distance of the edges (the same part of the image:
  /// a denoiser's output is not uniform, it keeps fewer noise events near the sensor border, for one).
  double background_px = 40.0;
  int cell_px = 16;  ///< cells of the test for activity elsewhere
  /// One-sided significance of each Poisson test (the cell test divides it by the number of cells).
  double significance = 1e-3;
  /// Image motion (pixels) that the excess events near the model may stand for before the held pose must be
  /// measured again. Bound on the motion: an edge of L pixels moving by d pixels makes at least ~L d events
  /// (one per pixel it crosses at a contrast above the threshold; evsim's default edges make ~3.6), so the
  /// motion is at most excess / visible length.
  double max_motion_px = 1.0;
  /// ... or a window's significant excess of at least this many events near the model (motion along an edge makes
  /// none, so the length bound alone can miss a target whose moving edges are few): half the tracker's
  /// min_inliers, worth a measurement.
  double min_motion_events = 50.0;
  /// A significant motion too small to measure keeps the held pose only while the pose change it may stand for
  /// (the implied motion times the held model's pose_change_per_px()) stays within these:
  /// the error a confident pose must stay within (issue 21). A planar board's tilt changes its image by a fraction
  /// of a pixel per degree: 0.4 px of creep after the denoiser held a board 2.4 deg off.
  double max_rotation_deg = 2.0;
  double max_translation_m = 0.02;
  /// The hold's counts (noise rate, accumulated excess) forget with this time constant: a slow drift of the
  /// noise's spatial pattern (a denoiser's output is only roughly Poisson) must not add up to "motion" over a long
  /// stop. A creep of the target is still seen: it makes ~3.6 events per pixel of edge crossed, so at
  /// >= max_motion_px / (3.6 x memory) px/s the accumulated excess implies > max_motion_px.
  double memory_s = 1.0;
};

/// What one window (or the hold so far) says.
struct StandstillEvidence {
  std::size_t near{0}, ring{0}, far{0};  ///< events per class in the window
  double noise_rate_hz{0.0};             ///< per pixel, measured in `far` over the hold so far
  /// Per pixel, the window's background noise alone: `far` events in the cells whose counts the Poisson noise
  /// explains (cells significantly above the rate, clutter or a hot pixel, left out until none is). <= the window's
  /// `far` rate; the same on a uniform background.
  double background_rate_hz{0.0};
  double expected_near{0.0}, expected_ring{0.0};
  double implied_motion_px{0.0};  ///< excess in near + ring / visible length (window or hold, the larger)
  bool moving{false};             ///< significant excess near the model implying > max_motion_px (window or hold)
  bool unexplained{false};        ///< a cell away from the model with significantly more active pixels than noise
  bool signal{false};             ///< the window alone: significantly more events in `near` than the noise explains
};

/// P(X >= n) for X ~ Poisson(mu) (1 when n <= mu is not computed exactly: the test only needs small tails).
[[nodiscard]] double poisson_upper_tail(std::uint64_t n, double mu) noexcept;

class StandstillMonitor {
 public:
  StandstillMonitor() = default;
  /// Starts a hold at T_cam_model (projects the model, classes the pixels, clears the accumulated counts).
  /// False when no model edge is in view (nothing to hold on).
  bool start(const camera::CameraModel& camera, const UndistortMap& map, const camera::LineModel& model,
             const camera::Pose& T_cam_model, const StandstillOptions& options);
  /// One window of `window_us`. Its events from fresh_from_us on (the part not seen by the previous call when
  /// windows overlap), `fresh_us` long, add to the hold's totals (noise rate, accumulated excess).
  StandstillEvidence observe(EventSpan window, std::int64_t window_us, std::int64_t fresh_from_us,
                             std::int64_t fresh_us);
  [[nodiscard]] bool active() const noexcept { return !cls_.empty(); }
  void stop() noexcept;
  [[nodiscard]] double visible_length_px() const noexcept { return length_px_; }

 private:
  /// background_rate_hz of the window just counted.
  [[nodiscard]] double background_rate(double window_s) const;
  StandstillOptions o_;
  int width_{0}, height_{0};
  int cells_x_{0}, cells_y_{0};
  std::vector<std::uint8_t> cls_;  ///< per pixel: 0 far, 1 near, 2 ring, 3 margin, 4 far and within background_px
  std::vector<std::uint32_t> cell_far_area_;
  std::vector<std::uint32_t> stamp_;  ///< per pixel: the window that last counted it (distinct pixels per cell)
  std::vector<std::uint32_t> cell_count_;
  std::vector<std::uint32_t> cell_band_area_;   ///< per cell: its `far` pixels within background_px (class 4)
  std::vector<std::uint32_t> cell_band_count_;  ///< per cell: the window's events on them
  std::uint32_t window_id_{0};
  double area_near_{0}, area_ring_{0}, area_far_{0};
  double length_px_{0};
  // Totals over the hold (fresh events only).
  double acc_near_{0}, acc_ring_{0}, acc_far_{0}, acc_exposure_s_{0};
};

/// The largest pose change (rotation angle, translation) whose image moves the model's edges at T_cam_model across
/// themselves by 1 px RMS over their visible length (motion along an edge makes no event): what one pixel of a hold's
/// implied motion can stand for in the pose's weakest direction (a planar board's tilt: several degrees). Infinite
/// when the edges do not fix the pose.
struct PoseChangePerPx {
  double rotation_deg{0.0};
  double translation_m{0.0};
};
[[nodiscard]] PoseChangePerPx pose_change_per_px(const camera::CameraModel& camera, const camera::LineModel& model,
                                                 const camera::Pose& T_cam_model);

}  // namespace evpipe::pose
