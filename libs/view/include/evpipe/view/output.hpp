#pragma once
// Video and PNG output through libevpipe_view_output.so, loaded with dlopen on first use (output_module.h says why).
// Looked for: $EVPIPE_VIEW_OUTPUT (a path), beside the program's install (<bin>/../lib/evpipe/), then the build tree.

#include <cstdint>
#include <memory>
#include <string>

#include <opencv2/core.hpp>

namespace evpipe::view {

struct OutputModule;

class FrameOutput {
 public:
  /// Loads the module. Throws std::runtime_error saying where it looked and why it failed.
  FrameOutput();
  ~FrameOutput();
  FrameOutput(const FrameOutput&) = delete;
  FrameOutput& operator=(const FrameOutput&) = delete;

  /// Video (one at a time): opened on the first frame; throws std::runtime_error naming the file on failure.
  void open_video(const std::string& path, double fps);
  void write_video(const cv::Mat& bgr);
  void close_video();
  struct VideoInfo {
    std::string path, codec;
    std::int64_t frames = 0;
    int width = 0, height = 0;
  };
  [[nodiscard]] VideoInfo video_info() const;

  /// Throws std::runtime_error naming the file when it cannot be written.
  void write_png(const std::string& path, const cv::Mat& bgr);

 private:
  std::unique_ptr<OutputModule> module_;
  void* video_ = nullptr;
  VideoInfo last_info_;
};

}  // namespace evpipe::view
