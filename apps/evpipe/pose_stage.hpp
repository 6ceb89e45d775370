#pragma once
// evpipe's pose stage wiring: the configured camera, line model and prior loaded once, the estimator run per
// window, its timing, and the trajectory CSV of published poses.

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "evpipe/camera/trajectory.hpp"
#include "evpipe/config/run_config.hpp"
#include "evpipe/core/slicer.hpp"
#include "evpipe/pose/estimator.hpp"

namespace evpipe::app {

/// What the summary reports about the pose stage.
struct PoseSummary {
  bool enabled = false;
  std::uint64_t windows = 0;
  std::uint64_t valid_poses = 0;
  std::uint64_t windows_by_status[3] = {0, 0, 0};
  std::uint64_t init_attempts = 0, init_successes = 0, losses = 0;
  double first_init_ms = 0;       ///< compute time of the window whose initialisation first succeeded
  std::vector<double> update_ms;  ///< compute time per tracked window (for percentiles)
  std::int64_t first_valid_t_us = 0, last_valid_t_us = 0;
  std::string poses_out;
  std::string last_note;  ///< the latest reason a window produced no valid pose
};

class PoseStage {
 public:
  /// Loads camera, model and prior named in cfg.pose. Throws config::ConfigError naming the file and field.
  static std::unique_ptr<PoseStage> create(const config::RunConfig& cfg);

  /// Runs the estimator on one window (copied into one contiguous span when it spans batches).
  pose::PoseEstimate process(const EventWindow& window);
  /// Writes a pose row (when --poses-out is set). Only valid poses are published.
  void write(const pose::PoseEstimate& estimate);
  void reset() { estimator_.reset(); }

  [[nodiscard]] PoseSummary summary() const;

 private:
  PoseStage(pose::PoseEstimator estimator, std::optional<camera::TrajectoryCsvWriter> csv, std::string csv_path);

  pose::PoseEstimator estimator_;
  std::optional<camera::TrajectoryCsvWriter> csv_;
  PoseSummary summary_;
  std::vector<Event> scratch_;
};

/// The published row of an estimate (extra CSV columns after the eight of interfaces.md).
[[nodiscard]] std::vector<std::string> pose_csv_extra_columns();

}  // namespace evpipe::app
