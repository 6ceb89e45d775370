#pragma once
// The per-window pose state machine: initialise (OPnL with automatic correspondences) -> track (MM) -> on loss
// re-initialise around the last good pose. One call per window of denoised events; no threads here.
//
//   initialising --init ok--> tracking --lost_after_windows unhealthy updates--> lost --init ok--> tracking
//                              |      ^
//        unhealthy update, but |      | excess events near the model (it moves again): measured from the held
//        the data shows no     v      | pose with zero velocity; unmeasurable -> unhealthy (-> lost)
//        motion (standstill)  holding --activity elsewhere the model does not explain, hold_contradicted_windows
//                                       in a row--> lost
//
// While initialising or lost the estimate carries pose_valid = false and the last good pose (or the prior); while
// holding, pose_valid = true and the last measured pose (t_last_update_us says when it was measured).

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/prior.hpp"
#include "evpipe/core/event.hpp"
#include "evpipe/pose/initialiser.hpp"
#include "evpipe/pose/pose_filter.hpp"
#include "evpipe/pose/projection.hpp"
#include "evpipe/pose/standstill.hpp"
#include "evpipe/pose/tracker.hpp"
#include "evpipe/pose/types.hpp"

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace evpipe::pose {

struct EstimatorOptions {
  InitialiserOptions init;
  TrackerOptions track;
  /// Consecutive unhealthy tracking updates before the track is declared lost (the pose is held meanwhile).
  int lost_after_windows = 3;
  /// Windows with fewer events are not worth an initialisation attempt (counted as a failed attempt).
  std::size_t init_min_events = 200;
  /// A slow target gives sparse 30 ms windows in which no line is long enough to detect: initialisation then
  /// uses the events of the last init_accumulate_us (up to init_target_events, the newest kept), tracking
  /// still uses the window alone.
  std::int64_t init_accumulate_us = 300'000;
  std::size_t init_target_events = 4000;
  /// > 0: every other attempt (and every attempt whose init_accumulate_us holds fewer than init_min_events) uses the
  /// newest init_long_target_events of the last init_long_accumulate_us instead (a slow target's edges move too
  /// little in 300 ms for LSD: no line at 0.01-0.02 m/s). Only attempts that search around a pose (the configured
  /// prior, or the last good pose after a loss) use it: without one, the clutter scenes accepted wrong board poses
  /// from the long accumulation (docs/history.md, "Sparse windows and slow targets": clutter wrong confident 2 -> 26).
  /// After a loss both accumulations span at most what the model's image took to move track_max_blur_px at the last
  /// tracked speed (a target lost while moving keeps moving: its long accumulation is a blur), until the last good
  /// pose is older than the longer of the two accumulations.
  std::int64_t init_long_accumulate_us = 1'000'000;
  std::size_t init_long_target_events = 20'000;
  /// Tracking on a sparse window (slow target, most events filtered out, or the target's events drowned in noise)
  /// uses an accumulated history instead: the newest events holding track_min_events events of the target (the
  /// count minus the noise the measured noise rate explains over the span). Its span is bounded by the motion:
  /// at most track_max_blur_px of image motion at the last tracked speed (a still or slow target: long spans),
  /// never more than track_history_max_us; track_max_span_us when the speed is not known yet (pose.md §8 and
  /// ELOPET: windows sized by count, capped in time).
  std::size_t track_min_events = 1500;
  std::int64_t track_max_span_us = 100'000;
  double track_max_blur_px = 3.0;
  std::int64_t track_history_max_us = 1'000'000;
  /// The speed that bounds a history's span is measured between the last tracked pose and the oldest one of the
  /// same run of tracking updates within this baseline: a slow target's pose jitter between two consecutive windows
  /// reads as speed (0.3 px of jitter over a 30 ms step is 10 px/s, a 0.3 s span where the target moves 2 px/s; over
  /// 100 ms, 3 px/s). Longer baselines underrate a turning target's speed (300 ms: more planar poses 2-5 deg off in
  /// the clutter scenes). 0 (default): the last two poses. With the tracker's segment motion, 100 ms gave 3 more
  /// wrong confident board poses (clutter lines with and without a prior, slow planar 0.04 m/s at 5 Hz/px; 2.0-2.4
  /// deg) and no coverage the long initialisation accumulation did not already give (one run, results scenes).
  std::int64_t speed_baseline_us = 0;
  /// ... but only when the window has at least this many events of its own (a window without the target is
  /// not tracked on the target's past events).
  std::size_t track_min_window_events = 10;
  /// Re-initialisation after a loss searches around the last good pose with these tolerances.
  double reinit_position_tolerance_m = 0.3;
  double reinit_angle_tolerance_deg = 45.0;
  /// Largest change from the predicted pose one update may make; a bigger one counts as unhealthy (the tracker
  /// locked onto other edges). Per window: 0.05 m and 10 deg are 1.7 m/s and 330 deg/s at 30 ms windows.
  double max_step_m = 0.05;
  double max_step_deg = 10.0;
  /// Predict the next pose by constant velocity from the last two tracked poses (else: the last pose).
  bool constant_velocity = true;
  /// An update that fits the window (the tracker's health tests and the step gate pass, and the events near the
  /// fitted model exceed the noise) but whose verification is inconclusive (too little support along the model to
  /// judge; a better symmetric alternative is a refutation) is not published and does not count towards
  /// lost_after_windows: the model explains the events, there is just not enough of them to vouch for the pose. The
  /// track is lost when no update was verified for this long. 0 (default): such updates count as unhealthy. Off:
  /// measured with 1 s on the standstill and slow scenes (docs/history.md) it kept tracks alive through the
  /// inconclusive windows of a moving target at 5 Hz/px, but a target that stopped during such a run could then
  /// not be held (its last verified pose was older than the unverified fits) and was lost.
  std::int64_t unverified_max_us = 0;
  /// Standstill (docs/algorithms.md "Holding"): an unhealthy update whose window shows no motion near the last
  /// pose's model beyond the noise (standstill.hpp) holds that pose (status holding) instead of counting as
  /// unhealthy. false: every unhealthy update counts (the behaviour before holding).
  bool hold = true;
  StandstillOptions standstill;
  /// Fusion of the track's window poses over time (pose_filter.hpp): the published tracking and holding poses are
  /// the filter's, with its covariance; the tracker itself still starts each window from its own poses.
  PoseFilterOptions filter;
  /// A hold starts only when the last tracked motion moved the model's image by at most this per window (a
  /// target that was moving fast cannot have stopped within one window; its events vanishing means something
  /// else).
  double hold_entry_max_motion_px = 3.0;
  /// Windows in a row with activity elsewhere that the model does not explain (the target may have moved while
  /// unseen, or something else moves) that end a hold: lost.
  int hold_contradicted_windows = 10;

  /// A (re-)initialised track is published (pose_valid) only from its confirm_windows-th healthy tracking update in
  /// a row on; the updates before carry status tracking but pose_valid = false, and an unconfirmed track is never
  /// held. A wrong initial pose that passed every single-window test is not tracked on: the next updates fail
  /// (seen: 36 mm / 15 deg on a decoy, 20 mm / 6 deg on the roadheader without a prior, planar poses 2-5 deg off
  /// from 300 ms accumulations), and they are not published. 0: the initial pose itself is published.
  int confirm_windows = 0;
  /// The same without a configured prior (every initialisation then searches the whole view, or around a pose found
  /// that way): at least this many. The initial pose's verification has no motion to say which segments must show
  /// support (every one is required; half of them and a third of their expected cells suffice); the updates after it
  /// have the pose before them. Clutter beside the target let wrong initial poses (the board 170-180 deg / 0.3-0.5 m
  /// off) pass alone and fail at the next windows. An unconfirmed track whose update is not healthy is dropped (the
  /// search starts again), so the confirmation is that many healthy updates in a row right after the initialisation.
  int confirm_windows_without_prior = 3;
  /// ... and those updates together must show this share of the cells their edges should show
  /// (VerifyResult::cells_supported / cells_expected summed), else the track is dropped. A pose that lays part of
  /// the model on other structure shows about half of them, window after window, and passes the single window's
  /// test (min_coverage, a third) now and then; a true pose shows most of them (measured 0.8-0.95 on the synthetic
  /// sets). The threshold is the middle between the two, two thirds.
  double confirm_min_coverage_without_prior = 2.0 / 3.0;
  /// A track started by the direct alignment (InitialiserOptions::direct_alignment) is published from this many
  /// healthy updates on (at least confirm_windows): the alignment has no correspondences, and its search's best place
  /// can nearly tie with a wrong one (seq_0003 at 255 ms: ridge contrast 149.0 against 148.9, 68 mm / 19 deg off,
  /// verified alone). One: seq_0003's span within 10 mm / 1 deg 67 -> 59 % with `significance`, 82 -> 78 % raw.
  int confirm_windows_direct = 1;
  /// Compare every initial and tracked pose with the pose turned by the model's partial symmetries
  /// (model_symmetries(), filled into init.verification / track.verification when they list none): a pose whose
  /// symmetric alternative explains the window better is refused, and without a prior an initial pose whose
  /// alternative it cannot rule out is refused too.
  bool compare_symmetries = true;

  /// Throws std::invalid_argument naming the field when a value is out of range.
  void validate() const;
};

/// The result of one window.
struct PoseEstimate {
  std::int64_t t_us{0};  ///< sensor time the pose refers to (the time passed with the window: its middle)
  /// Sensor time of the last window that measured the pose: t_us while tracking, older while holding, the
  /// last measurement (0 if none yet) while initialising or lost.
  std::int64_t t_last_update_us{0};
  camera::Pose T_cam_model;
  bool pose_valid{false};  ///< true tracking / holding; false initialising / lost: the last good pose or the prior
  Covariance6 covariance{Covariance6::Zero()};
  bool covariance_known{false};
  TrackStatus status{TrackStatus::initialising};
  std::size_t window_events{0};    ///< events the estimate used (a sparse window is extended, see options)
  std::int64_t events_span_us{0};  ///< the time those events span (a measured pose; 0 otherwise)
  std::size_t inliers{0};
  double sigma_px{0.0};
  bool initialised_now{false};  ///< this window ran a successful (re-)initialisation
  std::string note;             ///< why the pose is not valid / what happened (empty when tracking normally)
};

/// One initialisation attempt cut out of the estimator (prepare_initialisation), so that it can run on another
/// thread: run_initialisation() reads only the estimator's fixed inputs (camera, model, options).
struct InitJob {
  std::vector<Event> events;  ///< the window, or the accumulated events when it is sparse
  /// The events a tracking update at t_us uses (tracking_events()), when they differ from `events`: a pose found
  /// on accumulated events is a blur of the target's motion over their span, so it is polished on these before
  /// it is published as the pose at t_us. Empty: the same as `events`.
  std::vector<Event> fresh;
  /// With the long accumulation (init_long_accumulate_us): the shorter one, the found pose is polished on it too
  /// and that polish wins when healthy (fresher: a moving target's long accumulation is blurred by its motion).
  std::vector<Event> shorter;
  std::int64_t t_us{0};                       ///< the window time a found pose refers to
  std::optional<camera::PosePrior> search;    ///< searched first: the configured prior, or around the last good pose
  std::optional<camera::PosePrior> fallback;  ///< searched when the first search fails (every other attempt)
  std::uint64_t generation{0};                ///< reset() between preparing and completing discards the result
};

/// What an attempt found.
struct InitOutcome {
  std::int64_t t_us{0};
  bool ok{false};
  TrackUpdate polished;  ///< the found pose polished by the tracker on the job's events, then its fresh ones (ok)
  /// false: the fresh events did not give a healthy polish; the track starts from the accumulation's pose, but this
  /// window's pose is not published as valid (it is a blur of the motion over the accumulation's span).
  bool measured_at_t{true};
  /// !measured_at_t: the time the events the pose was fitted on span (it stands for their middle, not for t_us).
  std::int64_t blur_span_us{0};
  /// Found by the direct alignment (InitResult::direct): published after confirm_windows_direct healthy updates.
  bool direct{false};
  std::string note;  ///< why not ok
  std::uint64_t generation{0};
  /// Set by advance_initialisation(): the track was carried on the worker over the windows that passed during
  /// the attempt; t_us and polished are then those of the last slice tracked, `previous` the pose before it.
  std::optional<camera::StampedPose> previous;
  int caught_up_slices{0};
  std::uint64_t caught_up_unhealthy{0};  ///< unhealthy updates among those slices
};

/// Counters over the estimator's life (for the run summary and the statistics message).
struct EstimatorCounters {
  std::uint64_t windows{0};
  std::uint64_t init_attempts{0};
  std::uint64_t init_successes{0};
  std::uint64_t losses{0};  ///< tracking → lost transitions
  std::uint64_t unhealthy_updates{0};
  std::uint64_t windows_by_status[4]{0, 0, 0, 0};  ///< indexed by TrackStatus
  std::uint64_t holds{0};                          ///< tracking → holding transitions
  std::uint64_t hold_resumes{0};                   ///< holding → tracking (measured again from the held pose)
};

class PoseEstimator {
 public:
  /// Throws std::invalid_argument when the options are invalid or the model has fewer than 4 segments.
  PoseEstimator(camera::CameraModel camera, camera::LineModel model, std::optional<camera::PosePrior> prior,
                EstimatorOptions options = {});
  /// One window of denoised events (time-ordered) and the sensor time its pose refers to. evpipe passes the
  /// window's middle (a pose fitted to a whole window represents its middle); the catch-up after an attempt
  /// run elsewhere cuts its slices centred on such times (a caller passing window ends gets slices half a
  /// window late, which only costs their newest half).
  /// `raw` (optional): the same window's events before denoising. A hold's standstill test (StandstillMonitor) then
  /// watches them as well as `window`: a denoiser deletes much of a creeping target's events, and on the kept ones
  /// alone a roadheader drifting 0.03 m/s under 5 Hz/px was held 20 mm off.
  PoseEstimate process(EventSpan window, std::int64_t t_end_us, EventSpan raw = {});
  /// Forget the track (after a clock discontinuity or a device reconnect): next window initialises again.
  void reset();

  // Initialisation elsewhere. process() runs an attempt on the window that needs one and returns when it is
  // done (50-500 ms); a caller that must keep publishing meanwhile splits it (stages::PoseProcessor with a worker
  // thread):
  //   needs_initialisation() -> prepare_initialisation(window) -> run_initialisation(job) on the worker,
  //   initialising_window(window) for each window while it runs, complete_initialisation(outcome, window) once
  //   it is done. Every call except run_initialisation counts as one window.
  [[nodiscard]] bool needs_initialisation() const noexcept {
    return status_ != TrackStatus::tracking && status_ != TrackStatus::holding;
  }
  /// A window that needs initialisation: the job for it (`now` then says the attempt started), or nullopt and
  /// `now` saying why not (too few events).
  std::optional<InitJob> prepare_initialisation(EventSpan window, std::int64_t t_end_us, PoseEstimate& now);
  /// The attempt. Const and touching only the camera, model and options: safe on another thread while the
  /// owner keeps calling the other members.
  [[nodiscard]] InitOutcome run_initialisation(const InitJob& job) const;
  /// On the worker, after run_initialisation(): tracks the windows that passed during the attempt, so that the
  /// window applying the outcome has (almost) nothing left to catch up and is not late. `events`: every event
  /// from the attempt's window on (time-ordered; the job's events first), up to the window at `t_now_us`. The
  /// slices complete_initialisation() would track (their stride is set by the span up to t_now_us, and a sparse
  /// slice's history starts at the job's events). Const, like run_initialisation.
  /// Returns the outcome unchanged when it failed or when the track is lost on the way (complete_initialisation
  /// then catches up as before and reports the loss).
  [[nodiscard]] InitOutcome advance_initialisation(const InitOutcome& outcome, EventSpan events,
                                                   std::int64_t t_now_us) const;
  /// A window that arrives while an attempt runs: remembered (it feeds the next attempt), not valid.
  PoseEstimate initialising_window(EventSpan window, std::int64_t t_end_us);
  /// Applies a finished attempt. On success the track starts from the found pose (at the job's time) and this
  /// window is tracked from it (the estimate says initialised_now); an outcome from before a reset() is dropped.
  PoseEstimate complete_initialisation(const InitOutcome& outcome, EventSpan window, std::int64_t t_end_us);

  /// While an attempt runs elsewhere every event since its window is remembered for the catch-up, up to this
  /// many (3.2 MB; 0.2 s at 1 Mev/s): a longer attempt catches up over the newest.
  static constexpr std::size_t kCatchUpMaxEvents = 200'000;
  /// At most this many tracking updates catch up an attempt (~1 ms each; on the worker when the caller uses
  /// advance_initialisation, else on the window that applies it).
  static constexpr std::int64_t kCatchUpMaxSlices = 8;
  /// A tracking history (track_min_events of the target, see the options) holds at most this many events
  /// (3.2 MB): a slow target under heavy noise is tracked on the newest.
  static constexpr std::size_t kHistoryMaxEvents = 200'000;

  [[nodiscard]] TrackStatus status() const noexcept { return status_; }
  [[nodiscard]] const EstimatorCounters& counters() const noexcept { return counters_; }

 private:
  std::optional<InitJob> make_job(EventSpan window, std::int64_t t_end_us, PoseEstimate& skipped);
  [[nodiscard]] PoseEstimate held_estimate(EventSpan window, std::int64_t t_end_us) const;
  PoseEstimate apply_initialisation(const InitOutcome& outcome, PoseEstimate out);
  /// The track between windows: what one tracking update reads and writes.
  struct TrackState {
    std::optional<camera::StampedPose> last;      ///< last good pose
    std::optional<camera::StampedPose> previous;  ///< the one before (for constant velocity)
    int unhealthy_in_a_row{0};
    bool lost{false};         ///< lost_after_windows unhealthy updates in a row
    TrackUpdate last_update;  ///< the update that measured `last` (its covariance is the held pose's)
    /// `last` found on accumulated events its window did not confirm (InitOutcome::blur_span_us): their span, 0 when
    /// `last` was measured at its time.
    std::int64_t last_blur_span_us{0};
    std::optional<TrackUpdate> previous_update;  ///< the one that measured `previous`
    /// The tracked poses of the current run of updates (since the last start, hold or resume), oldest first, within
    /// speed_baseline_us of the newest: the baseline of history_span_us's speed.
    std::vector<camera::StampedPose> trail;
    int healthy_in_a_row{0};  ///< healthy updates in a row since the initialisation
    bool confirmed{false};    ///< confirm_needed healthy updates in a row seen since the initialisation
    int confirm_needed{0};    ///< confirm_windows, or confirm_windows_without_prior for a track found without one
    double confirm_min_coverage{0.0};  ///< confirm_min_coverage_without_prior for a track found without a prior
    double confirm_supported{0.0};     ///< the unconfirmed updates' supported cells, summed
    double confirm_expected{0.0};      ///< ... and the cells their edges should show (VerifyResult::cells_expected)
    /// The background rate (events per pixel per second) an accumulated history's noise is estimated with: the
    /// estimator's last measurement (noise_rate_hz_), 0 on a worker's catch-up (the window count alone).
    double noise_rate_hz{0.0};
    /// The newest update that fitted the window (tracker-healthy, within the step gate) but that the verification
    /// could not confirm (too little support to judge, not refuted): never published, only predicted from.
    std::optional<camera::StampedPose> fitted{};
    bool step_unverified{false};  ///< the last step was such an update
  };
  /// history: the remembered events up to this window (recent_, or a prefix of it when catching up).
  PoseEstimate track(EventSpan window, std::int64_t t_end_us, EventSpan history);
  /// The track a successful outcome starts: its pose at its time, and the pose before when it was advanced.
  static TrackState start_state(const InitOutcome& outcome);
  /// One tracking update of `state` (const: also run on the worker by advance_initialisation).
  /// allow_unverified: an inconclusive verification may continue the track unpublished (unverified_max_us; the
  /// caller then checks the fit's support); else it counts as unhealthy (the worker's catch-up).
  PoseEstimate track_step(TrackState& state, EventSpan window, std::int64_t t_end_us, EventSpan history,
                          std::uint64_t& unhealthy, bool allow_unverified = false) const;
  /// The catch-up slices after a found pose at from_us, up to the window at to_us, over `events` (the
  /// remembered events). Returns the slices tracked; stops when the state is lost.
  int catch_up(TrackState& state, std::int64_t from_us, std::int64_t to_us, EventSpan events,
               std::uint64_t& unhealthy) const;
  PoseEstimate counted(PoseEstimate out);
  void remember(EventSpan window, std::int64_t t_us);
  /// After a tracking update (or a catch-up): reinit_span_us_ from the track's speed, 0 while holding.
  void note_speed();
  [[nodiscard]] EventSpan tracking_events(EventSpan window, std::int64_t t_us, EventSpan history) const {
    return tracking_events(track_, window, t_us, history);
  }
  /// The events a tracking update of `state` uses (the window, or the accumulated history: track_min_events).
  [[nodiscard]] EventSpan tracking_events(const TrackState& state, EventSpan window, std::int64_t t_us,
                                          EventSpan history) const;
  /// The newest events of `history` that hold track_min_events of the target beyond the noise at noise_rate_hz, none
  /// older than span_us before t_us (the window alone when it is rich enough or (almost) empty).
  [[nodiscard]] EventSpan tracking_events(double noise_rate_hz, std::int64_t span_us, EventSpan window,
                                          std::int64_t t_us, EventSpan history) const;
  /// The span (us) over which the model's image moves track_max_blur_px at the state's last tracked speed
  /// (track_max_span_us when unknown), at most track_history_max_us.
  [[nodiscard]] std::int64_t history_span_us(const TrackState& state) const;
  [[nodiscard]] camera::Pose predict(const TrackState& state, std::int64_t t_end_us) const;
  void set_status(TrackStatus s);
  /// Standstill: after an unhealthy update (state restored to before it), does this window allow a hold at the
  /// last pose? Starts the monitor when it does.
  bool try_hold(EventSpan window, std::int64_t t_end_us);
  /// Do the events an update used have significantly more events near the model at this pose than the noise
  /// explains (and at least the tracker's min_inliers more)?
  bool signal_near(EventSpan events, const camera::Pose& T_cam_model);
  /// A window while holding.
  PoseEstimate hold_step(EventSpan window, std::int64_t t_end_us, EventSpan history);
  PoseEstimate held_pose(std::int64_t t_end_us, std::size_t window_events) const;
  /// A tracking pose of a track not yet confirmed (confirm_windows) is not published as valid.
  void unconfirmed(PoseEstimate& out) const;
  [[nodiscard]] double image_motion_per_window_px(const TrackState& state) const;
  /// Largest image motion (px) of the model's segment ends between two poses.
  [[nodiscard]] double image_motion_px(const camera::Pose& a, const camera::Pose& b) const;

  camera::CameraModel camera_;
  /// The camera's undistortion table, built with the estimator (at start-up) and only read after: the tracking
  /// updates on the pose thread and on an initialisation worker share it (the camera overload of track_window
  /// would build one per thread on its first call: ~10 ms on the window that first tracks).
  UndistortMap map_;
  camera::LineModel model_;
  std::optional<camera::PosePrior> prior_;
  EstimatorOptions options_;
  TrackStatus status_{TrackStatus::initialising};
  TrackState track_;
  std::vector<Event> recent_;  ///< the newest events (init_accumulate_us, at most a few thousand)
  /// The span over which the model's image moved track_max_blur_px at the speed of the newest tracking update that
  /// had one (history_span_us); 0 while none had, or once the target was held still. After a loss it bounds the
  /// re-initialisation's accumulations (make_job) until the last good pose is older than the long accumulation.
  std::int64_t reinit_span_us_{0};
  std::uint64_t generation_{0};
  std::optional<std::int64_t> attempt_t_us_;  ///< an attempt prepared and not completed: its window's time
  StandstillMonitor standstill_;              ///< active while holding (the windows' events)
  StandstillMonitor standstill_raw_;          ///< ... on process()'s raw events, when given
  /// Observes a hold window on both monitors (the raw one when process() got raw events): motion or unexplained
  /// activity in either; the kept events' noise rate.
  StandstillEvidence observe_hold(EventSpan window, std::int64_t window_us, bool all_fresh, std::int64_t fresh_us);
  PoseChangePerPx hold_per_px_;                      ///< the held pose's pose_change_per_px (set when a hold starts)
  StandstillMonitor probe_;                          ///< signal_near's scratch
  std::int64_t hold_previous_t_us_{0};               ///< the previous window's time while holding
  std::optional<std::int64_t> last_published_t_us_;  ///< time of the track's last pose published as tracking
  int hold_contradicted_{0};                         ///< windows in a row with unexplained activity while holding
  /// While holding: the first window of the current run of motion that tracking could not measure.
  std::optional<std::int64_t> hold_unmeasured_since_us_;
  std::int64_t hold_newest_counted_us_{0};  ///< newest event counted into the hold's totals
  std::int64_t hold_newest_raw_us_{0};      ///< ... of the raw events
  EventSpan raw_{};  ///< during process(): its `raw` events (the hold's standstill test counts them too)
  /// Background activity near the model (events per pixel per second), measured by the last support test
  /// (signal_near) or hold window: what the noise explains of an accumulated history's events. The Poisson part
  /// only (StandstillEvidence::background_rate_hz): clutter beside the target is not noise, and counted as noise it
  /// made every window of the real board (7 000 events, 6.9 Hz/px of "noise" from its monitor's border) a sparse one
  /// tracked on 100 ms of events, 7 px of motion across a grid 5.9 px apart.
  double noise_rate_hz_{0.0};
  /// Fusion of the published poses (options_.filter), and the last two fused ones by measurement time (a hold
  /// holds the last pose, or the one before when the last moved too fast to have stopped: try_hold).
  PoseFilter filter_;
  struct Fused {
    std::int64_t t_us;  ///< the measurement's time
    FusedPose pose;
  };
  std::array<std::optional<Fused>, 2> fused_;  ///< newest first
  /// The published pose of a window: the filter's fusion of a measured tracking pose, the fused pose a hold holds.
  void fuse(PoseEstimate& out);
  EstimatorCounters counters_;
};

}  // namespace evpipe::pose
