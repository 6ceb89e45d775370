#pragma once
// The --png figure of evpose-eval (docs/evpose-eval.md): x, y, z estimated vs truth over time (three panels, like
// the first rows of the paper's figure 13) and the error per axis over time (like its figure 14).

#include <cstdint>
#include <span>
#include <string>

#include "evpipe/camera/pose.hpp"
#include "evpipe/metrics/trajectory.hpp"

namespace evpose_eval {

struct PlotInput {
  std::span<const evpipe::camera::StampedPose> truth;  ///< drawn over its whole time span
  const evpipe::metrics::TrajectoryEval* eval = nullptr;
  std::int64_t max_gap_us = 100'000;  ///< the estimate's line is broken at larger gaps
  std::string title;                  ///< one or two lines, separated by '\n'
};

/// Draws the figure and writes it (format from the extension, normally .png).
/// @throws std::runtime_error naming the path when the image cannot be written.
void write_plot(const std::string& path, const PlotInput& in);

}  // namespace evpose_eval
