// The preview frame (issue 22): class image of raw and kept events, model projection, the renderer's colours per
// status (holding = 3 amber) and toggles, and a video that decodes to the frames written.
#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/videoio.hpp>

#include "evpipe/view/frame.hpp"
#include "evpipe/view/render.hpp"
#include "evpipe/view/video.hpp"

using namespace evpipe;
using transport::PreviewPixel;

namespace {

std::size_t count_colour(const cv::Mat& img, const cv::Vec3b& c) {
  std::size_t n = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      if (img.at<cv::Vec3b>(y, x) == c) ++n;
  return n;
}

transport::PreviewRecord frame_with(std::int8_t status) {
  transport::PreviewRecord r;
  view::start_image(r, view::preview_grid(346, 260));
  r.window_t1_us = 30'000;
  r.status = status;
  const std::vector<Event> raw = {{100, 10, 10, true}, {200, 20, 20, false}, {40'000, 30, 30, true}};
  const std::vector<Event> kept = {{100, 10, 10, true}};
  EXPECT_EQ(view::mark_raw(r, raw, 0, 30'000), 2);  // the third is outside the window
  EXPECT_EQ(view::mark_kept(r, kept), 1);
  r.segments = {{50, 50, 300, 50}};
  return r;
}

}  // namespace

TEST(PreviewFrame, GridBinsLargeSensorsOnly) {
  EXPECT_EQ(view::preview_grid(346, 260).bin, 1);
  const auto g = view::preview_grid(1280, 720);
  EXPECT_EQ(g.bin, 4);
  EXPECT_LE(g.width * g.height, view::kMaxPreviewPixels);
}

TEST(PreviewFrame, MarksRawThenKeptByPolarity) {
  const auto r = frame_with(transport::kPreviewStatusTracking);
  EXPECT_EQ(r.pixels[10 * 346 + 10], static_cast<std::uint8_t>(PreviewPixel::kept_on));
  EXPECT_EQ(r.pixels[20 * 346 + 20], static_cast<std::uint8_t>(PreviewPixel::raw));
  EXPECT_EQ(r.pixels[30 * 346 + 30], static_cast<std::uint8_t>(PreviewPixel::none));
}

TEST(PreviewFrame, ProjectsTheModelAndCurvesDistortedLines) {
  camera::CameraModel cam;
  cam.fx = cam.fy = 300;
  cam.cx = 173;
  cam.cy = 130;
  camera::LineModel model;
  model.segments_m = {{{-0.2, 0, 0}, {0.2, 0, 0}}, {{0, 0, -2}, {0, 0, -1}}};  // the second is behind the camera
  camera::Pose pose;
  pose.t_cam_model_m = {0, 0.05, 1.0};
  auto segs = view::project_model(cam, model, pose);
  ASSERT_EQ(segs.size(), 1u);
  EXPECT_NEAR(segs[0].x0_px, 173 - 60, 1e-3);
  EXPECT_NEAR(segs[0].y0_px, 130 + 15, 1e-3);
  cam.k1 = -0.3;
  segs = view::project_model(cam, model, pose);
  EXPECT_GT(segs.size(), 4u);  // ~120 px: pieces of ~16 px
}

TEST(PreviewRender, ModelColourFollowsTheStatus) {
  for (const auto& [status, colour] : {std::pair{transport::kPreviewStatusTracking, view::kColourTracking},
                                       std::pair{transport::kPreviewStatusHolding, view::kColourHolding},
                                       std::pair{transport::kPreviewStatusLost, view::kColourLost},
                                       std::pair{transport::kPreviewStatusInitialising, view::kColourLost}}) {
    const auto img = view::render_preview(frame_with(status));
    EXPECT_EQ(img.cols, 692);
    EXPECT_EQ(img.rows, 520 + view::status_band_height({}));
    EXPECT_GT(count_colour(img, colour), 400u) << int(status);  // a 250 px line at zoom 2
  }
}

TEST(PreviewRender, TogglesRawAndKept) {
  const auto r = frame_with(transport::kPreviewStatusTracking);
  auto img = view::render_preview(r);
  EXPECT_EQ(count_colour(img, view::kColourKeptOn), 4u);  // one event at zoom 2
  EXPECT_EQ(count_colour(img, view::kColourRaw), 4u);
  view::RenderOptions o;
  o.show_raw = false;
  img = view::render_preview(r, o);
  EXPECT_EQ(count_colour(img, view::kColourRaw), 0u);
  EXPECT_EQ(count_colour(img, view::kColourKeptOn), 4u);
  o.show_raw = true;
  o.show_kept = false;
  img = view::render_preview(r, o);
  EXPECT_EQ(count_colour(img, view::kColourKeptOn), 0u);
  EXPECT_EQ(count_colour(img, view::kColourRaw), 8u);  // kept drawn as raw
}

TEST(PreviewVideo, WritesFramesThatDecodeBack) {
  const auto dir = std::filesystem::temp_directory_path() / "evpipe-test-view";
  std::filesystem::create_directories(dir);
  for (const std::string name : {"v.avi", "v.mp4"}) {
    const auto path = (dir / name).string();
    std::filesystem::remove(path);
    view::VideoOut out(path, 33.3);
    const auto img = view::render_preview(frame_with(transport::kPreviewStatusTracking));
    for (int i = 0; i < 12; ++i) out.write(img);
    out.close();
    cv::VideoCapture cap(out.path());
    ASSERT_TRUE(cap.isOpened()) << out.path() << " (" << out.codec() << ")";
    int frames = 0;
    cv::Mat f;
    while (cap.read(f)) {
      ++frames;
      EXPECT_EQ(f.cols, 692);
      EXPECT_EQ(f.rows, img.rows);
    }
    EXPECT_EQ(frames, 12) << out.path();
  }
}
