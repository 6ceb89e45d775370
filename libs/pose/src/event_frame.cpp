#include "evpipe/pose/event_frame.hpp"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace evpipe::pose {

EventFrame accumulate_event_frame(EventSpan events, SensorGeometry geometry, const EventFrameOptions& options) {
  EventFrame f;
  f.width = std::max(0, geometry.width);
  f.height = std::max(0, geometry.height);
  f.counts.assign(static_cast<std::size_t>(f.width) * static_cast<std::size_t>(f.height), 0.0F);
  for (const Event& e : events) {
    if (!geometry.contains(e.x, e.y)) continue;
    f.counts[static_cast<std::size_t>(e.y) * static_cast<std::size_t>(f.width) + e.x] += 1.0F;
  }
  if (options.clip_count > 0.0F) {
    for (float& c : f.counts) c = std::min(c, options.clip_count);
  }
  f.image = f.counts;
  if (options.blur_sigma_px > 0.0 && std::isfinite(options.blur_sigma_px) && !f.image.empty()) {
    const cv::Mat src(f.height, f.width, CV_32F, f.counts.data());
    cv::Mat dst(f.height, f.width, CV_32F, f.image.data());  // writes into f.image in place
    cv::GaussianBlur(src, dst, cv::Size(0, 0), options.blur_sigma_px, options.blur_sigma_px, cv::BORDER_REPLICATE);
  }
  return f;
}

std::vector<std::uint8_t> to_u8(const EventFrame& frame) {
  std::vector<std::uint8_t> out(frame.image.size(), 0);
  float top = 0.0F;
  for (const float v : frame.image) top = std::max(top, v);
  if (top <= 0.0F) return out;
  const float scale = 255.0F / top;
  for (std::size_t i = 0; i < out.size(); ++i) {
    out[i] = static_cast<std::uint8_t>(std::clamp(std::lround(frame.image[i] * scale), 0L, 255L));
  }
  return out;
}

}  // namespace evpipe::pose
