#include "evpipe/pose/estimator.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>

namespace evpipe::pose {

void EstimatorOptions::validate() const {
  if (lost_after_windows < 1)
    throw std::invalid_argument(fmt::format("pose.lost_after_windows: must be >= 1, got {}", lost_after_windows));
  if (!(reinit_position_tolerance_m > 0.0) || !std::isfinite(reinit_position_tolerance_m))
    throw std::invalid_argument(
        fmt::format("pose.reinit_position_tolerance_m: must be > 0, got {}", reinit_position_tolerance_m));
  if (!(max_step_m > 0.0) || !(max_step_deg > 0.0))
    throw std::invalid_argument(
        fmt::format("pose.max_step_m / max_step_deg: must be > 0, got {} / {}", max_step_m, max_step_deg));
  if (init_accumulate_us < 0)
    throw std::invalid_argument(fmt::format("pose.init_accumulate_us: must be >= 0, got {}", init_accumulate_us));
  if (!(reinit_angle_tolerance_deg > 0.0 && reinit_angle_tolerance_deg <= 180.0))
    throw std::invalid_argument(
        fmt::format("pose.reinit_angle_tolerance_deg: must be in (0, 180], got {}", reinit_angle_tolerance_deg));
  const StandstillOptions& s = standstill;
  if (!(s.band_px > 0.0 && s.band_px <= s.gate_px && s.gate_px <= s.far_px && s.far_px < s.background_px) ||
      s.cell_px < 1) {
    throw std::invalid_argument(
        fmt::format("pose standstill: need 0 < band_px <= gate_px <= far_px and cell_px >= 1, got {} / {} / {} / {}",
                    s.band_px, s.gate_px, s.far_px, s.cell_px));
  }
  if (!(s.significance > 0.0 && s.significance < 1.0) || !(s.max_motion_px > 0.0) || !(s.memory_s > 0.0) ||
      !(s.min_motion_events > 0.0) || !(s.max_rotation_deg >= 0.0) || !(s.max_translation_m >= 0.0))
    throw std::invalid_argument(
        fmt::format("pose standstill: significance must be in (0, 1), max_motion_px > 0 and max_rotation_deg / "
                    "max_translation_m >= 0, got {} / {} / {} / {}",
                    s.significance, s.max_motion_px, s.max_rotation_deg, s.max_translation_m));
  if (speed_baseline_us < 0)
    throw std::invalid_argument(fmt::format("pose.speed_baseline_us: must be >= 0, got {}", speed_baseline_us));
  if (!(track_max_blur_px > 0.0) || track_max_span_us < 0 || track_history_max_us < 0 || unverified_max_us < 0)
    throw std::invalid_argument(
        fmt::format("pose.track_max_blur_px must be > 0 and track_max_span_us / track_history_max_us / "
                    "unverified_max_us >= 0, got {} / {} / {} / {}",
                    track_max_blur_px, track_max_span_us, track_history_max_us, unverified_max_us));
  if (confirm_windows < 0 || confirm_windows_without_prior < 0 || confirm_windows_direct < 0)
    throw std::invalid_argument(fmt::format(
        "pose.confirm_windows / confirm_windows_without_prior / confirm_windows_direct: must be >= 0, got {} / {} / {}",
        confirm_windows, confirm_windows_without_prior, confirm_windows_direct));
  if (!(hold_entry_max_motion_px >= 0.0) || hold_contradicted_windows < 1)
    throw std::invalid_argument(
        fmt::format("pose hold: hold_entry_max_motion_px must be >= 0 and hold_contradicted_windows >= 1, got {} / {}",
                    hold_entry_max_motion_px, hold_contradicted_windows));
  filter.validate();
}

PoseEstimator::PoseEstimator(camera::CameraModel camera, camera::LineModel model,
                             std::optional<camera::PosePrior> prior, EstimatorOptions options)
    : camera_(std::move(camera)),
      map_(camera_),
      model_(std::move(model)),
      prior_(std::move(prior)),
      options_(std::move(options)),
      filter_(options_.filter) {
  options_.validate();
  if (model_.segments_m.size() < 4)
    throw std::invalid_argument(
        fmt::format("line model '{}' has {} segments; OPnL needs at least 4", model_.name, model_.segments_m.size()));
  // The model's partial symmetries, once: initialisation and every tracking update compare the pose with the pose
  // turned by each (verification.hpp, "Symmetric alternatives").
  if (options_.compare_symmetries) {
    const std::vector<camera::Pose> symmetries = model_symmetries(model_);
    if (options_.init.verification.symmetries.empty()) options_.init.verification.symmetries = symmetries;
    if (options_.track.verification.symmetries.empty()) options_.track.verification.symmetries = symmetries;
  }
}

void PoseEstimator::reset() {
  ++generation_;
  attempt_t_us_.reset();
  last_published_t_us_.reset();
  recent_.clear();
  reinit_span_us_ = 0;
  track_ = TrackState{};
  filter_.reset();
  fused_ = {};
  standstill_.stop();
  standstill_raw_.stop();
  set_status(TrackStatus::initialising);
}

void PoseEstimator::set_status(TrackStatus s) {
  if ((status_ == TrackStatus::tracking || status_ == TrackStatus::holding) && s == TrackStatus::lost) {
    ++counters_.losses;
  }
  if (s != TrackStatus::holding) {
    standstill_.stop();
    standstill_raw_.stop();
  }
  status_ = s;
}

camera::Pose PoseEstimator::predict(const TrackState& state, std::int64_t t_end_us) const {
  const auto& last = state.last;
  const auto& previous = state.previous;
  // Newer than the last verified pose: an unverified fit (TrackState::fitted) is where the target was seen last.
  const camera::StampedPose& from = state.fitted && state.fitted->t_us > last->t_us ? *state.fitted : *last;
  if (!options_.constant_velocity || !previous || !last || last->t_us <= previous->t_us) return from.pose;
  // Constant velocity on SE(3): apply the last relative motion, scaled to the time step, once more.
  const double s = static_cast<double>(t_end_us - from.t_us) / static_cast<double>(last->t_us - previous->t_us);
  if (!(s > 0.0) || s > 3.0) return from.pose;                       // a long gap makes the extrapolation meaningless
  const camera::Pose delta = last->pose * previous->pose.inverse();  // T_last_prev in the camera frame
  const Eigen::AngleAxisd rot(delta.q_cam_model);
  camera::Pose step;
  step.q_cam_model = Eigen::Quaterniond(Eigen::AngleAxisd(rot.angle() * s, rot.axis()));
  step.t_cam_model_m = delta.t_cam_model_m * s;  // small-motion approximation of the screw, fine at window steps
  return step * from.pose;
}

namespace {

// A healthy tracking update as the window's valid pose.
void publish_update(const TrackUpdate& u, PoseEstimate& out) {
  out.T_cam_model = u.T_cam_model;
  out.pose_valid = true;
  out.covariance = u.covariance;
  out.covariance_known = u.covariance_known;
  out.inliers = u.inliers;
  out.sigma_px = u.sigma_px;
}

}  // namespace

PoseEstimate PoseEstimator::held_estimate(EventSpan window, std::int64_t t_end_us) const {
  PoseEstimate out;
  out.t_us = t_end_us;
  out.window_events = window.size();
  out.status = status_;
  if (track_.last) {
    out.t_last_update_us = track_.last->t_us;
    out.T_cam_model = track_.last->pose;
  } else if (prior_) {
    out.T_cam_model = prior_->pose;
  }
  return out;
}

std::optional<InitJob> PoseEstimator::prepare_initialisation(EventSpan window, std::int64_t t_end_us,
                                                             PoseEstimate& now) {
  ++counters_.windows;
  remember(window, t_end_us);
  std::optional<InitJob> job = make_job(window, t_end_us, now);
  if (job) {
    attempt_t_us_ = t_end_us;  // remember every event from here until the outcome (the catch-up needs them)
    now = held_estimate(window, t_end_us);
    now.note = "initialisation started";
  }
  now = counted(std::move(now));
  return job;
}

std::optional<InitJob> PoseEstimator::make_job(EventSpan window, std::int64_t t_end_us, PoseEstimate& skipped) {
  // The window alone when it is rich enough (the freshest view), else the accumulated events: the newest
  // init_target_events of the last init_accumulate_us. Every other attempt (slow motion: too few events of the
  // target's edges in that, or drowned in the noise) the newest init_long_target_events of the last
  // init_long_accumulate_us instead, whatever the window's size (windows sized by count, ELOPET-style: at a high
  // event rate the span stays short by itself).
  // After a loss neither spans more than the model's image took to move track_max_blur_px at the last tracked speed
  // (the tracking history's bound): a target lost while moving keeps moving, and 0.3-1 s of its events are a blur
  // that fits other structure (decoy seed 7403: a re-initialised board 9-17 deg off, verified). Once the last good
  // pose is older than the long accumulation, that speed says nothing of the events any more (the target may have
  // stopped or slowed to a crawl): unbounded again.
  const bool bounded =
      track_.last && reinit_span_us_ > 0 &&
      t_end_us - track_.last->t_us <= std::max(options_.init_long_accumulate_us, options_.init_accumulate_us);
  const std::int64_t max_span_us = bounded ? reinit_span_us_ : std::numeric_limits<std::int64_t>::max();
  const auto newest = [&](std::size_t count, std::int64_t span_us) {
    span_us = std::min(span_us, max_span_us);
    auto first = recent_.end() - static_cast<std::ptrdiff_t>(std::min(recent_.size(), count));
    while (first != recent_.end() && first->t_us < t_end_us - span_us) ++first;
    return EventSpan(first, recent_.end());
  };
  EventSpan events = window.size() < options_.init_target_events
                         ? newest(options_.init_target_events, options_.init_accumulate_us)
                         : window;
  // The longer accumulation every other attempt, and whenever the shorter one is too small to attempt at all (else
  // a target too slow to give init_min_events in init_accumulate_us never gets an attempt to alternate with).
  // Only for an attempt that searches around a pose (the configured prior, or the last good pose after a loss):
  // without one, the long accumulation's blur of the scene's other structure gave wrong poses (EstimatorOptions).
  const bool longer = options_.init_long_accumulate_us > 0 && (prior_.has_value() || track_.last.has_value()) &&
                      (counters_.init_attempts % 2 == 1 || events.size() < options_.init_min_events);
  EventSpan shorter;
  if (longer) {
    const EventSpan more = newest(options_.init_long_target_events, options_.init_long_accumulate_us);
    if (more.size() > events.size()) {
      if (events.size() >= options_.init_min_events) shorter = events;
      events = more;
    }
  }
  if (events.size() < options_.init_min_events) {
    skipped = held_estimate(window, t_end_us);
    skipped.note =
        fmt::format("{} events in the window, initialisation needs {}", events.size(), options_.init_min_events);
    return std::nullopt;
  }
  ++counters_.init_attempts;
  InitJob job;
  job.events.assign(events.begin(), events.end());
  job.shorter.assign(shorter.begin(), shorter.end());
  const EventSpan fresh = tracking_events(window, t_end_us, recent_);
  if (fresh.data() != events.data() || fresh.size() != events.size()) job.fresh.assign(fresh.begin(), fresh.end());
  job.t_us = t_end_us;
  job.generation = generation_;
  // After a loss search around the last good pose; before the first success around the configured prior.
  job.search = prior_;
  if (track_.last) {
    camera::PosePrior around;
    around.pose = track_.last->pose;
    around.position_tolerance_m = options_.reinit_position_tolerance_m;
    around.angle_tolerance_deg = options_.reinit_angle_tolerance_deg;
    job.search = around;
    // The last good pose may itself have been wrong (a track that drifted before it was declared lost): then
    // search around the configured prior too, every other attempt (the prior is where the target is installed).
    if (prior_ && counters_.init_attempts % 2 == 0) job.fallback = prior_;
  }
  return job;
}

InitOutcome PoseEstimator::run_initialisation(const InitJob& job) const {
  InitOutcome out;
  out.t_us = job.t_us;
  out.generation = job.generation;
  InitResult init = initialise_pose(job.events, camera_, model_, job.search, options_.init);
  if (!init.ok && job.fallback) init = initialise_pose(job.events, camera_, model_, job.fallback, options_.init);
  if (!init.ok) {
    out.note = "initialisation: " + init.message;
    return out;
  }
  out.direct = init.direct;
  // Polish the initial pose with the tracker so the first published pose carries a robust scale and a covariance
  // like every later one, and is measured on the events a tracking update at job.t_us uses: a pose found on the
  // accumulated events is polished on them first (the nearer start), then on the fresh ones (tracking_events: the
  // window, or a history bounded by the model's image motion; the accumulation spans up to init_accumulate_us).
  out.polished = track_window(job.events, map_, model_, init.T_cam_model, options_.track);
  EventSpan fitted_on = job.events;
  if (!job.shorter.empty()) {
    // Found on the long accumulation: the newer, shorter one gives the fresher pose when it can be verified on it.
    TrackUpdate shorter = track_window(job.shorter, map_, model_, init.T_cam_model, options_.track);
    if (shorter.healthy) {
      out.polished = std::move(shorter);
      fitted_on = job.shorter;
    }
  }
  if (!out.polished.healthy) {
    out.note = "initialisation found a pose but tracking rejected it: " + out.polished.reason;
    return out;
  }
  if (!job.fresh.empty()) {
    TrackUpdate now = track_window(job.fresh, map_, model_, out.polished.T_cam_model, options_.track);
    out.measured_at_t = now.healthy;
    if (now.healthy) {
      out.polished = std::move(now);
    } else {
      out.note =
          "initialised on the accumulated events; the window's own events did not confirm the pose: " + now.reason;
      if (!fitted_on.empty()) out.blur_span_us = fitted_on.back().t_us - fitted_on.front().t_us;
    }
  }
  out.ok = true;
  return out;
}

PoseEstimate PoseEstimator::apply_initialisation(const InitOutcome& outcome, PoseEstimate out) {
  if (!outcome.ok) {
    out.note = outcome.note;
    return out;
  }
  const TrackUpdate& u = outcome.polished;
  ++counters_.init_successes;
  // Carried over the attempt's windows on the worker (advance_initialisation): the pose before, for constant
  // velocity, and the updates it ran.
  track_ = start_state(outcome);
  counters_.unhealthy_updates += outcome.caught_up_unhealthy;
  set_status(TrackStatus::tracking);
  out.status = status_;
  publish_update(u, out);
  out.t_last_update_us = outcome.t_us;
  out.initialised_now = true;
  if (!outcome.measured_at_t) {
    out.pose_valid = false;  // tracking from here, but this window did not measure the pose (InitOutcome)
    out.note = outcome.note;
  }
  // Without a configured prior every search is one (a re-initialisation searches around a pose found without one).
  const bool without_prior = !prior_;
  track_.confirm_needed = without_prior ? std::max(options_.confirm_windows, options_.confirm_windows_without_prior)
                                        : options_.confirm_windows;
  if (outcome.direct) track_.confirm_needed = std::max(track_.confirm_needed, options_.confirm_windows_direct);
  track_.confirm_min_coverage = without_prior ? options_.confirm_min_coverage_without_prior : 0.0;
  track_.confirmed = track_.healthy_in_a_row >= track_.confirm_needed && track_.confirm_min_coverage <= 0.0;
  unconfirmed(out);
  return out;
}

PoseEstimate PoseEstimator::initialising_window(EventSpan window, std::int64_t t_end_us) {
  ++counters_.windows;
  remember(window, t_end_us);
  PoseEstimate out = held_estimate(window, t_end_us);
  out.note = "initialisation in progress";
  return counted(std::move(out));
}

PoseEstimate PoseEstimator::complete_initialisation(const InitOutcome& outcome, EventSpan window,
                                                    std::int64_t t_end_us) {
  attempt_t_us_.reset();
  if (outcome.generation != generation_ || !needs_initialisation()) {
    // Stale (a reset since) or already tracking: this window is an ordinary one.
    return !needs_initialisation() ? process(window, t_end_us) : initialising_window(window, t_end_us);
  }
  if (!outcome.ok || outcome.t_us == t_end_us) {
    ++counters_.windows;
    remember(window, t_end_us);
    return counted(apply_initialisation(outcome, held_estimate(window, t_end_us)));
  }
  // Found on an earlier window: the track starts there (or at the last slice the worker tracked,
  // advance_initialisation) and catches up the windows since on the remembered events (catch_up).
  apply_initialisation(outcome, PoseEstimate{});
  std::uint64_t unhealthy = 0;
  const int slices = outcome.caught_up_slices + catch_up(track_, outcome.t_us, t_end_us, recent_, unhealthy);
  note_speed();
  counters_.unhealthy_updates += unhealthy;
  if (track_.lost) set_status(TrackStatus::lost);
  ++counters_.windows;
  remember(window, t_end_us);
  PoseEstimate out =
      status_ == TrackStatus::tracking ? track(window, t_end_us, recent_) : held_estimate(window, t_end_us);
  note_speed();
  if (out.note.empty() && !out.pose_valid) {
    out.note =
        fmt::format("initialisation succeeded, but the track was lost catching up the {} windows it took", slices);
  }
  out.initialised_now = out.pose_valid;
  return counted(std::move(out));
}

void PoseEstimator::note_speed() {
  if (status_ == TrackStatus::holding) {
    reinit_span_us_ = 0;
  } else if (track_.previous && track_.last) {
    reinit_span_us_ = history_span_us(track_);
  }
}

void PoseEstimator::remember(EventSpan window, std::int64_t t_us) {
  // Windows may overlap (hop < length): only events newer than those already held are added.
  const std::int64_t newest_held = recent_.empty() ? std::numeric_limits<std::int64_t>::min() : recent_.back().t_us;
  std::vector<Event> scratch;
  const EventSpan fresh = events_after(window, newest_held, scratch);
  std::int64_t oldest_kept =
      t_us - std::max({options_.init_accumulate_us, options_.init_long_accumulate_us, options_.track_history_max_us});
  const std::size_t long_events = options_.init_long_accumulate_us > 0 ? options_.init_long_target_events : 0;
  // A tracking history may span many windows (a slow target under noise): up to kHistoryMaxEvents.
  std::size_t cap =
      std::max({options_.init_target_events, long_events, options_.track_min_events, window.size(), kHistoryMaxEvents});
  if (attempt_t_us_) {  // an attempt runs elsewhere: keep what the catch-up will track, within a bound
    oldest_kept = std::min(oldest_kept, *attempt_t_us_ - options_.track.window_us);
    cap = std::max(cap, kCatchUpMaxEvents);
  }
  append_bounded(recent_, fresh, cap, oldest_kept);
}

std::int64_t PoseEstimator::history_span_us(const TrackState& state) const {
  if (!state.previous || !state.last || state.last->t_us <= state.previous->t_us) return options_.track_max_span_us;
  // The speed over the longest baseline of the run (speed_baseline_us): the oldest trail pose within it, at least the
  // previous pose.
  const camera::StampedPose* from = &*state.previous;
  for (const camera::StampedPose& p : state.trail) {
    if (p.t_us < from->t_us && state.last->t_us - p.t_us <= options_.speed_baseline_us) {
      from = &p;
      break;
    }
  }
  const double px_per_us =
      image_motion_px(from->pose, state.last->pose) / static_cast<double>(state.last->t_us - from->t_us);
  const double span_us =
      px_per_us > 0.0 ? options_.track_max_blur_px / px_per_us : static_cast<double>(options_.track_history_max_us);
  return std::clamp(static_cast<std::int64_t>(std::min(span_us, 1e15)),
                    std::min(options_.track.window_us, options_.track_history_max_us), options_.track_history_max_us);
}

EventSpan PoseEstimator::tracking_events(const TrackState& state, EventSpan window, std::int64_t t_us,
                                         EventSpan history) const {
  return tracking_events(state.noise_rate_hz, history_span_us(state), window, t_us, history);
}

EventSpan PoseEstimator::tracking_events(double noise_rate_hz, std::int64_t span_us, EventSpan window,
                                         std::int64_t t_us, EventSpan history) const {
  // An (almost) empty window alone: the target has gone, old events must not hide that.
  if (window.size() < options_.track_min_window_events || history.empty()) return window;
  // The target's events in a span: the count minus what the measured background rate explains over the sensor.
  const double noise_per_us =
      noise_rate_hz * 1e-6 * static_cast<double>(camera_.width) * static_cast<double>(camera_.height);
  const double window_noise = noise_per_us * static_cast<double>(std::max<std::int64_t>(options_.track.window_us, 1));
  const auto target = static_cast<double>(options_.track_min_events);
  if (static_cast<double>(window.size()) - window_noise >= target) return window;  // a rich window alone
  // A sparse one: the newest events that hold track_min_events of the target, none older than the span over which
  // the model's image moves track_max_blur_px (history_span_us).
  const std::int64_t oldest_us = t_us - span_us;
  const std::int64_t newest_us = history.back().t_us;
  auto first = history.end();
  std::size_t n = 0;
  while (first != history.begin() && (first - 1)->t_us >= oldest_us) {
    --first;
    ++n;
    const double noise =
        noise_per_us * static_cast<double>(std::max<std::int64_t>(newest_us - first->t_us, options_.track.window_us));
    if (static_cast<double>(n) - noise >= target) break;
  }
  const EventSpan extended(first, history.end());
  return extended.size() > window.size() ? extended : window;
}

PoseEstimate PoseEstimator::process(EventSpan window, std::int64_t t_end_us, EventSpan raw) {
  ++counters_.windows;
  remember(window, t_end_us);
  if (!needs_initialisation()) {
    raw_ = raw;
    PoseEstimate out = track(window, t_end_us, recent_);
    note_speed();
    raw_ = {};
    return counted(std::move(out));
  }
  PoseEstimate skipped;
  const std::optional<InitJob> job = make_job(window, t_end_us, skipped);
  if (!job) return counted(std::move(skipped));
  return counted(apply_initialisation(run_initialisation(*job), held_estimate(window, t_end_us)));
}

PoseEstimate PoseEstimator::counted(PoseEstimate out) {
  ++counters_.windows_by_status[static_cast<int>(out.status)];
  fuse(out);
  // A published tracking pose is the track's newest pose (an initialisation's, or an update's).
  if (out.pose_valid && out.status == TrackStatus::tracking && track_.last) last_published_t_us_ = track_.last->t_us;
  return out;
}

void PoseEstimator::fuse(PoseEstimate& out) {
  if (!options_.filter.enabled) return;
  if (out.status == TrackStatus::holding && out.pose_valid) {
    // The held pose is a measured one: hold its fusion (the filter then knows the target is still).
    for (const std::optional<Fused>& f : fused_) {
      if (!f || f->t_us != out.t_last_update_us) continue;
      out.T_cam_model = f->pose.T_cam_model;
      out.covariance = f->pose.covariance;
      filter_.hold(out.t_last_update_us, out.T_cam_model, out.covariance);
      break;
    }
    return;
  }
  if (out.status != TrackStatus::tracking) {
    // Initialising or lost: the next track starts afresh.
    filter_.reset();
    fused_ = {};
    return;
  }
  // A tracking window that measured nothing (not valid) leaves the filter as it is: the next measurement predicts
  // over the gap.
  if (!out.pose_valid || !out.covariance_known || out.t_last_update_us != out.t_us) return;
  if (out.initialised_now) filter_.reset();
  const FusedPose f = filter_.update(out.t_us, out.T_cam_model, out.covariance, out.events_span_us);
  out.T_cam_model = f.T_cam_model;
  out.covariance = f.covariance;
  fused_[1] = fused_[0];
  fused_[0] = Fused{out.t_us, f};
}

PoseEstimate PoseEstimator::track(EventSpan window, std::int64_t t_end_us, EventSpan history) {
  if (status_ == TrackStatus::holding) return hold_step(window, t_end_us, history);
  track_.noise_rate_hz = noise_rate_hz_;
  const TrackState before = track_;
  const EventSpan used = tracking_events(before, window, t_end_us, history);
  std::uint64_t unhealthy = 0;
  PoseEstimate out = track_step(track_, window, t_end_us, history, unhealthy, true);
  if (track_.step_unverified && !signal_near(used, track_.fitted->pose)) {
    // Not even the fit has more events near it than the noise explains: an ordinary unhealthy update.
    track_.step_unverified = false;
    track_.fitted = before.fitted;
    track_.healthy_in_a_row = 0;
    out.note = "tracking: no more events near the fitted model than the noise explains (" + out.note + ")";
    if (++track_.unhealthy_in_a_row >= options_.lost_after_windows) {
      track_.lost = true;
      track_.previous.reset();
      track_.trail.clear();
    }
  }
  if (out.pose_valid && options_.hold && !signal_near(used, out.T_cam_model)) {
    // Healthy on paper, but the window has no more events near the fitted model than the noise explains: the
    // update fitted noise (a still target under a high noise rate), it measured nothing.
    const std::string why = fmt::format(
        "tracking: no more events near the fitted model than the noise explains ({} "
        "inliers, sigma {:.2f} px)",
        out.inliers, out.sigma_px);
    track_ = before;
    unhealthy = 1;
    if (++track_.unhealthy_in_a_row >= options_.lost_after_windows) {
      track_.lost = true;
      track_.previous.reset();
      track_.trail.clear();
    }
    const std::size_t n_used = out.window_events;
    out = held_estimate(window, t_end_us);
    out.window_events = n_used;
    out.note = why;
  }
  // A pose may be held when it was published (verified on its own window), or, an initial pose its window did not
  // confirm (found on accumulated events), when its edges moved so slowly that the image cannot have moved
  // max_motion_px since the middle of those events (a crawling target): the pose stands for that middle, not for
  // its stamp. A moving target whose events the denoiser deleted held its blurred accumulated pose otherwise (the
  // paper's filter: `holding` 11-22 mm / 2.5-5 deg off; measured from the stamp, a 0.02 m/s roadheader under 5 Hz/px
  // was held 11-18 mm off).
  const bool holdable =
      before.last && (last_published_t_us_ == before.last->t_us ||
                      before.last_update.max_edge_speed_px_s * 1e-6 *
                              static_cast<double>(t_end_us - before.last->t_us + before.last_blur_span_us / 2) <=
                          options_.standstill.max_motion_px);
  if (!out.pose_valid && options_.hold && status_ == TrackStatus::tracking && track_.confirmed && holdable) {
    // Unhealthy: a still target (no events to measure it on) or a lost one? Decided on the last good pose.
    TrackState after = std::move(track_);
    track_ = before;
    // An unverified fit that moved the model's image away from the last verified pose: that pose is stale.
    const bool fit_moved = after.fitted && after.fitted->t_us > before.last->t_us &&
                           image_motion_px(before.last->pose, after.fitted->pose) > options_.standstill.max_motion_px;
    if (!fit_moved && try_hold(window, t_end_us)) {
      track_.unhealthy_in_a_row = 0;
      track_.fitted.reset();
      track_.previous.reset();  // the target is still: when it moves again, predict from rest
      track_.trail.clear();
      ++counters_.holds;
      set_status(TrackStatus::holding);
      hold_previous_t_us_ = t_end_us;
      hold_contradicted_ = 0;
      hold_unmeasured_since_us_.reset();
      PoseEstimate held = held_pose(t_end_us, window.size());
      held.note = "holding: no motion near the model beyond the noise (" + out.note + ")";
      return held;
    }
    track_ = std::move(after);
  }
  counters_.unhealthy_updates += unhealthy;
  if (track_.lost) set_status(TrackStatus::lost);
  out.status = status_;
  unconfirmed(out);
  return out;
}

void PoseEstimator::unconfirmed(PoseEstimate& out) const {
  if (!out.pose_valid || out.status != TrackStatus::tracking || track_.confirmed) return;
  out.pose_valid = false;
  out.note = fmt::format("initialised: {} of {} healthy updates in a row before the track is published",
                         track_.healthy_in_a_row, track_.confirm_needed);
}

PoseEstimate PoseEstimator::track_step(TrackState& state, EventSpan window, std::int64_t t_end_us, EventSpan history,
                                       std::uint64_t& unhealthy, bool allow_unverified) const {
  PoseEstimate out;
  const camera::Pose predicted = predict(state, t_end_us);
  const EventSpan events = tracking_events(state, window, t_end_us, history);
  // Verification hook (pose-verify): the last tracked pose gives the motion each segment's support depends on.
  const std::optional<MotionHint> motion =
      state.last ? std::optional<MotionHint>(MotionHint{*state.last, t_end_us}) : std::nullopt;
  const TrackUpdate u = track_window(events, map_, model_, predicted, options_.track, motion);
  out.t_us = t_end_us;
  out.window_events = events.size();
  if (!events.empty()) out.events_span_us = events.back().t_us - events.front().t_us + 1;
  // A target cannot jump: an update far from the prediction has locked onto other edges (a wrong local
  // minimum the per-window health test cannot see).
  // Fitted, but the verification could not judge it (ran, failed, no symmetric alternative explains it better).
  const bool inconclusive =
      !u.healthy && !u.verification.reason.empty() &&
      u.verification.symmetry_log_ratio > -symmetry_decision_log_ratio(options_.track.verification);
  const bool jumped =
      (u.healthy || inconclusive) && (camera::translation_distance_m(u.T_cam_model, predicted) > options_.max_step_m ||
                                      camera::rotation_angle_deg(u.T_cam_model, predicted) > options_.max_step_deg);
  state.step_unverified = false;
  bool confirmation_failed = false;  // healthy, but the unconfirmed track's updates together showed too little
  if (inconclusive && !jumped && options_.unverified_max_us > 0 && allow_unverified &&
      t_end_us - state.last->t_us <= options_.unverified_max_us) {
    // The model explains the events but they are too few to vouch for the pose: not published, not a loss.
    state.fitted = camera::StampedPose{t_end_us, u.T_cam_model};
    state.step_unverified = true;
    state.healthy_in_a_row = 0;
    ++unhealthy;
    out.t_last_update_us = state.last->t_us;
    out.T_cam_model = state.last->pose;
    out.inliers = u.inliers;
    out.sigma_px = u.sigma_px;
    out.note = "tracking, unverified: " + u.reason;
  } else if (u.healthy && !jumped) {
    state.fitted.reset();
    state.unhealthy_in_a_row = 0;
    if (!state.confirmed) {
      state.confirm_supported += static_cast<double>(u.verification.cells_supported);
      state.confirm_expected += u.verification.cells_expected;
    }
    if (++state.healthy_in_a_row >= state.confirm_needed && !state.confirmed) {
      state.confirmed = state.confirm_supported >= state.confirm_min_coverage * state.confirm_expected;
      if (!state.confirmed) {
        // Healthy window by window, but together short of what the model's edges should show: a partial match.
        confirmation_failed = true;
        out.note = fmt::format(
            "tracking: the first {} updates show {:.0f} % of the cells the model's edges should (need {:.0f} %): "
            "not confirmed, initialising again",
            state.healthy_in_a_row, 100.0 * state.confirm_supported / std::max(state.confirm_expected, 1e-9),
            100.0 * state.confirm_min_coverage);
      }
    }
    state.previous = state.last;
    state.last = camera::StampedPose{t_end_us, u.T_cam_model};
    state.last_blur_span_us = 0;
    if (state.trail.empty() && state.previous) state.trail.push_back(*state.previous);
    state.trail.push_back(*state.last);
    while (state.trail.size() > 2 && t_end_us - state.trail.front().t_us > options_.speed_baseline_us) {
      state.trail.erase(state.trail.begin());
    }
    state.previous_update = std::move(state.last_update);
    state.last_update = u;
    publish_update(u, out);
    out.t_last_update_us = t_end_us;
  } else {
    out.t_last_update_us = state.last->t_us;
    ++unhealthy;
    ++state.unhealthy_in_a_row;
    state.healthy_in_a_row = 0;
    out.T_cam_model = state.last->pose;  // hold the last good pose; not published as valid
    out.inliers = u.inliers;
    out.sigma_px = u.sigma_px;
    out.note = jumped ? fmt::format("tracking: the update moved {:.0f} mm / {:.1f} deg from the prediction",
                                    1000.0 * camera::translation_distance_m(u.T_cam_model, predicted),
                                    camera::rotation_angle_deg(u.T_cam_model, predicted))
                      : "tracking: " + u.reason;
    if (state.unhealthy_in_a_row >= options_.lost_after_windows) {
      state.lost = true;
      state.previous.reset();
      state.trail.clear();
    }
  }
  if (!state.confirmed && !state.lost && (confirmation_failed || !(u.healthy && !jumped))) {
    // Not confirmed yet (confirm_windows, confirm_windows_without_prior): an initial pose whose next updates do not
    // all verify, or together show too little, is not tracked on; the search starts again.
    state.lost = true;
    state.previous.reset();
    state.trail.clear();
    if (!confirmation_failed) out.note += " (the track was not confirmed: initialising again)";
  }
  if (state.lost) out.pose_valid = false;
  out.status = state.lost ? TrackStatus::lost : TrackStatus::tracking;
  return out;
}

PoseEstimator::TrackState PoseEstimator::start_state(const InitOutcome& outcome) {
  TrackState state;
  state.last = camera::StampedPose{outcome.t_us, outcome.polished.T_cam_model};
  state.previous = outcome.previous;
  state.last_update = outcome.polished;
  state.last_blur_span_us = outcome.measured_at_t ? 0 : outcome.blur_span_us;
  // Advanced on the worker: handed over from a healthy last slice; the slices' healthy updates count (as if in a
  // row: the handover needs the last one healthy, and an unhealthy one among them is rare).
  state.healthy_in_a_row = outcome.caught_up_slices - static_cast<int>(outcome.caught_up_unhealthy);
  return state;
}

int PoseEstimator::catch_up(TrackState& state, std::int64_t from_us, std::int64_t to_us, EventSpan events,
                            std::uint64_t& unhealthy) const {
  // Found on an earlier window: the track starts there. The target moved while the attempt ran, so the windows
  // that passed meanwhile are tracked first, on the remembered events (window_us slices centred on their times,
  // step_us apart, at most kCatchUpMaxSlices: a long attempt is crossed in longer strides), each from the one
  // before: the current window then starts from a recent pose, not from where the target was when the attempt
  // began. Slices too sparse to track (not remembered, or windows dropped upstream) are skipped.
  const std::int64_t length = std::max<std::int64_t>(options_.track.window_us, 1);
  const std::int64_t span = to_us - from_us;
  const std::int64_t step = std::max({options_.track.step_us, span / (kCatchUpMaxSlices + 1), std::int64_t{1}});
  int slices = 0;
  const auto before = [](const Event& e, std::int64_t v) { return e.t_us < v; };
  for (std::int64_t t = from_us + step; t + step <= to_us && !state.lost; t += step) {
    const auto* first = std::lower_bound(events.data(), events.data() + events.size(), t - length / 2, before);
    const auto* last = std::lower_bound(first, events.data() + events.size(), t + length - length / 2, before);
    if (static_cast<std::size_t>(last - first) < options_.track_min_window_events) continue;
    (void)track_step(state, EventSpan(first, last), t, EventSpan(events.data(), last), unhealthy);
    ++slices;
  }
  return slices;
}

InitOutcome PoseEstimator::advance_initialisation(const InitOutcome& outcome, EventSpan events,
                                                  std::int64_t t_now_us) const {
  if (!outcome.ok) return outcome;
  TrackState state = start_state(outcome);
  std::uint64_t unhealthy = 0;
  const int slices = catch_up(state, outcome.t_us, t_now_us, events, unhealthy);
  // Handed over only from a healthy last slice: the pose thread resumes from exactly that state.
  if (state.lost || slices == 0 || state.unhealthy_in_a_row > 0 || !state.last || state.last->t_us == outcome.t_us) {
    return outcome;
  }
  InitOutcome advanced = outcome;
  advanced.t_us = state.last->t_us;
  advanced.polished.T_cam_model = state.last->pose;
  advanced.previous = state.previous;
  advanced.caught_up_slices = outcome.caught_up_slices + slices;
  advanced.caught_up_unhealthy = outcome.caught_up_unhealthy + unhealthy;
  return advanced;
}

double PoseEstimator::image_motion_px(const camera::Pose& a, const camera::Pose& b) const {
  double moved2 = 0.0;
  for (const camera::Segment3& s : model_.segments_m) {
    for (const Eigen::Vector3d* P : {&s.a_m, &s.b_m}) {
      const Eigen::Vector3d p0 = a.apply(*P), p1 = b.apply(*P);
      if (!(p0.z() > 1e-3) || !(p1.z() > 1e-3)) continue;
      moved2 = std::max(moved2, (p0.head<2>() / p0.z() - p1.head<2>() / p1.z()).squaredNorm());
    }
  }
  return std::sqrt(moved2) * focal_px(camera_);
}

double PoseEstimator::image_motion_per_window_px(const TrackState& state) const {
  if (!state.previous || !state.last || state.last->t_us <= state.previous->t_us) return 0.0;
  return image_motion_px(state.previous->pose, state.last->pose) /
         static_cast<double>(state.last->t_us - state.previous->t_us) *
         static_cast<double>(std::max<std::int64_t>(options_.track.window_us, 1));
}

bool PoseEstimator::signal_near(EventSpan events, const camera::Pose& T_cam_model) {
  if (!probe_.start(camera_, map_, model_, T_cam_model, options_.standstill)) return false;
  // The events the update used (a sparse window extended to the newest events): their span is the exposure.
  std::int64_t exposure_us = std::max<std::int64_t>(options_.track.window_us, 1);
  if (!events.empty()) exposure_us = std::max(exposure_us, events.back().t_us - events.front().t_us + 1);
  const StandstillEvidence ev =
      probe_.observe(events, exposure_us, std::numeric_limits<std::int64_t>::min(), exposure_us);
  noise_rate_hz_ = ev.background_rate_hz;
  // Significant, and enough of it for the tracker's own minimum: the inliers of a fit (within ~4.7 sigma of the
  // edges, inside the near band at sigma < 0.7 px) are then mostly the target's events, not the noise's.
  return ev.signal &&
         static_cast<double>(ev.near) - ev.expected_near >= static_cast<double>(options_.track.min_inliers);
}

bool PoseEstimator::try_hold(EventSpan window, std::int64_t t_end_us) {
  (void)t_end_us;
  if (!track_.last) return false;
  if (image_motion_per_window_px(track_) > options_.hold_entry_max_motion_px) {
    // The last update moved the model faster than a target that stops within a window can: a fit on the vanishing
    // events, not to be held. The pose before it may be (the tests below then decide on its model).
    if (!track_.previous || !track_.previous_update) return false;
    track_.last = track_.previous;
    track_.last_update = *track_.previous_update;
    track_.previous.reset();
    track_.trail.clear();
  }
  // With raw events two tests watch the hold (one false-alarm budget: each at half the significance). The kept
  // events have little noise, so few of the target's are significant; the raw ones hold all of a creeping target's
  // (a denoiser deletes most of them) against the sensor's whole noise.
  StandstillOptions so = options_.standstill;
  if (!raw_.empty()) so.significance /= 2.0;
  if (!standstill_.start(camera_, map_, model_, track_.last->pose, so)) return false;
  standstill_raw_.stop();
  if (!raw_.empty()) (void)standstill_raw_.start(camera_, map_, model_, track_.last->pose, so);
  const std::int64_t window_us = std::max<std::int64_t>(options_.track.window_us, 1);
  hold_newest_counted_us_ = std::numeric_limits<std::int64_t>::min();
  hold_newest_raw_us_ = std::numeric_limits<std::int64_t>::min();
  const StandstillEvidence ev = observe_hold(window, window_us, true, window_us);
  if (ev.moving || ev.unexplained) {
    standstill_.stop();
    standstill_raw_.stop();
    return false;
  }
  hold_per_px_ = pose_change_per_px(camera_, model_, track_.last->pose);
  return true;
}

StandstillEvidence PoseEstimator::observe_hold(EventSpan window, std::int64_t window_us, bool all_fresh,
                                               std::int64_t fresh_us) {
  constexpr std::int64_t kAll = std::numeric_limits<std::int64_t>::min();
  StandstillEvidence ev =
      standstill_.observe(window, window_us, all_fresh ? kAll : hold_newest_counted_us_ + 1, fresh_us);
  if (!window.empty()) hold_newest_counted_us_ = std::max(hold_newest_counted_us_, window.back().t_us);
  if (!standstill_raw_.active() || raw_.empty()) return ev;
  const StandstillEvidence raw =
      standstill_raw_.observe(raw_, window_us, all_fresh ? kAll : hold_newest_raw_us_ + 1, fresh_us);
  hold_newest_raw_us_ = std::max(hold_newest_raw_us_, raw_.back().t_us);
  ev.moving = ev.moving || raw.moving;
  ev.unexplained = ev.unexplained || raw.unexplained;
  ev.implied_motion_px = std::max(ev.implied_motion_px, raw.implied_motion_px);
  return ev;
}

PoseEstimate PoseEstimator::held_pose(std::int64_t t_end_us, std::size_t window_events) const {
  PoseEstimate out;
  out.t_us = t_end_us;
  out.t_last_update_us = track_.last->t_us;
  out.T_cam_model = track_.last->pose;
  out.pose_valid = true;
  out.status = TrackStatus::holding;
  out.covariance = track_.last_update.covariance;
  out.covariance_known = track_.last_update.covariance_known;
  out.sigma_px = track_.last_update.sigma_px;
  out.window_events = window_events;
  return out;
}

PoseEstimate PoseEstimator::hold_step(EventSpan window, std::int64_t t_end_us, EventSpan history) {
  const std::int64_t window_us = std::max<std::int64_t>(options_.track.window_us, 1);
  const std::int64_t fresh_us = std::clamp<std::int64_t>(t_end_us - hold_previous_t_us_, 0, window_us);
  hold_previous_t_us_ = t_end_us;
  const StandstillEvidence ev = observe_hold(window, window_us, false, fresh_us);
  noise_rate_hz_ = ev.background_rate_hz;
  if (!ev.moving) {
    hold_unmeasured_since_us_.reset();
    track_.unhealthy_in_a_row = 0;  // "in a row": a window without motion ends a run of unmeasurable ones
    hold_contradicted_ = ev.unexplained ? hold_contradicted_ + 1 : 0;
    if (hold_contradicted_ < options_.hold_contradicted_windows) {
      PoseEstimate out = held_pose(t_end_us, window.size());
      if (ev.unexplained) {
        out.note = fmt::format("holding, but activity away from the model for {} windows", hold_contradicted_);
      }
      return out;
    }
    // The hold is contradicted for too long: the target may have moved where the model cannot see it.
    PoseEstimate out = held_estimate(window, t_end_us);
    track_.lost = true;
    track_.previous.reset();
    track_.trail.clear();
    set_status(TrackStatus::lost);
    out.status = status_;
    out.note = fmt::format("lost: activity away from the held model for {} windows in a row", hold_contradicted_);
    return out;
  }
  // Motion near the model: measure it from the held pose (zero velocity).
  const camera::Pose& held = track_.last->pose;
  // The window first: the motion's events are fresh, the extension to older events adds the still period's noise (a
  // fit on 100 ms of it started 30 mm off on a 10 s stop at 5 Hz/px).
  EventSpan events = window;
  TrackUpdate u = track_window(events, map_, model_, held, options_.track);
  if (u.healthy && !signal_near(events, u.T_cam_model)) {
    u.healthy = false;
    u.reason = "no more events near the fitted model than the noise explains";
  }
  if (!u.healthy && ev.implied_motion_px <= options_.track_max_blur_px) {
    // Too few events in the window (a slow creep, a sparse restart): the events since the held pose was measured
    // (at most track_history_max_us), the newest that hold track_min_events of the target. The model's image moved
    // at most about implied_motion_px over them: within the blur a tracking history allows.
    const std::int64_t span_us = std::min(t_end_us - track_.last->t_us, options_.track_history_max_us);
    const EventSpan longer = tracking_events(noise_rate_hz_, span_us, window, t_end_us, history);
    if (longer.size() > window.size()) {
      TrackUpdate v = track_window(longer, map_, model_, held, options_.track);
      if (v.healthy && signal_near(longer, v.T_cam_model)) {
        u = std::move(v);
        events = longer;
      }
    }
  }
  // From rest, and seen first within the association gate of the held model: a measured pose whose model image
  // lies further than that gate from the held one is not this motion's onset (a fit on its few events and the
  // noise, seen 25 mm / 11 deg off).
  const bool jumped = u.healthy && (camera::translation_distance_m(u.T_cam_model, held) > options_.max_step_m ||
                                    camera::rotation_angle_deg(u.T_cam_model, held) > options_.max_step_deg ||
                                    image_motion_px(held, u.T_cam_model) > options_.standstill.gate_px);
  PoseEstimate out;
  out.t_us = t_end_us;
  out.window_events = events.size();
  if (!events.empty()) out.events_span_us = events.back().t_us - events.front().t_us + 1;
  if (u.healthy && !jumped) {
    track_.unhealthy_in_a_row = 0;
    track_.previous.reset();
    track_.trail.clear();
    track_.fitted.reset();
    track_.last = camera::StampedPose{t_end_us, u.T_cam_model};
    track_.last_update = u;
    track_.last_blur_span_us = 0;
    ++counters_.hold_resumes;
    set_status(TrackStatus::tracking);
    publish_update(u, out);
    out.t_last_update_us = t_end_us;
    out.status = status_;
    return out;
  }
  // It moves, but no pose can be measured.
  const std::string why = jumped ? std::string("the update jumped") : u.reason;
  // What the motion may stand for in the pose, in its weakest direction (StandstillOptions::max_rotation_deg).
  const double implied_deg = ev.implied_motion_px * hold_per_px_.rotation_deg;
  const double implied_m = ev.implied_motion_px * hold_per_px_.translation_m;
  const bool within_pose_bound =
      implied_deg <= options_.standstill.max_rotation_deg && implied_m <= options_.standstill.max_translation_m;
  if (!jumped && ev.implied_motion_px <= options_.standstill.max_motion_px && within_pose_bound) {
    // A significant excess worth a measurement (min_motion_events), but less motion than a hold tolerates (in the
    // image and in the pose it may stand for): held.
    PoseEstimate kept = held_pose(t_end_us, window.size());
    kept.note =
        fmt::format("holding: motion near the model (~{:.1f} px) too small to measure: {}", ev.implied_motion_px, why);
    return kept;
  }
  // Not held (a held pose must not become a wrong one). Unhealthy towards a loss only once the motion since the held
  // pose may exceed what a tracking history's blur allows (track_max_blur_px), or has stayed unmeasured for
  // track_history_max_us: until then a target starting slowly is measured as soon as its events suffice (the
  // retry above spans everything since the held pose).
  ++counters_.unhealthy_updates;
  if (!hold_unmeasured_since_us_) hold_unmeasured_since_us_ = t_end_us;
  const bool counts = jumped || ev.implied_motion_px > options_.track_max_blur_px ||
                      t_end_us - *hold_unmeasured_since_us_ >= options_.track_history_max_us;
  if (counts) ++track_.unhealthy_in_a_row;
  out.T_cam_model = held;
  out.t_last_update_us = track_.last->t_us;
  out.inliers = u.inliers;
  out.sigma_px = u.sigma_px;
  out.note = fmt::format(
      "holding ended: motion near the model (~{:.1f} px, up to {:.1f} deg / {:.1f} mm) that tracking cannot measure: "
      "{}",
      ev.implied_motion_px, implied_deg, 1000.0 * implied_m, why);
  if (track_.unhealthy_in_a_row >= options_.lost_after_windows) {
    track_.lost = true;
    set_status(TrackStatus::lost);
    out.status = status_;
  } else {
    out.status = TrackStatus::tracking;  // not valid; the hold's evidence is kept for the next window
  }
  return out;
}

}  // namespace evpipe::pose
