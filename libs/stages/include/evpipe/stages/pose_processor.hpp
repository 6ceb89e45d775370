#pragma once
// The pose stage's work (stages::WindowProcessor): the camera, line model and prior loaded once, the estimator run
// on each window (stamped at the window's middle), the initialisation worker protocol, the timing summary, and the
// trajectory CSV of published poses.
//
// Initialisation worker (options.init_worker): an attempt (OPnL + verification, 10-300 ms) runs on a niced
// background thread while the pose thread goes on returning `initialising` for the windows that arrive meanwhile
// (their events are kept in a bounded catch-up feed); the worker then tracks through that feed itself, and the
// first window after it ends applies the outcome. Without the worker the attempt runs in line.

#include <chrono>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "evpipe/camera/trajectory.hpp"
#include "evpipe/core/slicer.hpp"
#include "evpipe/pose/estimator.hpp"
#include "evpipe/runtime/background_task.hpp"
#include "evpipe/stages/pipeline.hpp"

namespace evpipe::stages {

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

/// What the pose stage is made from (evpipe fills it from the run configuration's pose and window sections).
struct PoseProcessorOptions {
  std::string camera;     ///< calibration YAML (required)
  std::string model;      ///< line model, YAML or DXF (required)
  std::string prior;      ///< pose prior YAML; empty = none
  std::string poses_out;  ///< trajectory CSV of the published poses; empty = none
  /// The program's input files: poses_out must not be one of them (refused before truncating).
  std::vector<std::string> inputs;
  pose::EstimatorOptions estimator;  ///< its track.window_us / step_us must be the windows the pipeline cuts
  bool init_worker = false;          ///< attempts on a background thread (see the top of this file)
  int init_worker_nice = 10;         ///< that thread's nice increment
};

/// Sees each window with its estimate on the pose thread (evpipe's preview). Must return quickly.
class WindowObserver {
 public:
  WindowObserver() = default;
  virtual ~WindowObserver() = default;
  WindowObserver(const WindowObserver&) = delete;
  WindowObserver& operator=(const WindowObserver&) = delete;
  virtual void on_window(const EventWindow& window, const pose::PoseEstimate& estimate) = 0;
};

class PoseProcessor final : public WindowProcessor {
 public:
  /// Loads camera, model and prior and creates the poses CSV. Throws std::invalid_argument naming the file and
  /// the field (a missing camera or model, a bad file, a CSV that cannot be created or is one of the inputs).
  static std::unique_ptr<PoseProcessor> create(const PoseProcessorOptions& options);
  ~PoseProcessor() override;
  PoseProcessor(const PoseProcessor&) = delete;
  PoseProcessor& operator=(const PoseProcessor&) = delete;

  /// Runs the estimator on one window (copied into one contiguous span only when it spans batches). With the
  /// initialisation worker an attempt is handed to it and this window and those after it return at once
  /// (`initialising`) until it is done. A window that starts a clock segment resets the track.
  pose::PoseEstimate process(const EventWindow& window) override;
  /// Writes a pose row (when poses_out is set); only valid poses. Publish thread.
  void write(const pose::PoseEstimate& estimate);
  /// Pose thread (set before the pipeline starts).
  void set_observer(WindowObserver* observer) noexcept { observer_ = observer; }

  /// Pose thread, or any thread once the pipeline has joined.
  [[nodiscard]] PoseSummary summary() const;

 private:
  PoseProcessor(pose::PoseEstimator estimator, std::optional<camera::TrajectoryCsvWriter> csv, std::string csv_path,
                bool init_worker, int init_worker_nice);
  /// init_ms: set to the worker's compute time when this window applied its successful attempt.
  pose::PoseEstimate estimate(EventSpan events, EventSpan raw, std::int64_t t_us, double& init_ms);

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
  std::unique_ptr<runtime::BackgroundTask<pose::InitOutcome>> init_worker_;
  std::optional<camera::TrajectoryCsvWriter> csv_;
  WindowObserver* observer_ = nullptr;
  PoseSummary summary_;
  std::vector<Event> scratch_;
  std::vector<Event> raw_scratch_;  // a window's unfiltered events when they span several batches
};

/// Without a camera and a model: every window gives an estimate that says so (the events still reach the observer).
class EventsOnlyProcessor final : public WindowProcessor {
 public:
  explicit EventsOnlyProcessor(WindowObserver* observer = nullptr) : observer_(observer) {}
  pose::PoseEstimate process(const EventWindow& window) override;

 private:
  WindowObserver* observer_;
};

/// The published row of an estimate (extra CSV columns after the eight of interfaces.md).
[[nodiscard]] std::vector<std::string> pose_csv_extra_columns();

}  // namespace evpipe::stages
