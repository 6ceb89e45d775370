#pragma once
// evpipe's pose stage wiring: the configured camera, line model and prior loaded once, the estimator run per
// window, its timing, and the trajectory CSV of published poses.

#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "evpipe/camera/trajectory.hpp"
#include "evpipe/config/run_config.hpp"
#include "evpipe/core/slicer.hpp"
#include "evpipe/pipeline/background_task.hpp"
#include "evpipe/pose/estimator.hpp"

namespace evpipe::app {

/// What the summary reports about the pose stage.
struct PoseSummary {
  bool enabled = false;
  std::uint64_t windows = 0;
  std::uint64_t valid_poses = 0;
  std::uint64_t windows_by_status[4] = {0, 0, 0, 0};  ///< indexed by pose::TrackStatus
  std::uint64_t init_attempts = 0, init_successes = 0, losses = 0;
  std::uint64_t holds = 0, hold_resumes = 0;  ///< tracking → holding, holding → tracking
  double first_init_ms = 0;                   ///< compute time of the first successful initialisation attempt
  bool init_worker = false;                   ///< attempts ran on a worker thread
  /// Pose-thread compute time per valid window (for percentiles): tracking updates, and with the worker also the
  /// window that applies an attempt (its catch-up included); not an attempt run in line.
  std::vector<double> update_ms;
  std::int64_t first_valid_t_us = 0, last_valid_t_us = 0;
  std::string poses_out;
  std::string last_note;  ///< the latest reason a window produced no valid pose
};

class PoseStage {
 public:
  /// Loads camera, model and prior named in cfg.pose and creates the poses CSV, which must not be one of `inputs`
  /// (the program's input files: refused before truncating). Throws config::ConfigError naming the file and field.
  static std::unique_ptr<PoseStage> create(const config::RunConfig& cfg, std::span<const std::string> inputs = {});
  ~PoseStage();
  PoseStage(const PoseStage&) = delete;
  PoseStage& operator=(const PoseStage&) = delete;

  /// Runs the estimator on one window (copied into one contiguous span when it spans batches). With the
  /// initialisation worker an attempt is handed to it and this window and those after it return at once
  /// (`initialising`) until it is done.
  pose::PoseEstimate process(const EventWindow& window);
  /// Writes a pose row (when --poses-out is set). Only valid poses are published.
  void write(const pose::PoseEstimate& estimate);
  void reset() { estimator_.reset(); }

  [[nodiscard]] PoseSummary summary() const;

 private:
  PoseStage(pose::PoseEstimator estimator, std::optional<camera::TrajectoryCsvWriter> csv, std::string csv_path,
            bool init_worker, int init_worker_nice);
  /// init_ms: set to the worker's compute time when this window applied its successful attempt.
  pose::PoseEstimate estimate(EventSpan events, std::int64_t t_us, double& init_ms);

  /// Events of the windows that pass while an attempt runs (appended by this thread), taken by the worker once
  /// its attempt has succeeded: it tracks them itself (PoseEstimator::advance_initialisation), so that the window
  /// applying the outcome is not held up by a catch-up of up to 8 updates.
  struct CatchUpFeed {
    std::mutex mutex;
    std::vector<Event> events;  ///< time-ordered, newer than the job's events
    std::int64_t newest_t_us = 0;
    std::int64_t window_t_us = 0;  ///< time of the newest window fed
  };
  void feed(EventSpan events, std::int64_t t_us);
  pose::InitOutcome run_attempt(const pose::InitJob& job);

  pose::PoseEstimator estimator_;
  CatchUpFeed feed_;
  // Declared after the estimator and the feed: destroyed (joined) first, while what its job reads still exists.
  std::unique_ptr<pipeline::BackgroundTask<pose::InitOutcome>> init_worker_;
  std::optional<camera::TrajectoryCsvWriter> csv_;
  PoseSummary summary_;
  std::vector<Event> scratch_;
};

/// Does cfg ask for initialisation on a worker thread (pose.init_worker, "auto" resolved)?
[[nodiscard]] bool init_on_worker(const config::RunConfig& cfg);

/// The published row of an estimate (extra CSV columns after the eight of interfaces.md).
[[nodiscard]] std::vector<std::string> pose_csv_extra_columns();

}  // namespace evpipe::app
