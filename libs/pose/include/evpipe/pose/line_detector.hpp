#pragma once
// Event frame -> 2D line segments (LSD, double-response merging, robust refit on the supporting events).
// CONTRACT (issue 5 helpers): the names below are used by the initialiser; extend, do not rename.

#include "evpipe/camera/line_model.hpp"
#include "evpipe/core/event.hpp"

#include <cstddef>
#include <vector>

namespace evpipe::pose {

struct DetectedLine {
  camera::Segment2 segment_px;  ///< measured (distorted) pixel coordinates, refit to the supporting events
  std::size_t support{0};       ///< events within the fit band
  double rms_px{0.0};           ///< RMS perpendicular distance of the supporting events
};

struct LineDetectorOptions {
  // (the implementation adds its parameters here, documented)
};

/// Lines seen in a window of (denoised) events. Empty input gives an empty result.
[[nodiscard]] std::vector<DetectedLine> detect_lines(EventSpan events, SensorGeometry geometry,
                                                     const LineDetectorOptions& options = {});

}  // namespace evpipe::pose
