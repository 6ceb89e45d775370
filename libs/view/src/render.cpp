#include "evpipe/view/render.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace evpipe::view {

namespace {
constexpr int kLine_px = 18;
constexpr int kBandLines = 3;
constexpr double kFontScale = 0.45;
constexpr Colour kTextColour{230, 230, 230};

cv::Scalar scalar(const Colour& c) {
  return {static_cast<double>(c.b), static_cast<double>(c.g), static_cast<double>(c.r)};
}
}  // namespace

Colour model_colour(std::int8_t status) {
  switch (status) {
    case transport::kPreviewStatusTracking:
      return kColourTracking;
    case transport::kPreviewStatusHolding:  // 3: holding (pose_t STATUS_HOLDING)
      return kColourHolding;
    default:  // initialising, lost, anything unknown
      return kColourLost;
  }
}

int status_band_height(const RenderOptions& options) {
  return options.status_band ? kBandLines * kLine_px + 6 : 0;
}

cv::Size render_size(const transport::PreviewRecord& r, const RenderOptions& options) {
  const int s = std::max(options.zoom, 1) * std::max(r.bin, 1);
  return {r.width * s, r.height * s + status_band_height(options)};
}

std::vector<std::string> status_lines(const transport::PreviewRecord& r) {
  std::vector<std::string> lines;
  std::string status(transport::preview_status_name(r.status));
  std::transform(status.begin(), status.end(), status.begin(), [](unsigned char c) { return std::toupper(c); });
  lines.push_back(fmt::format("t {:.3f} s  {}  inliers {}/{} ({:.0f} %)  scale {:.2f} px",
                              static_cast<double>(r.t_us) * 1e-6, status, r.inliers, r.pose_events,
                              100.0 * r.inlier_share(), r.sigma_px));
  const double w = r.window_s() > 0 ? r.window_s() : 1.0;
  lines.push_back(
      fmt::format("events {:.0f} k/s raw, {:.0f} k/s kept  latency {:.2f} ms (p99 {:.2f})  drops {} (previews {})",
                  r.raw_events / w * 1e-3, r.kept_events / w * 1e-3, r.latency_ms, r.latency_p99_ms, r.queue_drops,
                  r.previews_dropped));
  lines.push_back(r.note.empty() ? std::string() : r.note);
  return lines;
}

cv::Mat render_preview(const transport::PreviewRecord& r, const RenderOptions& options) {
  const int zoom = std::max(options.zoom, 1);
  const int s = zoom * std::max(r.bin, 1);
  const cv::Size size = render_size(r, options);
  cv::Mat img(size, CV_8UC3, scalar(kColourBackground));
  for (int y = 0; y < r.height; ++y) {
    for (int x = 0; x < r.width; ++x) {
      const auto code = static_cast<transport::PreviewPixel>(r.pixels[static_cast<std::size_t>(y) * r.width + x]);
      const Colour* colour = nullptr;
      switch (code) {
        case transport::PreviewPixel::none:
          break;
        case transport::PreviewPixel::raw:
          if (options.show_raw) colour = &kColourRaw;
          break;
        case transport::PreviewPixel::kept_on:
          colour = options.show_kept ? &kColourKeptOn : (options.show_raw ? &kColourRaw : nullptr);
          break;
        case transport::PreviewPixel::kept_off:
          colour = options.show_kept ? &kColourKeptOff : (options.show_raw ? &kColourRaw : nullptr);
          break;
      }
      if (colour) img(cv::Rect(x * s, y * s, s, s)).setTo(scalar(*colour));
    }
  }
  const cv::Scalar model = scalar(model_colour(r.status));
  const int thickness = 1;  // thin: the kept events on the edges stay visible beside it
  for (const auto& seg : r.segments) {
    // Clip far-away endpoints first: cv::line takes int coordinates.
    const auto clampf = [](float v) { return static_cast<int>(std::lround(std::clamp(v, -1e5F, 1e5F))); };
    cv::line(img, {clampf(seg.x0_px * static_cast<float>(zoom)), clampf(seg.y0_px * static_cast<float>(zoom))},
             {clampf(seg.x1_px * static_cast<float>(zoom)), clampf(seg.y1_px * static_cast<float>(zoom))}, model,
             thickness, cv::LINE_8);
  }
  if (options.status_band) {
    const int top = r.height * s;
    cv::Mat band = img(cv::Rect(0, top, size.width, size.height - top));
    band.setTo(cv::Scalar(40, 40, 40));
    auto lines = status_lines(r);
    if (options.paused) lines[2] = "PAUSED (space: resume, n: step)" + (lines[2].empty() ? "" : "  " + lines[2]);
    for (std::size_t i = 0; i < lines.size(); ++i) {
      cv::putText(img, lines[i], {6, top + kLine_px * static_cast<int>(i + 1)}, cv::FONT_HERSHEY_SIMPLEX, kFontScale,
                  i == 0 ? model : scalar(kTextColour), 1, cv::LINE_8);
    }
  }
  return img;
}

cv::Mat render_message(cv::Size size, const std::string& line1, const std::string& line2) {
  cv::Mat img(size, CV_8UC3, cv::Scalar(20, 20, 20));
  cv::putText(img, line1, {10, size.height / 2 - 10}, cv::FONT_HERSHEY_SIMPLEX, kFontScale, scalar(kTextColour), 1,
              cv::LINE_8);
  if (!line2.empty())
    cv::putText(img, line2, {10, size.height / 2 + 12}, cv::FONT_HERSHEY_SIMPLEX, kFontScale, scalar(kTextColour), 1,
                cv::LINE_8);
  return img;
}

}  // namespace evpipe::view
