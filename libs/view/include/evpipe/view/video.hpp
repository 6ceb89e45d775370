#pragma once
// Writing preview frames to a video file a normal player opens: MPEG-4 in .mp4 / .mkv through OpenCV's FFmpeg
// backend (Debian's libopencv-videoio), or Motion JPEG in .avi (OpenCV's own writer, no FFmpeg needed) - also the
// fallback when the FFmpeg writer cannot be opened (the file is then written beside the request as .avi).

#include <cstdint>
#include <memory>
#include <string>

#include <opencv2/core.hpp>

namespace cv {
class VideoWriter;
}

namespace evpipe::view {

class VideoOut {
 public:
  /// Opens on the first frame (its size fixes the video's). fps: frames per second of playback.
  VideoOut(std::string path, double fps);
  ~VideoOut();
  VideoOut(const VideoOut&) = delete;
  VideoOut& operator=(const VideoOut&) = delete;

  /// Throws std::runtime_error naming the file when no writer opens; a frame of another size is resized.
  void write(const cv::Mat& frame);
  /// Flushes and closes (also done by the destructor).
  void close();

  [[nodiscard]] const std::string& path() const noexcept { return path_; }  ///< the file written (after fallback)
  [[nodiscard]] std::int64_t frames() const noexcept { return frames_; }
  [[nodiscard]] cv::Size size() const noexcept { return size_; }
  [[nodiscard]] const std::string& codec() const noexcept { return codec_; }

 private:
  std::string path_;
  double fps_;
  std::unique_ptr<cv::VideoWriter> writer_;
  std::int64_t frames_ = 0;
  cv::Size size_;
  std::string codec_;
};

}  // namespace evpipe::view
