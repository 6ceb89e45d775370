#pragma once
// Writers for evpipe's small YAML files (interfaces.md): camera calibration, line model and pose prior. Each
// returns the text of a complete file that the matching loader (parse_camera, parse_line_model, parse_prior)
// reads back to an equal value. Used by evsim to write the files beside a recording.
//
// Numbers are written in the shortest form that reads back to the same double (fmt's "{}"), so a write → parse
// round trip is exact. No comments, timestamps or other run-dependent text: equal values give equal bytes.

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/prior.hpp"

#include <string>
#include <string_view>

namespace evpipe::camera {

/// The evpipe calibration format: a `camera:` map with width, height, fx, fy, cx, cy and all five distortion
/// coefficients (k1 k2 p1 p2 k3). parse_camera() of the result == camera.
/// @throws std::invalid_argument when a number is not finite (the loader would reject the file).
[[nodiscard]] std::string to_yaml(const CameraModel& camera);

/// A `model:` map with name, units and one `[x1, y1, z1, x2, y2, z2]` row per segment, in `units` ("mm" or
/// "m"; std::invalid_argument otherwise). Lengths are metres in memory; for "mm" each coordinate is written as
/// the shortest millimetre value whose division by 1000 (what the loader does) gives back the same double,
/// searched among the few doubles around x * 1000. Such a value exists for every model read from a mm file,
/// so parse_line_model() of the result == model bit for bit; for other models the coordinate can differ in the
/// last bit (relative 2e-16). "m" is always exact. The name is written double-quoted with YAML escapes.
/// @throws std::invalid_argument when a coordinate is not finite or units is unknown.
[[nodiscard]] std::string to_yaml(const LineModel& model, std::string_view units);

/// A `prior:` map: position (m), orientation (qw qx qy qz, unit norm, qw >= 0), position_tolerance and
/// angle_tolerance_deg. The orientation is written in the canonical wire form that parse_prior() reproduces
/// exactly, so the text of a parsed-and-rewritten prior is identical and parse_prior() of the result equals
/// the prior to within one rounding of the quaternion (|Δq| < 1e-15).
/// @throws std::invalid_argument when a number is not finite.
[[nodiscard]] std::string to_yaml(const PosePrior& prior);

/// A YAML double-quoted scalar: backslash and quote escaped, control characters as \xNN.
[[nodiscard]] std::string yaml_quoted(std::string_view s);

}  // namespace evpipe::camera
