#include "preview.hpp"

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <stdexcept>

namespace evdenoise {

Preview::Preview(const evpipe::SensorGeometry& geometry, std::int64_t t_first_us, std::int64_t t_last_us)
    : geometry_(geometry), origin_us_(t_first_us) {
  const std::int64_t span_us = t_last_us >= t_first_us ? t_last_us - t_first_us + 1 : 0;
  if (span_us >= kMaxFrames * kFrame_us) {
    // Evenly spread: first frame at the start, last one ending at the last event.
    const std::int64_t room_us = span_us - kFrame_us;
    for (int k = 0; k < kMaxFrames; ++k) {
      t0_us_.push_back(t_first_us + room_us * k / (kMaxFrames - 1));
    }
  } else {
    const auto n = std::max<std::int64_t>(1, (span_us + kFrame_us - 1) / kFrame_us);
    for (std::int64_t k = 0; k < n; ++k) {
      t0_us_.push_back(t_first_us + k * kFrame_us);
    }
  }
  for (int row = 0; row < 2; ++row) {
    for (std::size_t k = 0; k < t0_us_.size(); ++k) {
      cells_[row].emplace_back(geometry_.height, geometry_.width, CV_8UC3, cv::Scalar(255, 255, 255));
    }
    counts_[row].assign(t0_us_.size(), 0);
  }
}

void Preview::add(const evpipe::Event& e, int row) {
  if (!geometry_.contains(e.x, e.y)) {
    return;
  }
  for (std::size_t k = 0; k < t0_us_.size(); ++k) {
    if (e.t_us >= t0_us_[k] && e.t_us < t0_us_[k] + kFrame_us) {
      // BGR: red ON, blue OFF (as evsim --png).
      cells_[row][k].at<cv::Vec3b>(e.y, e.x) = e.polarity ? cv::Vec3b(0, 0, 255) : cv::Vec3b(255, 0, 0);
      ++counts_[row][k];
    }
  }
}

void Preview::write(const std::string& path, const std::string& filter) const {
  const int frames_n = frames();
  cv::Mat img(grid_size(geometry_, frames_n), CV_8UC3, cv::Scalar(160, 160, 160));
  for (int row = 0; row < 2; ++row) {
    const int y0 = kGap + row * (kCaption + geometry_.height + kGap);
    for (int k = 0; k < frames_n; ++k) {
      const int x0 = kGap + k * (geometry_.width + kGap);
      const auto kk = static_cast<std::size_t>(k);
      const cv::Rect caption(x0, y0, geometry_.width, kCaption);
      img(caption).setTo(cv::Scalar(235, 235, 235));
      const double from_ms = static_cast<double>(t0_us_[kk] - origin_us_) / 1000.0;
      const std::string text =
          row == 0 ? fmt::format("raw {:.1f}-{:.1f} ms: {} ev", from_ms, from_ms + kFrame_us / 1000.0, counts_[0][kk])
                   : fmt::format("{}: {} ev ({:.0f}%)", filter, counts_[1][kk],
                                 counts_[0][kk] > 0
                                     ? 100.0 * static_cast<double>(counts_[1][kk]) / static_cast<double>(counts_[0][kk])
                                     : 0.0);
      cv::putText(img(caption), text, cv::Point(4, kCaption - 6), cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1,
                  cv::LINE_AA);
      cells_[row][kk].copyTo(img(cv::Rect(x0, y0 + kCaption, geometry_.width, geometry_.height)));
    }
  }
  bool ok = false;
  try {
    ok = cv::imwrite(path, img);
  } catch (const cv::Exception& e) {
    throw std::runtime_error(fmt::format("{}: could not write the image: {}", path, e.what()));
  }
  if (!ok) {
    throw std::runtime_error(path + ": could not write the image");
  }
}

}  // namespace evdenoise
