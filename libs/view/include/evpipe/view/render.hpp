#pragma once
// Drawing a preview frame (evpipe-view, evpipe --video / --png-every): raw events grey, kept events coloured by
// polarity, the model green when tracking, amber when holding, red when lost or initialising, a status band below.
// Colours are exact (no anti-aliasing), so that tests and tools can count them.

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "evpipe/transport/preview.hpp"

namespace evpipe::view {

struct RenderOptions {
  bool show_raw = true;     ///< pixels with raw events only (removed by the denoiser), grey
  bool show_kept = true;    ///< kept events by polarity (off: kept pixels are drawn grey like raw ones)
  int zoom = 2;             ///< output pixels per sensor pixel
  bool status_band = true;  ///< the status lines under the image
  bool paused = false;      ///< marks the band "PAUSED"
};

/// A BGR colour (constexpr; converts to cv::Vec3b).
struct Colour {
  std::uint8_t b = 0, g = 0, r = 0;
  // NOLINTNEXTLINE(google-explicit-constructor): used where OpenCV wants a pixel value
  operator cv::Vec3b() const { return {b, g, r}; }
};
inline constexpr Colour kColourBackground{0, 0, 0};
inline constexpr Colour kColourRaw{80, 80, 80};
inline constexpr Colour kColourKeptOn{255, 170, 40};   // azure
inline constexpr Colour kColourKeptOff{230, 60, 230};  // violet
inline constexpr Colour kColourTracking{0, 220, 0};    // green
inline constexpr Colour kColourHolding{0, 170, 255};   // amber
inline constexpr Colour kColourLost{0, 0, 255};        // red (lost, initialising)

/// The model's colour for a wire status (3 = holding, see transport::kPreviewStatusHolding).
[[nodiscard]] Colour model_colour(std::int8_t status);
/// Height of the status band in output pixels (0 without it).
[[nodiscard]] int status_band_height(const RenderOptions& options);
/// Output size for a frame of this image size.
[[nodiscard]] cv::Size render_size(const transport::PreviewRecord& r, const RenderOptions& options);
/// The status text, one entry per band line.
[[nodiscard]] std::vector<std::string> status_lines(const transport::PreviewRecord& r);
/// The picture (CV_8UC3).
[[nodiscard]] cv::Mat render_preview(const transport::PreviewRecord& r, const RenderOptions& options = {});
/// A placeholder of the same layout with a message (evpipe-view while it waits).
[[nodiscard]] cv::Mat render_message(cv::Size size, const std::string& line1, const std::string& line2 = {});

}  // namespace evpipe::view
