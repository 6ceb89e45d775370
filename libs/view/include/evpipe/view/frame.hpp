#pragma once
// Building a preview frame (transport::PreviewRecord) from a window: the class image of the window's raw and kept
// events and the line model projected at a pose. No threads, no LCM: evpipe's preview worker calls these.

#include <cstdint>
#include <vector>

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/pose.hpp"
#include "evpipe/core/event.hpp"
#include "evpipe/transport/preview.hpp"

namespace evpipe::view {

/// At most this many image pixels per preview (a DAVIS346's 346 x 260 = 89 960 fit at bin 1): bounds the message
/// to 25 000 bytes of image (2 bits a pixel) whatever the sensor.
inline constexpr int kMaxPreviewPixels = 100'000;

/// At most this many model segments per preview (16 bytes each on the wire: 32 kB).
inline constexpr int kMaxPreviewSegments = 2048;

/// The preview image of a sensor: its size, binned so that it holds at most kMaxPreviewPixels pixels.
struct PreviewGrid {
  int bin = 1;
  int width = 0;
  int height = 0;
};
[[nodiscard]] PreviewGrid preview_grid(int sensor_width, int sensor_height);

/// Starts `r`'s image: grid size, every pixel `none`.
void start_image(transport::PreviewRecord& r, const PreviewGrid& grid);
/// Marks raw events with t_us in [t0_us, t1_us) (pixels still `none` become `raw`); returns how many there were.
/// Events outside the sensor are ignored.
std::int64_t mark_raw(transport::PreviewRecord& r, EventSpan events, std::int64_t t0_us, std::int64_t t1_us);
/// Marks kept events (the pixel takes the polarity of its latest kept event); returns how many.
std::int64_t mark_kept(transport::PreviewRecord& r, EventSpan events);

/// The model's segments projected at T_cam_model, distortion applied: a segment whose chord is long is cut into
/// pieces of about 16 pixels (at most 16, fewer for a model of many lines), each projected as a chord, so that a
/// distorted line is drawn curved. Segments behind the camera are clipped (camera::project_segment). At most
/// kMaxPreviewSegments (a model with more lines is drawn in part).
[[nodiscard]] std::vector<transport::PreviewSegment> project_model(const camera::CameraModel& camera,
                                                                   const camera::LineModel& model,
                                                                   const camera::Pose& T_cam_model);

}  // namespace evpipe::view
