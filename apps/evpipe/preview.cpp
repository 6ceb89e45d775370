#include "preview.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <filesystem>

#include "evpipe/core/file.hpp"
#include "evpipe/runtime/background_task.hpp"
#include "evpipe/view/frame.hpp"
#include "evpipe/view/render.hpp"

namespace evpipe::app {

PreviewWorker::PreviewWorker(PreviewOptions options, SensorGeometry geometry, std::int64_t hop_us,
                             std::optional<camera::CameraModel> camera, std::optional<camera::LineModel> model,
                             const stages::LcmSink* sink)
    : options_(std::move(options)),
      geometry_(geometry),
      hop_us_(hop_us),
      camera_(camera),
      model_(std::move(model)),
      sink_(sink) {
  if (options_.lcm) publisher_ = std::make_unique<transport::PreviewPublisher>(options_.lcm_url, options_.lcm_channel);
  if (!options_.video.empty() || options_.png_every > 0) output_ = std::make_unique<view::FrameOutput>();
  if (!options_.video.empty()) {
    const double fps =
        options_.video_fps > 0 ? options_.video_fps : 1e6 / static_cast<double>(std::max<std::int64_t>(hop_us_, 1));
    output_->open_video(options_.video, fps);
    video_ = true;
  }
  if (options_.png_every > 0) std::filesystem::create_directories(options_.png_dir);
  thread_ = std::thread([this] { run(); });
}

PreviewWorker::~PreviewWorker() {
  {
    const std::lock_guard lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void PreviewWorker::on_window(const EventWindow& window, const pose::PoseEstimate& estimate) {
  const std::uint64_t index = windows_offered_++;
  const bool every_window = video_ || options_.png_every > 0;
  const auto now = std::chrono::steady_clock::now();
  bool due = every_window;
  if (!due && options_.lcm && options_.hz > 0) {
    // On a grid of 1 / hz (host time), so that the rate is hz on average whatever the window hop.
    const auto period = std::chrono::duration_cast<std::chrono::steady_clock::duration>(
        std::chrono::duration<double>(1.0 / options_.hz));
    due = index == 0 || now >= next_offer_;
    if (due) next_offer_ = (index == 0 || now - next_offer_ > period) ? now + period : next_offer_ + period;
  }
  if (!due) return;
  if (options_.lossless) {
    // Replay with --video / --png-every: every window, in order; the pose thread waits for room (replay only).
    std::unique_lock lock(mutex_);
    cv_.wait(lock, [this] { return queue_.size() < 4 || stop_; });
    queue_.push_back({window, estimate});
  } else {
    std::unique_lock lock(mutex_, std::try_to_lock);
    if (!lock.owns_lock()) {
      dropped_busy_.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    if (!queue_.empty()) {  // the builder is behind: the newest wins
      queue_.clear();
      ++counters_.dropped;
    }
    queue_.push_back({window, estimate});
  }
  cv_.notify_one();
}

void PreviewWorker::run() {
  runtime::lower_priority_and_name("evpipe-preview", options_.nice);
  for (;;) {
    Job job;
    {
      std::unique_lock lock(mutex_);
      cv_.wait(lock, [this] { return stop_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopped and drained
      job = std::move(queue_.front());
      queue_.pop_front();
    }
    cv_.notify_all();  // room for a lossless producer
    try {
      build(job);
    } catch (const std::exception& e) {
      const std::lock_guard lock(mutex_);
      if (error_.empty()) error_ = e.what();
    }
  }
}

void PreviewWorker::build(const Job& job) {
  const auto& w = job.window;
  const auto& e = job.estimate;
  transport::PreviewRecord r;
  r.t_us = e.t_us;
  r.window_t0_us = w.t0_us;
  r.window_t1_us = w.t1_us;
  // The wire value of the status (pose_t.STATUS_*): 3 = holding once the pose stage has it.
  r.status = static_cast<std::int8_t>(e.status);
  r.pose_valid = e.pose_valid;
  r.pose_events = static_cast<std::int32_t>(e.window_events);
  r.inliers = static_cast<std::int32_t>(e.inliers);
  r.sigma_px = static_cast<float>(e.sigma_px);
  r.note = e.note;
  view::start_image(r, view::preview_grid(geometry_.width, geometry_.height));
  // Behind a filter the window's raw events (EventWindow::raw_parts); without one its events are the raw ones.
  std::int64_t raw = 0;
  for (const auto& part : w.raw_parts) raw += view::mark_raw(r, part, w.t0_us, w.t1_us);
  std::int64_t kept = 0;
  for (const auto& part : w.parts) kept += view::mark_kept(r, part);
  r.raw_events = static_cast<std::int32_t>(std::max(raw, kept));
  r.kept_events = static_cast<std::int32_t>(kept);
  if (camera_ && model_) r.segments = view::project_model(*camera_, *model_, e.T_cam_model);
  r.latency_ms = static_cast<float>(static_cast<double>(last_latency_ns_.load(std::memory_order_relaxed)) / 1e6);
  if (sink_) {
    if (const auto st = sink_->latest_stats()) {
      r.latency_p99_ms = static_cast<float>(static_cast<double>(st->latency_window_to_publish_ns.p99) / 1e6);
      for (const auto& q : st->queues) r.queue_drops += static_cast<std::int64_t>(q.dropped);
    }
  }
  std::uint64_t index = 0;
  {
    const std::lock_guard lock(mutex_);
    r.previews_dropped = static_cast<std::int64_t>(counters_.dropped + dropped_busy_.load(std::memory_order_relaxed) +
                                                   counters_.publish_failures);
    index = counters_.built++;
  }
  // Every window is built for a video; LCM still gets at most preview_hz of them.
  const auto now = std::chrono::steady_clock::now();
  const bool every_window = video_ || options_.png_every > 0;  // else on_window() has already kept to preview_hz
  if (publisher_ &&
      (!every_window || index == 0 || now - last_publish_ >= std::chrono::duration<double>(1.0 / options_.hz))) {
    last_publish_ = now;
    const bool ok = publisher_->publish(r);
    const auto c = publisher_->counters();
    const std::lock_guard lock(mutex_);
    counters_.published = static_cast<std::uint64_t>(c.published);
    counters_.publish_failures = static_cast<std::uint64_t>(c.failures);
    counters_.bytes = static_cast<std::uint64_t>(c.bytes);
    (void)ok;
  }
  if (video_ || (options_.png_every > 0 && index % static_cast<std::uint64_t>(options_.png_every) == 0)) {
    view::RenderOptions ro;
    ro.zoom = options_.zoom;
    const cv::Mat img = view::render_preview(r, ro);
    if (video_) output_->write_video(img);
    if (options_.png_every > 0 && index % static_cast<std::uint64_t>(options_.png_every) == 0) {
      const std::string path =
          (std::filesystem::path(options_.png_dir) / fmt::format("evpipe-{:06}.png", index)).string();
      check_output_file(path, options_.protected_files);  // a still never replaces an input or another output
      output_->write_png(path, img);
      const std::lock_guard lock(mutex_);
      ++counters_.pngs;
    }
    if (video_) {
      const auto info = output_->video_info();
      const std::lock_guard lock(mutex_);
      counters_.video_frames = static_cast<std::uint64_t>(info.frames);
      counters_.video_path = info.path;
      counters_.video_codec = info.codec;
      counters_.video_width = info.width;
      counters_.video_height = info.height;
    }
  }
}

void PreviewWorker::finish() {
  {
    const std::lock_guard lock(mutex_);
    stop_ = true;
  }
  cv_.notify_all();
  if (thread_.joinable()) thread_.join();
  if (video_) output_->close_video();
  const std::lock_guard lock(mutex_);
  if (!error_.empty()) throw std::runtime_error(error_);
}

PreviewCounters PreviewWorker::counters() const {
  const std::lock_guard lock(mutex_);
  PreviewCounters c = counters_;
  c.dropped += dropped_busy_.load(std::memory_order_relaxed);
  return c;
}

}  // namespace evpipe::app
