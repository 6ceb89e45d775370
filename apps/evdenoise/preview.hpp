#pragma once
// `evdenoise --png`: a grid of 30 ms event frames, the input on the top row and the filter's output below, one
// column per frame (like the paper's figures 8–9). Frames are spread evenly over the recording, or consecutive
// from its start when it is shorter than four frames.
//
// Cell = one sensor image at 1x: white background, red = ON, blue = OFF (the last event of a pixel wins).
// Layout: grey gaps of kGap px around cells, a caption bar of kCaption px above each cell.
//   width  = F·W + (F + 1)·kGap,   height = 2·(kCaption + H) + 3·kGap

#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "evpipe/core/event.hpp"

namespace evdenoise {

class Preview {
 public:
  static constexpr std::int64_t kFrame_us = 30'000;
  static constexpr int kMaxFrames = 4;
  static constexpr int kGap = 4;
  static constexpr int kCaption = 20;

  /// Frames for a recording whose events lie in [t_first_us, t_last_us] (t_last_us < t_first_us: no events).
  Preview(const evpipe::SensorGeometry& geometry, std::int64_t t_first_us, std::int64_t t_last_us);

  void add_input(const evpipe::Event& e) { add(e, 0); }
  void add_output(const evpipe::Event& e) { add(e, 1); }

  /// Writes the grid; `filter` labels the bottom row. Throws std::runtime_error naming the path on failure.
  void write(const std::string& path, const std::string& filter) const;

  [[nodiscard]] int frames() const noexcept { return static_cast<int>(t0_us_.size()); }
  [[nodiscard]] static cv::Size grid_size(const evpipe::SensorGeometry& g, int frames) {
    return {frames * g.width + (frames + 1) * kGap, 2 * (kCaption + g.height) + 3 * kGap};
  }

 private:
  void add(const evpipe::Event& e, int row);

  evpipe::SensorGeometry geometry_;
  std::int64_t origin_us_;
  std::vector<std::int64_t> t0_us_;
  std::vector<cv::Mat> cells_[2];         // [row][frame], CV_8UC3
  std::vector<std::uint64_t> counts_[2];  // events drawn per cell
};

}  // namespace evdenoise
