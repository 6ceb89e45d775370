#pragma once
// Event frame -> 2D line segments (LSD, double-response merging, robust refit on the supporting events).
// CONTRACT (issue 5 helpers): the names below are used by the initialiser; extend, do not rename.
//
// Pipeline (docs/algorithms.md, "Event frame and line segments"): count image of the window -> Gaussian blur ->
// OpenCV LSD -> anti-parallel double responses merged into their mid-line -> collinear fragments merged ->
// length gate -> each segment refit to the events within a band around it (Huber-weighted total least
// squares, endpoints from the extent of the support) -> duplicates after the refit removed.
// With a camera in the options all geometry is done in undistorted pixels (where the image of a 3D line is
// straight); the returned endpoints are mapped back to measured (distorted) pixels, so
// CameraModel::pixel_to_normalised() of both endpoints lies on the normalised image line.

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/core/event.hpp"
#include "evpipe/pose/event_frame.hpp"

#include <cstddef>
#include <optional>
#include <vector>

namespace evpipe::pose {

struct DetectedLine {
  camera::Segment2 segment_px;  ///< measured (distorted) pixel coordinates, refit to the supporting events
  std::size_t support{0};       ///< events within the fit band
  double rms_px{0.0};           ///< RMS perpendicular distance of the supporting events
};

struct LineDetectorOptions {
  EventFrameOptions frame;  ///< count image and blur given to LSD
  /// LSD's image scale (OpenCV default 0.8; 1.0 keeps the 346x260 frame's full resolution).
  double lsd_scale = 1.0;
  /// Calibration: when set, merging and refitting happen in undistorted pixels (straight lines) and the
  /// result is mapped back to measured pixels. Without it, measured pixels are treated as undistorted.
  std::optional<camera::CameraModel> camera;
  /// Double-response merge (pose.md §9.2): two segments within this angle (modulo 180°) ...
  double merge_angle_deg = 3.0;
  /// ... whose endpoints lie within this perpendicular distance of the other segment's line and whose
  /// extents overlap are the two flanks of one event ridge: replaced by their mid-line.
  double merge_distance_px = 4.0;
  /// Collinear fragments (angle as above) are joined when the endpoints of one lie within this distance of
  /// the other's line ...
  double collinear_distance_px = 2.0;
  /// ... and the gap between their extents along the line is at most this.
  double collinear_gap_px = 8.0;
  /// Segments shorter than this (after merging and after the refit) are dropped.
  double min_length_px = 15.0;
  /// Events within this perpendicular distance of a segment's line (and within its extent + band) support it.
  double fit_band_px = 2.5;
  /// Huber threshold of the robust total least squares refit (pixels).
  double huber_k_px = 1.0;
  /// Gather-and-refit rounds (the band follows the line).
  int fit_iterations = 4;
  /// Events a segment needs after the refit.
  std::size_t min_support = 20;
  /// Along the line, a 1-px bin belongs to the segment's extent when it holds at least this share of the
  /// median occupied bin's events (and at least 2 events); gaps of up to extent_gap_px empty bins are bridged.
  double extent_share = 0.25;
  double extent_gap_px = 3.0;
  /// A line (taken in order of decreasing support) is dropped when more than this share of its supporting
  /// events already supports a line kept before it: a duplicate of one ridge or a fragment at a junction.
  double max_shared_support = 0.5;
};

/// Lines seen in a window of (denoised) events. Empty input gives an empty result.
[[nodiscard]] std::vector<DetectedLine> detect_lines(EventSpan events, SensorGeometry geometry,
                                                     const LineDetectorOptions& options = {});

/// The raw LSD segments of a frame (measured pixels), before any merging: for diagnostics and tests.
[[nodiscard]] std::vector<camera::Segment2> lsd_segments(const EventFrame& frame, double lsd_scale = 1.0);

}  // namespace evpipe::pose
