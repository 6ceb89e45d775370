#include "evpipe/view/frame.hpp"

#include <algorithm>
#include <cmath>

namespace evpipe::view {

PreviewGrid preview_grid(int sensor_width, int sensor_height) {
  PreviewGrid g;
  const int w = std::max(sensor_width, 1);
  const int h = std::max(sensor_height, 1);
  for (g.bin = 1;; ++g.bin) {
    g.width = (w + g.bin - 1) / g.bin;
    g.height = (h + g.bin - 1) / g.bin;
    if (static_cast<std::int64_t>(g.width) * g.height <= kMaxPreviewPixels) return g;
  }
}

void start_image(transport::PreviewRecord& r, const PreviewGrid& grid) {
  r.width = grid.width;
  r.height = grid.height;
  r.bin = grid.bin;
  r.pixels.assign(static_cast<std::size_t>(grid.width) * static_cast<std::size_t>(grid.height),
                  static_cast<std::uint8_t>(transport::PreviewPixel::none));
}

namespace {

// Index of an event's pixel, or -1 outside the image.
std::int64_t pixel_index(const transport::PreviewRecord& r, const Event& e) {
  const int x = e.x / r.bin;
  const int y = e.y / r.bin;
  if (x >= r.width || y >= r.height) return -1;
  return static_cast<std::int64_t>(y) * r.width + x;
}

}  // namespace

std::int64_t mark_raw(transport::PreviewRecord& r, EventSpan events, std::int64_t t0_us, std::int64_t t1_us) {
  const auto by_time = [](const Event& e, std::int64_t t) { return e.t_us < t; };
  const auto begin = std::lower_bound(events.begin(), events.end(), t0_us, by_time);
  const auto end = std::lower_bound(begin, events.end(), t1_us, by_time);
  for (auto it = begin; it != end; ++it) {
    const auto i = pixel_index(r, *it);
    if (i < 0) continue;
    auto& p = r.pixels[static_cast<std::size_t>(i)];
    if (p == static_cast<std::uint8_t>(transport::PreviewPixel::none))
      p = static_cast<std::uint8_t>(transport::PreviewPixel::raw);
  }
  return end - begin;
}

std::int64_t mark_kept(transport::PreviewRecord& r, EventSpan events) {
  for (const auto& e : events) {
    const auto i = pixel_index(r, e);
    if (i < 0) continue;
    r.pixels[static_cast<std::size_t>(i)] =
        static_cast<std::uint8_t>(e.polarity ? transport::PreviewPixel::kept_on : transport::PreviewPixel::kept_off);
  }
  return static_cast<std::int64_t>(events.size());
}

std::vector<transport::PreviewSegment> project_model(const camera::CameraModel& camera, const camera::LineModel& model,
                                                     const camera::Pose& T_cam_model) {
  constexpr double kPiece_px = 16.0;
  constexpr int kMaxPieces = 16;
  // Pieces per line shrink with the model's size, so that a large CAD model stays within kMaxPreviewSegments.
  const int lines = std::max<int>(static_cast<int>(model.segments_m.size()), 1);
  const int max_pieces = std::clamp(kMaxPreviewSegments / lines, 1, kMaxPieces);
  std::vector<transport::PreviewSegment> out;
  const auto add = [&out](const camera::Segment2& s) {
    out.push_back({static_cast<float>(s.a_px.x()), static_cast<float>(s.a_px.y()), static_cast<float>(s.b_px.x()),
                   static_cast<float>(s.b_px.y())});
  };
  for (const auto& seg : model.segments_m) {
    if (out.size() >= static_cast<std::size_t>(kMaxPreviewSegments)) break;  // a model of more lines than that
    const auto chord = camera::project_segment(camera, T_cam_model, seg);
    if (!chord) continue;
    const double len = (chord->b_px - chord->a_px).norm();
    if (!std::isfinite(len)) continue;
    const int pieces =
        camera.has_distortion() ? std::clamp(static_cast<int>(std::ceil(len / kPiece_px)), 1, max_pieces) : 1;
    if (pieces == 1) {
      add(*chord);
      continue;
    }
    for (int k = 0; k < pieces; ++k) {
      camera::Segment3 piece;
      piece.a_m = seg.a_m + (seg.b_m - seg.a_m) * (static_cast<double>(k) / pieces);
      piece.b_m = seg.a_m + (seg.b_m - seg.a_m) * (static_cast<double>(k + 1) / pieces);
      if (const auto p = camera::project_segment(camera, T_cam_model, piece)) add(*p);
    }
  }
  return out;
}

}  // namespace evpipe::view
