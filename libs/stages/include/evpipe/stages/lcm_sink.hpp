#pragma once
// The publish stage's work (stages::PoseSink): each estimate goes to the poses CSV and, mapped once by to_record(),
// to LCM; the pipeline statistics go to LCM as stats_t; the camera-lost policy (a LOST pose message at once when the
// live camera disappears). Also keeps the valid poses for a replay's ATE and the latest status for the status line.

#include <cstdint>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "evpipe/camera/pose.hpp"
#include "evpipe/stages/pipeline.hpp"
#include "evpipe/transport/lcm_publisher.hpp"
#include "evpipe/transport/records.hpp"

namespace evpipe::stages {

class PoseProcessor;

/// The one mapping from an estimate to the wire record (pose_t): a new pose_t field is one line here.
[[nodiscard]] transport::PoseRecord to_record(const pose::PoseEstimate& estimate, bool source_connected);

/// Told each published pose's window -> LCM latency (evpipe's preview). Publish thread; must return at once.
class PublishObserver {
 public:
  PublishObserver() = default;
  virtual ~PublishObserver() = default;
  PublishObserver(const PublishObserver&) = delete;
  PublishObserver& operator=(const PublishObserver&) = delete;
  virtual void on_published(std::int64_t window_to_publish_ns) noexcept = 0;
};

class LcmSink final : public PoseSink {
 public:
  /// publisher and processor may be null (no LCM / no pose stage: then only statistics go out). keep_for_ate:
  /// collect valid poses (replay with ground truth only: a live service would grow without bound).
  LcmSink(transport::LcmPublisher* publisher, PoseProcessor* processor, bool live, bool keep_for_ate);

  void publish_pose(const PoseSample& sample) override;
  void publish_stats(const PipelineStats& stats) override;
  /// Set before the pipeline starts.
  void set_observer(PublishObserver* observer) noexcept { observer_ = observer; }

  /// Any thread: the latest statistics and the status of the latest pose.
  [[nodiscard]] std::optional<PipelineStats> latest_stats() const;
  [[nodiscard]] pose::TrackStatus latest_status() const;
  /// After the pipeline has joined.
  [[nodiscard]] const std::vector<camera::StampedPose>& valid_poses() const { return valid_poses_; }
  [[nodiscard]] std::uint64_t poses_published() const { return poses_; }

 private:
  transport::LcmPublisher* publisher_;
  PoseProcessor* processor_;
  PublishObserver* observer_ = nullptr;
  bool live_;
  bool keep_for_ate_;
  std::vector<camera::StampedPose> valid_poses_;
  std::uint64_t poses_ = 0;
  std::optional<camera::Pose> last_good_;
  std::int64_t last_t_us_ = 0;
  SourceState last_source_state_ = SourceState::starting;
  mutable std::mutex mutex_;  // guards the two below (read by the main and supervisor threads)
  std::optional<PipelineStats> latest_stats_;
  pose::TrackStatus latest_status_ = pose::TrackStatus::initialising;
};

/// The one-line status for the progress bar and systemd's STATUS=.
[[nodiscard]] std::string status_line(const PipelineStats& stats, pose::TrackStatus status, bool pose_on);

}  // namespace evpipe::stages
