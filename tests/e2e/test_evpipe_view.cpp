// The operator's view end to end (issue 22): the real evpipe replays the bundled roadheader sample with the preview
// on, the real evpipe-view watches it in a window under Xvfb and saves a screenshot that must show model and event
// pixels; evpipe --video writes one decodable frame per window; evpipe-view says clearly what is wrong when the
// channel is silent or carries another message type.
#include <gtest/gtest.h>

#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <regex>
#include <thread>

#include "evpipe/transport/lcm_publisher.hpp"
#include "evpipe/view/render.hpp"
#include "evpipe_run.hpp"
#include "evpipe_test_data.hpp"
#include "lcm_net.hpp"

using evpipe::testing::json_field;
using evpipe::testing::q;

namespace {

const std::string kEvpipe = EVPIPE_EXE;
const std::string kView = EVPIPE_VIEW_EXE;
// A port of this process's own: without a private network namespace (no unshare), the tests of this file run in
// parallel (one ctest each) on the host's loopback, and a shared port would let one test's previews reach another's
// viewer (the "wrong channel" viewer would then see a valid preview).
const std::string kUrl = "udpm://239.255.76.67:" + std::to_string(20000 + ::getpid() % 20000) + "?ttl=0";

std::string sample_args() {
  const std::string stem = (evpipe::testing::source_dir() / "tests/data/roadheader-sample").string();
  return " --replay " + q(stem + ".aedat4") + " --camera " + q(stem + ".camera.yaml") + " --model " +
         q(stem + ".model.yaml") + " --prior " + q(stem + ".prior.yaml") + " --no-progress";
}

std::size_t count_colour(const cv::Mat& img, const cv::Vec3b& c) {
  std::size_t n = 0;
  for (int y = 0; y < img.rows; ++y)
    for (int x = 0; x < img.cols; ++x)
      if (img.at<cv::Vec3b>(y, x) == c) ++n;
  return n;
}

/// An Xvfb server on a free display for the test's lifetime.
class Xvfb {
 public:
  Xvfb() {
    if (std::system("command -v Xvfb >/dev/null 2>&1") != 0) {
      why_ = "Xvfb is not installed (Debian package xvfb, tools/setup.sh)";
      return;
    }
    for (int attempt = 0; attempt < 20 && display_.empty(); ++attempt) {
      const int n = 100 + static_cast<int>((getpid() + attempt * 7) % 400);
      if (std::filesystem::exists("/tmp/.X11-unix/X" + std::to_string(n))) continue;
      pidfile_ = evpipe::testing::temp_dir("xvfb") / "pid";
      const std::string cmd = "Xvfb :" + std::to_string(n) +
                              " -screen 0 1024x768x24 -nolisten tcp >/dev/null 2>&1 & echo $! > " +
                              q(pidfile_.string());
      if (std::system(cmd.c_str()) != 0) continue;
      for (int i = 0; i < 100; ++i) {
        if (std::filesystem::exists("/tmp/.X11-unix/X" + std::to_string(n))) {
          display_ = ":" + std::to_string(n);
          break;
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
      }
    }
    if (display_.empty()) why_ = "Xvfb did not start";
  }
  ~Xvfb() {
    if (!pidfile_.empty()) (void)std::system(("kill $(cat " + q(pidfile_.string()) + ") 2>/dev/null").c_str());
  }
  Xvfb(const Xvfb&) = delete;
  Xvfb& operator=(const Xvfb&) = delete;
  [[nodiscard]] const std::string& display() const { return display_; }
  [[nodiscard]] const std::string& why_not() const { return why_; }

 private:
  std::string display_;
  std::string why_;
  std::filesystem::path pidfile_;
};

}  // namespace

TEST(EvpipeView, WatchesAReplayUnderXvfbAndItsScreenshotShowsModelAndEvents) {
  const auto net = evpipe::testing::ensure_multicast_route();  // before any thread
  if (!net.ok) GTEST_SKIP() << "no multicast route for udpm:// on loopback: " << net.message;
  const Xvfb x;
  if (x.display().empty()) GTEST_SKIP() << x.why_not();
  const auto dir = evpipe::testing::temp_dir("e2e-view");
  const auto shot = dir / "shot.png";
  evpipe::testing::Run view;
  std::thread viewer([&] {
    // 12 previews: the sample is 3 s at --speed 1, 10 previews a second (slow sanitizer builds may drop some).
    view = evpipe::testing::run("DISPLAY=" + x.display() + " " + kView + " --lcm-url " + q(kUrl) +
                                    " --frames 12 --timeout 20 --screenshot " + q(shot.string()),
                                dir);
  });
  std::this_thread::sleep_for(std::chrono::milliseconds(1500));  // subscribed before the first preview
  const auto r =
      evpipe::testing::run(kEvpipe + sample_args() + " --speed 1 --preview --json --lcm-url " + q(kUrl), dir);
  viewer.join();
  ASSERT_EQ(r.status, 0) << r.err;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.err, m, std::regex("LCM preview: ([0-9]+) published"))) << r.err;
  EXPECT_GE(std::stoi(m[1]), 12) << r.err;  // 3 s at 10 Hz: 30 (fewer only if the builder was busy: dropped)
  // At most 10 Hz of the process's wall time (a sanitizer build's start-up and flush lengthen the 3 s: 32 in 3.5 s).
  const double wall_s = std::stod(json_field(r.out, "wall_s"));
  EXPECT_LE(std::stoi(m[1]), static_cast<int>(10.0 * wall_s) + 1) << r.err << "\nwall " << wall_s << " s";
  ASSERT_EQ(view.status, 0) << view.err;
  const cv::Mat img = cv::imread(shot.string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(img.empty()) << shot;
  EXPECT_EQ(img.cols, 692);
  const std::size_t model = count_colour(img, evpipe::view::kColourTracking) +
                            count_colour(img, evpipe::view::kColourHolding) +
                            count_colour(img, evpipe::view::kColourLost);
  const std::size_t events = count_colour(img, evpipe::view::kColourRaw) +
                             count_colour(img, evpipe::view::kColourKeptOn) +
                             count_colour(img, evpipe::view::kColourKeptOff);
  EXPECT_GT(model, 1000u) << "model pixels";
  EXPECT_GT(count_colour(img, evpipe::view::kColourKeptOn) + count_colour(img, evpipe::view::kColourKeptOff), 100u);
  EXPECT_GT(events, 2000u) << "event pixels";
}

TEST(EvpipeView, ReplayVideoHasOneFramePerWindow) {
  const auto dir = evpipe::testing::temp_dir("e2e-video");
  for (const std::string name : {"out.mp4", "out.avi"}) {
    const auto video = dir / name;
    const auto pngs = dir / ("png-" + name);
    const auto r = evpipe::testing::run(kEvpipe + sample_args() + " --speed max --no-lcm --json --video " +
                                            q(video.string()) + " --png-every 40 --png-dir " + q(pngs.string()),
                                        dir);
    ASSERT_EQ(r.status, 0) << r.err;
    const int windows = std::stoi(json_field(r.out, "windows"));
    EXPECT_EQ(windows, 100);
    EXPECT_NE(r.err.find("video: 100 frames of 692x"), std::string::npos) << r.err;
    // The file written: the one asked for, or the Motion JPEG fallback beside it (an FFmpeg without H.264/MPEG-4).
    std::smatch written;
    ASSERT_TRUE(std::regex_search(r.err, written, std::regex("written to (\\S+)"))) << r.err;
    const std::string file = written[1];
    EXPECT_TRUE(file == video.string() || file == std::filesystem::path(video).replace_extension(".avi").string())
        << file;
    cv::VideoCapture cap(file);
    ASSERT_TRUE(cap.isOpened()) << file;
    int frames = 0;
    cv::Mat f;
    while (cap.read(f)) {
      if (frames++ == 0) {
        EXPECT_EQ(f.cols, 692);
        EXPECT_EQ(f.rows, 520 + evpipe::view::status_band_height({}));
      }
    }
    EXPECT_EQ(frames, windows) << file;
    EXPECT_EQ(std::distance(std::filesystem::directory_iterator(pngs), std::filesystem::directory_iterator{}), 3);
  }
}

TEST(EvpipeView, SilentOrWrongChannelGivesAClearMessage) {
  const auto net = evpipe::testing::ensure_multicast_route();
  if (!net.ok) GTEST_SKIP() << "no multicast route for udpm:// on loopback: " << net.message;
  const auto dir = evpipe::testing::temp_dir("e2e-view-bad");
  // Poses on the preview channel: another type.
  std::atomic<bool> done{false};
  std::thread talker([&] {
    evpipe::transport::LcmPublisher pub(kUrl, "EVPIPE_PREVIEW", "EVPIPE_STATS");
    while (!done) {
      pub.publish_pose({});
      std::this_thread::sleep_for(std::chrono::milliseconds(50));
    }
  });
  const auto wrong =
      evpipe::testing::run(kView + " --headless --frames 1 --timeout 2 --screenshot x.png --lcm-url " + q(kUrl), dir);
  const auto silent = evpipe::testing::run(
      kView + " --headless --frames 1 --timeout 2 --screenshot x.png --channel NOPE --lcm-url " + q(kUrl), dir);
  done = true;
  talker.join();
  EXPECT_EQ(wrong.status, 1);
  EXPECT_NE(wrong.err.find("is not an evpipe preview_t"), std::string::npos) << wrong.err;
  EXPECT_EQ(silent.status, 1);
  EXPECT_NE(silent.err.find("no message on NOPE"), std::string::npos) << silent.err;
  EXPECT_NE(silent.err.find("EVPIPE_PREVIEW"), std::string::npos) << "the channels seen: " << silent.err;
  // No display and no --headless: a usage error, not a crash.
  const auto no_display = evpipe::testing::run("env -u DISPLAY -u WAYLAND_DISPLAY " + kView + " --frames 1", dir);
  EXPECT_EQ(no_display.status, 2);
  EXPECT_NE(no_display.err.find("no display"), std::string::npos) << no_display.err;
  // A display that does not answer: also a clear usage error (OpenCV's Qt backend would abort).
  const auto dead_display = evpipe::testing::run("DISPLAY=:987 " + kView + " --frames 1", dir);
  EXPECT_EQ(dead_display.status, 2);
  EXPECT_NE(dead_display.err.find("no X server answers"), std::string::npos) << dead_display.err;
  EXPECT_FALSE(std::filesystem::exists(dir / "x.png"));
}
