#pragma once
// evpipe's preview (issue 22, docs/operations.md "Watching the pipeline"): what the pipeline saw in a window and
// where it put the model, as an LCM preview message (--preview, EVPIPE_PREVIEW) and/or a video (--video) and PNG
// stills (--png-every).
//
// Built so that the pose path never waits for it:
//  * The raw events come with the window: behind a filter the denoise stage attaches them (EventWindow::raw_parts,
//    shared batches, never copied), and a queued job keeps them alive; without a filter the window's events are the
//    raw ones.
//  * The pose thread offers a window and its estimate after the estimate is made (PoseProcessor): a relaxed
//    atomic store per window, and when a preview is due (preview_hz, host time) a try_lock'ed hand-off of the
//    window's pointers: a busy builder means the preview is dropped and counted, never a wait. Only a replay with
//    --video (every window, lossless) waits for the builder, so the video has every window.
//  * One builder thread (nice +10) rasterises raw and kept events, projects the model at the pose, publishes on
//    its own LCM instance (not the pose publisher's lock) and writes the video / PNGs.

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/core/slicer.hpp"
#include "evpipe/core/source.hpp"
#include "evpipe/pose/estimator.hpp"
#include "evpipe/stages/lcm_sink.hpp"
#include "evpipe/stages/pose_processor.hpp"
#include "evpipe/transport/preview.hpp"
#include "evpipe/view/output.hpp"

namespace evpipe::app {

struct PreviewOptions {
  double hz = 10.0;     ///< previews per second (host time); ignored for video frames
  bool lcm = false;     ///< publish preview_t
  std::string lcm_url;  ///< "" = LCM's default
  std::string lcm_channel{transport::kDefaultPreviewChannel};
  std::string video;     ///< video file (every window)
  double video_fps = 0;  ///< 0 = sensor time (1 / window hop)
  int png_every = 0;     ///< every Nth window as PNG (0 = none)
  std::string png_dir = ".";
  /// Files no still may overwrite (the inputs and the other outputs; a link of one counts): checked per still.
  std::vector<std::string> protected_files;
  bool lossless = false;  ///< replay: the pose thread waits for the builder (video/PNGs of every window)
  int zoom = 2;
  int nice = 10;
};

struct PreviewCounters {
  std::uint64_t built = 0;
  std::uint64_t dropped = 0;  ///< due previews not built: builder busy (or the hand-off's lock was taken)
  std::uint64_t published = 0;
  std::uint64_t publish_failures = 0;
  std::uint64_t bytes = 0;
  std::uint64_t video_frames = 0;
  std::uint64_t pngs = 0;
  std::string video_path;
  std::string video_codec;
  int video_width = 0, video_height = 0;
};

class PreviewWorker final : public stages::WindowObserver, public stages::PublishObserver {
 public:
  /// camera/model: for the projected segments (absent: no segments). sink: the latest statistics (drops, p99).
  PreviewWorker(PreviewOptions options, SensorGeometry geometry, std::int64_t hop_us,
                std::optional<camera::CameraModel> camera, std::optional<camera::LineModel> model,
                const stages::LcmSink* sink);
  ~PreviewWorker() override;
  PreviewWorker(const PreviewWorker&) = delete;
  PreviewWorker& operator=(const PreviewWorker&) = delete;

  /// Pose thread, after each window's estimate.
  void on_window(const EventWindow& window, const pose::PoseEstimate& estimate) override;
  /// Publish thread, after a pose went out: its window -> LCM latency.
  void on_published(std::int64_t latency_ns) noexcept override {
    last_latency_ns_.store(latency_ns, std::memory_order_relaxed);
  }
  /// Throws std::runtime_error when --video / --png-every cannot load their output module (view::FrameOutput).
  /// After the pipeline joined: builds what is queued, stops the thread, closes the video. Throws
  /// std::runtime_error when the video could not be written.
  void finish();
  [[nodiscard]] PreviewCounters counters() const;

 private:
  struct Job {
    EventWindow window;
    pose::PoseEstimate estimate;
  };
  void run();
  void build(const Job& job);

  PreviewOptions options_;
  SensorGeometry geometry_;
  std::int64_t hop_us_;
  std::optional<camera::CameraModel> camera_;
  std::optional<camera::LineModel> model_;
  const stages::LcmSink* sink_;
  std::unique_ptr<transport::PreviewPublisher> publisher_;
  std::unique_ptr<view::FrameOutput> output_;  ///< loaded for --video / --png-every only
  bool video_ = false;

  std::chrono::steady_clock::time_point next_offer_{};  // pose thread only
  std::uint64_t windows_offered_ = 0;                   // pose thread only
  std::atomic<std::int64_t> last_latency_ns_{0};
  std::atomic<std::uint64_t> dropped_busy_{0};            ///< hand-offs that found the lock taken
  std::chrono::steady_clock::time_point last_publish_{};  // builder thread only

  mutable std::mutex mutex_;
  std::condition_variable cv_;
  std::deque<Job> queue_;
  bool stop_ = false;
  PreviewCounters counters_;
  std::string error_;
  std::thread thread_;
};

}  // namespace evpipe::app
