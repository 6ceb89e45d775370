#pragma once
// 3D line model of the target (the CAD wireframe the pose estimator matches events against), its loaders
// (evpipe YAML and ASCII DXF), and the projection of a model segment into the image.

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/pose.hpp"

#include <Eigen/Core>

#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace evpipe::camera {

/// A segment in the model frame, metres.
struct Segment3 {
  Eigen::Vector3d a_m{Eigen::Vector3d::Zero()};
  Eigen::Vector3d b_m{Eigen::Vector3d::Zero()};
  [[nodiscard]] double length_m() const { return (b_m - a_m).norm(); }
  friend bool operator==(const Segment3&, const Segment3&) = default;
};

/// A segment in the image, pixels.
struct Segment2 {
  Eigen::Vector2d a_px{Eigen::Vector2d::Zero()};
  Eigen::Vector2d b_px{Eigen::Vector2d::Zero()};
};

/// The target's line model. Always metres in memory, whatever the file's units.
struct LineModel {
  std::string name;
  std::vector<Segment3> segments_m;
};

/// Segments shorter than this (after conversion to metres) are rejected as zero-length.
inline constexpr double kMinSegmentLength_m = 1e-9;

/// Loads a line model, format chosen by content (an ASCII DXF starts with a group code line "0" or "999";
/// anything else is read as YAML).
///
/// YAML: a top-level `model:` map (other top-level keys ignored; unknown keys inside `model:` are errors):
///   name: text (optional; default: the file name without extension)
///   units: mm | m (required)
///   lines: one row per segment, [x1, y1, z1, x2, y2, z2] in the model frame
///
/// DXF (ASCII; binary DXF is rejected): entities of the ENTITIES section, in file order:
///   LINE (10/20/30 start, 11/21/31 end, all six required), 3D POLYLINE (70 bit 8) with its VERTEX entities
///   up to SEQEND, 2D POLYLINE (elevation = its 30, object coordinates with extrusion 210/220/230), and
///   LWPOLYLINE (10/20 vertex pairs, elevation 38, extrusion 210/220/230); a polyline gives one segment per
///   consecutive vertex pair, plus the closing edge when 70 & 1. Units from the HEADER's $INSUNITS: 4 = mm,
///   6 = m; absent or 0 ("unitless") = mm (CAD tools default to mm, and so does the YAML model in
///   interfaces.md); any other value is an error. The name is the file name without extension. Not read:
///   blocks (INSERT is not expanded), curves (ARC, CIRCLE, SPLINE, ...), polyface/polygon meshes, bulges
///   (arcs) in polylines (the chord is used): each is reported in `notes`, none is an error. A zero-length
///   LINE is an error; a repeated polyline vertex (a common CAD export artifact) is skipped with a note.
///
/// Validation, both formats: at least one segment, all numbers finite, no segment shorter than
/// kMinSegmentLength_m. Files over 64 MiB (YAML: over 4 MiB) are rejected before parsing.
/// @param notes if not null, receives one line per non-fatal remark (assumed units, skipped entities).
/// @throws ModelError naming the file and the YAML field ("model.lines[3]: zero-length segment") or the DXF
///         line number ("line 57: LINE entity #2 has no end point y (group 21)").
[[nodiscard]] LineModel load_line_model(const std::string& path, std::vector<std::string>* notes = nullptr);
/// The same from text in memory; source_name is used in messages and for the default name.
[[nodiscard]] LineModel parse_line_model(std::string_view text, const std::string& source_name,
                                         std::vector<std::string>* notes = nullptr);

/// Projects a model segment with the pose T_cam_model. The segment is first clipped to the half-space
/// z > near_m in front of the camera (near_m below 1e-6 m is raised to 1e-6 m; nullopt if nothing is left);
/// the two remaining endpoints are then projected with distortion. With distortion the image of a 3D line is
/// a curve: this returns its chord between the projected endpoints, not the curve (the pose estimator refines
/// this where it matters). The result is not clipped to the image. nullopt also when an endpoint lies beyond
/// the distortion fold (see CameraModel::project()).
[[nodiscard]] std::optional<Segment2> project_segment(const CameraModel& camera, const Pose& T_cam_model,
                                                      const Segment3& segment_model, double near_m = 1e-3);

}  // namespace evpipe::camera
