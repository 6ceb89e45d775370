#pragma once
// A window of events accumulated into a count image (the "event frame" the line detector works on).

#include "evpipe/core/event.hpp"

#include <cstdint>
#include <vector>

namespace evpipe::pose {

struct EventFrameOptions {
  /// Gaussian blur of the count image (pixels; 0 = none). Joins the one-pixel gaps of a ridge so that a
  /// gradient-based detector sees one continuous edge.
  double blur_sigma_px = 1.0;
  /// Counts per pixel are clipped to this before blurring (0 = no clip): a hot or flickering pixel must not
  /// dominate the 8-bit scaling of the frame.
  float clip_count = 8.0F;
};

/// Row-major image, width x height.
struct EventFrame {
  int width{0};
  int height{0};
  std::vector<float> counts;  ///< events per pixel (both polarities), clipped, not blurred
  std::vector<float> image;   ///< counts blurred with options.blur_sigma_px (== counts when no blur)

  [[nodiscard]] float count(int x, int y) const { return counts[static_cast<std::size_t>(y) * width + x]; }
};

/// Accumulates the events (out-of-sensor coordinates are skipped) into a frame of the sensor's size.
[[nodiscard]] EventFrame accumulate_event_frame(EventSpan events, SensorGeometry geometry,
                                                const EventFrameOptions& options = {});

/// The blurred image scaled to 8 bits (row-major): the largest value maps to 255. What LSD takes.
[[nodiscard]] std::vector<std::uint8_t> to_u8(const EventFrame& frame);

}  // namespace evpipe::pose
