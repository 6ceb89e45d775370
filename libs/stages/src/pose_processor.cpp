#include "evpipe/stages/pose_processor.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <limits>
#include <stdexcept>

#include "evpipe/camera/error.hpp"
#include "evpipe/camera/prior.hpp"

namespace evpipe::stages {

std::vector<std::string> pose_csv_extra_columns() {
  // The contract of issue 21 (docs/operations.md): status, inliers, sigma_px, the time of the last measurement,
  // then the 6x6 covariance row-major (rx ry rz [rad] tx ty tz [m], as pose_t's; empty cells when unknown).
  std::vector<std::string> columns = {"status", "inliers", "sigma_px", "t_last_update_us"};
  for (int i = 0; i < 36; ++i) columns.push_back(fmt::format("cov_{}", i));
  return columns;
}

pose::PoseEstimate EventsOnlyProcessor::process(const EventWindow& window) {
  pose::PoseEstimate estimate;
  estimate.t_us = window.t0_us + (window.t1_us - window.t0_us) / 2;  // the window's middle, as PoseProcessor's
  estimate.window_events = window.size();
  estimate.note = "no pose stage (no --camera/--model)";
  if (observer_) observer_->on_window(window, estimate);
  return estimate;
}

std::unique_ptr<PoseProcessor> PoseProcessor::create(const PoseProcessorOptions& o) {
  if (o.camera.empty() || o.model.empty())
    throw std::invalid_argument(
        "pose: --camera and --model (pose.camera, pose.model) are both needed to estimate poses");
  try {
    auto cam = camera::load_camera(o.camera);
    auto model = camera::load_line_model(o.model);
    std::optional<camera::PosePrior> prior;
    if (!o.prior.empty()) prior = camera::load_prior(o.prior);
    pose::PoseEstimator estimator(std::move(cam), std::move(model), std::move(prior), o.estimator);
    std::optional<camera::TrajectoryCsvWriter> csv;
    if (!o.poses_out.empty()) csv.emplace(o.poses_out, pose_csv_extra_columns(), o.inputs);
    return std::unique_ptr<PoseProcessor>(
        new PoseProcessor(std::move(estimator), std::move(csv), o.poses_out, o.init_worker, o.init_worker_nice));
  } catch (const camera::ModelError& e) {
    throw std::invalid_argument(e.what());
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(fmt::format("pose: {}", e.what()));
  } catch (const std::runtime_error& e) {  // the CSV could not be created
    throw std::invalid_argument(fmt::format("pose: {}", e.what()));
  }
}

PoseProcessor::PoseProcessor(pose::PoseEstimator estimator, std::optional<camera::TrajectoryCsvWriter> csv,
                             std::string csv_path, bool init_worker, int init_worker_nice)
    : estimator_(std::move(estimator)), csv_(std::move(csv)) {
  summary_.enabled = true;
  summary_.poses_out = std::move(csv_path);
  summary_.init_worker = init_worker;
  // Niced (pose.init_worker_nice, default +10): an attempt uses whatever CPU the stages leave (on 2 cores it would
  // otherwise delay them).
  if (init_worker) {
    init_worker_ = std::make_unique<runtime::BackgroundTask<pose::InitOutcome>>("evpipe-init", init_worker_nice);
  }
}

PoseProcessor::~PoseProcessor() = default;

pose::PoseEstimate PoseProcessor::estimate(EventSpan events, EventSpan raw, std::int64_t t_us, double& init_ms) {
  if (!init_worker_) return estimator_.process(events, t_us, raw);  // PoseProcessor::process times an attempt in line
  // An attempt runs on the worker: this window waits for nothing.
  if (init_worker_->pending()) {
    std::optional<pose::InitOutcome> outcome = init_worker_->poll();
    if (!outcome) {
      feed(events, t_us);
      return estimator_.initialising_window(events, t_us);
    }
    const std::uint64_t before = estimator_.counters().init_successes;
    auto e = estimator_.complete_initialisation(*outcome, events, t_us);
    if (estimator_.counters().init_successes > before) {  // applied (not dropped as stale)
      init_ms = std::chrono::duration<double, std::milli>(init_worker_->last_duration()).count();
    }
    return e;
  }
  if (estimator_.needs_initialisation()) {
    pose::PoseEstimate now;
    std::optional<pose::InitJob> job = estimator_.prepare_initialisation(events, t_us, now);
    if (job) {
      {
        const std::lock_guard lock(feed_.mutex);
        feed_.events.clear();
        feed_.newest_t_us = job->events.empty() ? std::numeric_limits<std::int64_t>::min() : job->events.back().t_us;
        feed_.window_t_us = job->t_us;
      }
      // The estimator and the feed outlive the worker (member order); the job owns its events.
      init_worker_->submit([this, j = std::move(*job)] { return run_attempt(j); });
    }
    return now;
  }
  return estimator_.process(events, t_us, raw);
}

void PoseProcessor::feed(EventSpan events, std::int64_t t_us) {
  const std::lock_guard lock(feed_.mutex);
  // Windows may overlap (hop < length): only events newer than those already fed (the bound is read once: a
  // window holds many events of one microsecond, and windows never split a microsecond).
  const std::int64_t newest = feed_.newest_t_us;
  std::vector<Event> scratch;
  const EventSpan fresh = events_after(events, newest, scratch);
  if (!fresh.empty()) feed_.newest_t_us = std::max(newest, fresh.back().t_us);
  feed_.window_t_us = t_us;
  // Bounded like the estimator's own memory of an attempt's windows: a longer attempt catches up over the newest.
  append_bounded(feed_.events, fresh, pose::PoseEstimator::kCatchUpMaxEvents, std::numeric_limits<std::int64_t>::min());
}

pose::InitOutcome PoseProcessor::run_attempt(const pose::InitJob& job) {  // on the worker
  pose::InitOutcome outcome = estimator_.run_initialisation(job);
  if (!outcome.ok) return outcome;
  std::vector<Event> since;
  std::int64_t window_t_us = 0;
  {
    const std::lock_guard lock(feed_.mutex);
    since.swap(feed_.events);
    window_t_us = feed_.window_t_us;
  }
  if (since.empty()) return outcome;
  std::vector<Event> events;  // the job's events as history, then everything since
  events.reserve(job.events.size() + since.size());
  events.insert(events.end(), job.events.begin(), job.events.end());
  events.insert(events.end(), since.begin(), since.end());
  return estimator_.advance_initialisation(outcome, events, window_t_us);
}

namespace {

/// The events of `parts` as one span: the single part itself, else copied into `scratch`.
EventSpan one_span(const std::vector<EventSpan>& parts, std::vector<Event>& scratch) {
  if (parts.size() == 1) return parts.front();
  scratch.clear();
  for (const EventSpan& part : parts) scratch.insert(scratch.end(), part.begin(), part.end());
  return scratch;
}

}  // namespace

pose::PoseEstimate PoseProcessor::process(const EventWindow& window) {
  const EventSpan events = one_span(window.parts, scratch_);
  if (window.starts_segment && estimator_.counters().windows > 0) {
    estimator_.reset();  // clock jumped: the track is stale
  }
  // The window's events before denoising, for the hold's standstill test (a denoiser deletes much of a creeping
  // target's events): copied only while there is a track to hold.
  const EventSpan raw = !window.raw_parts.empty() && !estimator_.needs_initialisation()
                            ? one_span(window.raw_parts, raw_scratch_)
                            : EventSpan{};
  // The pose is fitted to all events of the window: it best represents the window's middle, which is the
  // time it is stamped with (a 30 ms window lags its end by 15 ms).
  // Timed on this thread: an update, or the window that applies a worker's attempt (with its catch-up); an
  // attempt in line is reported as the initialisation time instead, one on the worker by its own duration.
  double init_ms = 0.0;
  const auto t0 = std::chrono::steady_clock::now();
  auto estimate = this->estimate(events, raw, window.t0_us + (window.t1_us - window.t0_us) / 2, init_ms);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (estimate.initialised_now && !init_worker_) init_ms = ms;
  if (init_ms > 0.0 && summary_.first_init_ms == 0) summary_.first_init_ms = init_ms;
  if (estimate.pose_valid) {
    if (!(estimate.initialised_now && !init_worker_)) summary_.update_ms.push_back(ms);
    if (summary_.valid_poses == 0) summary_.first_valid_t_us = estimate.t_us;
    summary_.last_valid_t_us = estimate.t_us;
    ++summary_.valid_poses;
  } else if (!estimate.note.empty()) {
    summary_.last_note = estimate.note;
  }
  // --log-level trace: every window's outcome (diagnosis: why a window carries no valid pose).
  spdlog::trace("pose t={} {} valid={} events={} inliers={} sigma={:.2f} {}", estimate.t_us,
                pose::to_string(estimate.status), estimate.pose_valid, estimate.window_events, estimate.inliers,
                estimate.sigma_px, estimate.note);
  if (observer_) observer_->on_window(window, estimate);  // never waits, except for a replay's --video
  return estimate;
}

void PoseProcessor::write(const pose::PoseEstimate& e) {
  if (!csv_ || !e.pose_valid) return;
  std::vector<std::string> extra = {std::string(pose::to_string(e.status)), fmt::format("{}", e.inliers),
                                    fmt::format("{:.4f}", e.sigma_px), fmt::format("{}", e.t_last_update_us)};
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j) extra.push_back(e.covariance_known ? fmt::format("{:.6e}", e.covariance(i, j)) : "");
  csv_->write({e.t_us, e.T_cam_model}, extra);
}

PoseSummary PoseProcessor::summary() const {
  PoseSummary s = summary_;
  const auto& c = estimator_.counters();
  s.windows = c.windows;
  for (int i = 0; i < 4; ++i) s.windows_by_status[i] = c.windows_by_status[i];
  s.holds = c.holds;
  s.hold_resumes = c.hold_resumes;
  s.init_attempts = c.init_attempts;
  s.init_successes = c.init_successes;
  s.losses = c.losses;
  return s;
}

}  // namespace evpipe::stages
