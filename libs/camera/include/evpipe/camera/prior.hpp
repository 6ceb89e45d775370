#pragma once
// The initial pose prior (interfaces.md): where the target is expected before tracking starts.

#include "evpipe/camera/pose.hpp"

#include <string>
#include <string_view>

namespace evpipe::camera {

struct PosePrior {
  Pose pose;                         ///< T_cam_model expected at start
  double position_tolerance_m{0.3};  ///< radius around pose.t_cam_model_m searched, metres
  double angle_tolerance_deg{45.0};  ///< rotation away from pose.q_cam_model accepted, degrees
};

/// Loads the `prior:` map of a YAML file; the file may be a prior file or a bigger run configuration (other
/// top-level keys are ignored). Keys (unknown keys inside `prior:` are errors):
///   position: [x, y, z]            metres, camera frame (required)
///   orientation: [qw, qx, qy, qz]  required; normalised on load (must not be zero); stored with qw >= 0
///   position_tolerance: metres     optional, default 0.3, must be > 0
///   angle_tolerance_deg: degrees   optional, default 45, must be in (0, 180]
/// @throws ModelError naming the file and field, e.g. "prior.yaml: prior.position_tolerance: must be > 0, got 0".
[[nodiscard]] PosePrior load_prior(const std::string& path);
/// The same from text in memory; source_name is used in messages.
[[nodiscard]] PosePrior parse_prior(std::string_view text, const std::string& source_name);

}  // namespace evpipe::camera
