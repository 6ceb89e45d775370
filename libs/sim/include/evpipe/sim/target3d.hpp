#pragma once
// Events of a 3D line-model target moving in front of a fixed DAVIS camera (evsim's pose scenes).
//
// Event model (docs/simulation.md): every model segment is a straight high-contrast edge. Across the edge
// the log intensity steps by `contrast_log`, spread over a ramp `blur_px` wide. A pixel fires an event each
// time the log intensity at its centre has changed by the contrast threshold since its last event, so one
// edge crossing gives n = floor(contrast_log / threshold) events, at the n evenly spaced offsets
// (k - 0.5) / n * blur_px - blur_px / 2 from the edge line (k = 1..n): strong edges fire more than once,
// at the sub-frame times the ramp passes the pixel centre. ON when the pixel gets brighter (the segment's
// bright side arrives), OFF otherwise. Then a per-pixel refractory period and Gaussian timestamp jitter.
//
// Geometry is exact with lens distortion: pixel centres are undistorted once into normalised coordinates,
// where the image of a 3D line is straight. Crossing times are interpolated linearly inside simulation
// steps short enough that no segment moves more than `max_step_px`.

#include <cstdint>
#include <random>
#include <vector>

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/pose.hpp"
#include "evpipe/core/event.hpp"

namespace evpipe::sim {

struct EdgeOptions {
  double contrast_log = 0.9;         ///< log-intensity step across an edge
  double threshold_log = 0.25;       ///< DAVIS contrast threshold (log units); events per crossing = floor(ratio)
  double blur_px = 1.0;              ///< width of the intensity ramp across an edge (optics + motion)
  std::int64_t refractory_us = 200;  ///< per-pixel dead time after an event
  double jitter_us = 20.0;           ///< std. dev. of timestamp jitter
  double max_step_px = 0.25;         ///< largest segment displacement per simulation step
};

struct TargetScene {
  camera::CameraModel camera;
  camera::LineModel model;
  /// T_cam_model over time, sorted by t_us, dense enough for linear interpolation (>= 1 kHz).
  std::vector<camera::StampedPose> trajectory;
  EdgeOptions edge;
};

/// Signal events of the scene in [t0_us, t1_us) ∩ the trajectory's span, time-ordered. Each segment's bright
/// side is drawn from `rng` once (deterministic for a seed).
std::vector<Event> render_target(const TargetScene& scene, std::int64_t t0_us, std::int64_t t1_us,
                                 std::mt19937_64& rng);

/// A stop of the generated motion: the target stands still from at_s (seconds after the start) for for_s
/// seconds. The motion slows down smoothly over the ramp before at_s and speeds up over the ramp after the stop
/// (MotionOptions::stop_ramp_s), then continues where it stopped: the motion is paused, not changed.
struct MotionStop {
  double at_s = 0.0;
  double for_s = 0.0;
};

/// Smooth random motion about a base pose: each of x, y, z and the three rotation-vector components is a sum
/// of three sinusoids with random frequencies in [min_freq_hz, max_freq_hz] and phases, scaled so that the
/// excursion stays within ±range and the speed within max_speed (both checked on the generated samples).
/// With stops, the motion's own time is paused (time warp): the poses are those of the unpaused motion, the
/// speed only drops (ramps of the form 0.5 (1 ± cos)), so the bounds still hold.
struct MotionOptions {
  camera::Pose base;                                        ///< T_cam_model at the centre of the motion
  Eigen::Vector3d pivot_model_m = Eigen::Vector3d::Zero();  ///< rotations turn about this model point
  double range_m = 0.08;                                    ///< max |excursion| per axis
  double range_deg = 10.0;                                  ///< max |rotation-vector component|
  double max_speed_m_s = 0.15;  ///< max translational speed (bounds the amplitude·frequency)
  double max_angular_speed_deg_s = 20.0;
  double min_freq_hz = 0.05;
  double max_freq_hz = 0.4;
  double rate_hz = 1000.0;        ///< sample rate of the trajectory
  std::vector<MotionStop> stops;  ///< sorted by at_s, not overlapping (ramps included); empty: no stop
  double stop_ramp_s = 0.1;       ///< slowing down before and speeding up after each stop
};

/// The motion time (seconds since the start) at real time t_s under `stops`: t_s minus the time lost to the stops
/// before t_s (constant while standing still). std::invalid_argument for unsorted or overlapping stops, a
/// negative time or duration, or a negative ramp.
double motion_time_s(double t_s, const std::vector<MotionStop>& stops, double ramp_s);
std::vector<camera::StampedPose> generate_motion(std::int64_t t0_us, std::int64_t t1_us, const MotionOptions& options,
                                                 std::mt19937_64& rng);

/// Centre of the model's bounding box (model frame, metres): the natural pivot of the motion.
Eigen::Vector3d bbox_centre(const camera::LineModel& model);

/// A base pose that shows `model` centred in front of the camera at `distance_m`: the model's bounding-box
/// centre on the optical axis. `R_cam_model` orients it (identity: model x right, y down, z away).
camera::Pose facing_pose(const camera::LineModel& model, double distance_m,
                         const Eigen::Quaterniond& R_cam_model = Eigen::Quaterniond::Identity());

/// R_cam_model of an upright camera looking at a model whose frame is x forward, y left, z up (the roadheader;
/// the usual vehicle convention) from `azimuth_deg` about the model's z axis (0: from straight ahead of the
/// model, 90: from its left side, -90: from its right) and `elevation_deg` above the horizontal. "Upright": the
/// model's z axis points up in the image.
Eigen::Quaterniond look_at_z_up(double azimuth_deg, double elevation_deg);

/// evsim's default view of the front-left three-quarter: the cutting head and the machine's left side visible.
inline constexpr double kDefaultViewAzimuth_deg = 60.0;
inline constexpr double kDefaultViewElevation_deg = 20.0;

/// The default orientation for a model: identity when all its points share one z (a planar target drawn in
/// z = const, facing the camera as config/target-planar.yaml is); otherwise the model is taken to be in the
/// x forward, y left, z up convention and seen as look_at_z_up(kDefaultViewAzimuth_deg,
/// kDefaultViewElevation_deg). A model in another convention needs an explicit orientation.
Eigen::Quaterniond default_view(const camera::LineModel& model);

/// The trajectory with rows inserted (slerp + linear) into every gap longer than max_gap_us, evenly spaced, so
/// that no gap exceeds it. The original rows are kept unchanged and the inserted ones lie on the interpolation
/// between them, so the interpolated trajectory is the same (to rounding). Returned unchanged when already dense.
std::vector<camera::StampedPose> densify(const std::vector<camera::StampedPose>& trajectory, std::int64_t max_gap_us);

/// `truth` moved by exactly `offset_m` in a uniformly random direction and turned by exactly `offset_deg` about
/// a uniformly random axis (applied in the camera frame: R' = R(axis, offset) * R): a pose prior that is off by
/// a known amount.
camera::Pose perturb_pose(const camera::Pose& truth, double offset_m, double offset_deg, std::mt19937_64& rng);

}  // namespace evpipe::sim
