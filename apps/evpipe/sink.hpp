#pragma once
// evpipe's ends of the pipeline: the pose processor (the pose stage, or nothing when no camera/model is
// configured) and the sink on the publish thread (poses CSV, LCM pose and statistics messages, device-loss
// reporting, the samples kept for the ATE of a replay with ground truth).

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "evpipe/camera/pose.hpp"
#include "evpipe/pipeline/pipeline.hpp"
#include "evpipe/transport/lcm_publisher.hpp"
#include "pose_stage.hpp"

namespace evpipe::app {

class PreviewWorker;

/// Runs the pose stage on each window; without a pose stage every window gives an estimate that says so.
/// With a preview worker (--preview, --video), each window and its estimate are offered to it (preview.hpp).
class PoseProcessor final : public pipeline::WindowProcessor {
 public:
  explicit PoseProcessor(PoseStage* stage, PreviewWorker* preview = nullptr) : stage_(stage), preview_(preview) {}
  pose::PoseEstimate process(const EventWindow& window) override;

 private:
  PoseStage* stage_;
  PreviewWorker* preview_;
};

class AppSink final : public pipeline::PoseSink {
 public:
  /// publisher and stage may be null (no LCM / no pose stage). keep_for_ate: collect valid poses (replay with
  /// ground truth only: a live service would grow without bound).
  AppSink(transport::LcmPublisher* publisher, PoseStage* stage, bool live, bool keep_for_ate);

  void publish_pose(const pipeline::PoseSample& sample) override;
  /// Tells the preview worker each published pose's window -> LCM latency (set before the pipeline starts).
  void set_preview(PreviewWorker* preview) noexcept { preview_ = preview; }
  void publish_stats(const pipeline::PipelineStats& stats) override;

  /// Any thread: the latest statistics and the status of the latest pose.
  [[nodiscard]] std::optional<pipeline::PipelineStats> latest_stats() const;
  [[nodiscard]] pose::TrackStatus latest_status() const;
  /// After the pipeline has joined.
  [[nodiscard]] const std::vector<camera::StampedPose>& valid_poses() const { return valid_poses_; }
  [[nodiscard]] std::uint64_t poses_published() const { return poses_; }

 private:
  transport::LcmPublisher* publisher_;
  PoseStage* stage_;
  PreviewWorker* preview_ = nullptr;
  bool live_;
  bool keep_for_ate_;
  std::vector<camera::StampedPose> valid_poses_;
  std::uint64_t poses_ = 0;
  std::optional<camera::Pose> last_good_;
  std::int64_t last_t_us_ = 0;
  pipeline::SourceState last_source_state_ = pipeline::SourceState::starting;
  mutable std::mutex mutex_;  // guards the two below (read by the main and supervisor threads)
  std::optional<pipeline::PipelineStats> latest_stats_;
  pose::TrackStatus latest_status_ = pose::TrackStatus::initialising;
};

/// The one-line status for the progress bar and systemd's STATUS=.
[[nodiscard]] std::string status_line(const pipeline::PipelineStats& stats, pose::TrackStatus status, bool pose_on);

}  // namespace evpipe::app
