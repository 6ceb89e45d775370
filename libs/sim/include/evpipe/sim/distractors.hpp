#pragma once
// Clutter for the 3D target scenes (evsim --distractor, docs/simulation.md "Distractors"): real scene structure
// that is not the target. Every kind is placed from the target's image at the first ground-truth pose, so the
// same option works for any model and distance:
//   lines         3 vertical bars and a diagonal beside the target, at its depth, fixed in the target's frame:
//                 they move in the image exactly as the scene does when the CAMERA moves (world-static
//                 structure: tunnel supports, cables);
//   moving-lines  the same bars as a second body with its own generated motion (another machine, a swinging
//                 cable);
//   decoy         a rectangle with the target's image outline, shifted sideways, 1.5 x as far (so 1.5 x as large):
//                 fixed in the target's frame like `lines` (a monitor border, a door frame seen by a moving camera);
//   decoy-static  the same rectangle fixed in the CAMERA frame: a fixed camera sees no event from it (the
//                 roadheader's case: the camera is fixed, the machine moves); the control that static clutter is
//                 invisible;
//   flicker       a patch of pixels firing ON/OFF at flicker_hz (an LED, a monitor): n events per pixel and
//                 transition as an edge crossing gives (floor(contrast / threshold)), spread over the ramp.
// Line distractors are rendered exactly as the target (render_target: same edge model, refractory, jitter).

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/pose.hpp"
#include "evpipe/core/event.hpp"
#include "evpipe/sim/target3d.hpp"

namespace evpipe::sim {

enum class DistractorKind { lines, moving_lines, decoy, decoy_static, flicker };

/// "lines", "moving-lines", "decoy", "decoy-static", "flicker".
const char* to_string(DistractorKind kind) noexcept;
/// The kind named `name`; std::invalid_argument listing the known names otherwise.
DistractorKind distractor_kind(const std::string& name);
std::vector<std::string> distractor_kind_names();

/// The target's image at a pose: bounding box of its projected segments (sampled), clipped to the image.
struct ImageBox {
  double u0 = 0, v0 = 0, u1 = 0, v1 = 0;
  [[nodiscard]] double width() const { return u1 - u0; }
  [[nodiscard]] double height() const { return v1 - v0; }
};
ImageBox target_image_box(const camera::CameraModel& camera, const camera::LineModel& model, const camera::Pose& T);

/// A line distractor: segments in its own frame and its motion (T_cam_body over time, like a target).
struct DistractorBody {
  DistractorKind kind = DistractorKind::lines;
  camera::LineModel model;
  std::vector<camera::StampedPose> trajectory;
};

struct FlickerOptions {
  double rate_hz = 100.0;  ///< ON/OFF cycles per second (an LED on 50 Hz mains flickers at 100 Hz)
  int size_px = 10;        ///< square patch side
  double rise_us = 1000;   ///< the n events of a transition are spread over this
};

/// The line body of `kind` (not flicker) for a target whose trajectory is `target_trajectory` (sorted, >= 2 rows):
/// placed from the target's image at the first pose. `motion` (moving-lines only) gives the body's own motion
/// (base and pivot are set here; stops are ignored) drawn from `rng`; the other kinds do not draw.
DistractorBody make_distractor_body(DistractorKind kind, const camera::CameraModel& camera,
                                    const camera::LineModel& target,
                                    const std::vector<camera::StampedPose>& target_trajectory, MotionOptions motion,
                                    std::mt19937_64& rng);

/// Pixel rectangle of the flicker patch: in the corner of the image farthest from the target's image centre.
ImageBox flicker_patch(const camera::CameraModel& camera, const camera::LineModel& target, const camera::Pose& T,
                       int size_px);

/// Flicker events in [t0_us, t1_us): every pixel of `patch` (integer pixels inside it) turns ON at the start of each
/// cycle and OFF at its middle (random phase per patch), `levels` events per transition at rise_us * (k - 0.5) /
/// levels after it, each with Gaussian jitter jitter_us (clamped); time-ordered.
std::vector<Event> flicker_events(const ImageBox& patch, std::int64_t t0_us, std::int64_t t1_us,
                                  const FlickerOptions& options, int levels, double jitter_us, std::mt19937_64& rng);

}  // namespace evpipe::sim
