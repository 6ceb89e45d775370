#include "evpipe/view/video.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>
#include <stdexcept>

namespace evpipe::view {

VideoOut::VideoOut(std::string path, double fps) : path_(std::move(path)), fps_(fps > 0 ? fps : 30.0) {}

VideoOut::~VideoOut() {
  close();
}

void VideoOut::write(const cv::Mat& frame) {
  if (!writer_) {
    size_ = frame.size();
    writer_ = std::make_unique<cv::VideoWriter>();
    std::string ext = std::filesystem::path(path_).extension().string();
    for (auto& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (ext != ".avi") {
      // H.264 (libx264 in Debian's FFmpeg; small files, every player), else FFmpeg's own MPEG-4 part 2 encoder.
      if (writer_->open(path_, cv::CAP_FFMPEG, cv::VideoWriter::fourcc('a', 'v', 'c', '1'), fps_, size_, true)) {
        codec_ = "H.264 (FFmpeg)";
      } else if (writer_->open(path_, cv::CAP_FFMPEG, cv::VideoWriter::fourcc('m', 'p', '4', 'v'), fps_, size_, true)) {
        codec_ = "MPEG-4 (FFmpeg)";
      } else {
        const std::string fallback = std::filesystem::path(path_).replace_extension(".avi").string();
        spdlog::warn("video: cannot open an FFmpeg MPEG-4 writer for {}; writing Motion JPEG to {}", path_, fallback);
        path_ = fallback;
      }
    }
    if (!writer_->isOpened()) {
      if (!writer_->open(path_, cv::CAP_OPENCV_MJPEG, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), fps_, size_, true))
        throw std::runtime_error(fmt::format("{}: cannot open a video writer (MPEG-4 or Motion JPEG)", path_));
      codec_ = "MJPG (AVI)";
    }
  }
  if (frame.size() == size_) {
    writer_->write(frame);
  } else {
    cv::Mat resized;
    cv::resize(frame, resized, size_, 0, 0, cv::INTER_NEAREST);
    writer_->write(resized);
  }
  ++frames_;
}

void VideoOut::close() {
  if (writer_) writer_->release();
  writer_.reset();
}

}  // namespace evpipe::view
