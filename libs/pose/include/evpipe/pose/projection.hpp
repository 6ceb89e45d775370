#pragma once
// The tracker's geometry: the model's segments projected with a pose (visible part, in normalised undistorted
// coordinates where the image of a 3D line is straight), a per-pixel undistortion table for events, and the
// association of events with the nearest projected segment (point-to-segment distance, distance and ambiguity
// gates). Distances are computed in normalised coordinates and reported in pixels via f = (fx + fy) / 2.

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/pose.hpp"
#include "evpipe/core/event.hpp"

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace evpipe::pose {

/// Pixel → normalised undistorted coordinates for every sensor pixel, built once per camera: events have
/// integer coordinates, so the table replaces an iterative undistortion per event.
class UndistortMap {
 public:
  UndistortMap() = default;
  explicit UndistortMap(const camera::CameraModel& camera);
  [[nodiscard]] const camera::CameraModel& camera() const noexcept { return camera_; }
  [[nodiscard]] bool contains(int x, int y) const noexcept {
    return x >= 0 && y >= 0 && x < camera_.width && y < camera_.height && !table_.empty();
  }
  /// Normalised undistorted coordinates of pixel (x, y); contains(x, y) must hold.
  [[nodiscard]] const Eigen::Vector2d& at(int x, int y) const noexcept {
    return table_[static_cast<std::size_t>(y) * static_cast<std::size_t>(camera_.width) + static_cast<std::size_t>(x)];
  }
  [[nodiscard]] bool empty() const noexcept { return table_.empty(); }
  /// The association grid: square cells of kGridCellPx pixels (in normalised units) over the bounding box of the
  /// table's normalised coordinates, and the cell of every pixel's normalised point.
  static constexpr double kGridCellPx = 8.0;
  struct Grid {
    Eigen::Vector2d origin{Eigen::Vector2d::Zero()};  ///< normalised coordinates of cell (0, 0)'s corner
    double cell{1.0};                                 ///< cell side, normalised units
    int nx{1}, ny{1};
  };
  [[nodiscard]] const Grid& grid() const noexcept { return grid_; }
  /// Cell index (cy * nx + cx) of pixel (x, y)'s normalised point; contains(x, y) must hold.
  [[nodiscard]] std::uint32_t cell_of(int x, int y) const noexcept {
    return cells_[static_cast<std::size_t>(y) * static_cast<std::size_t>(camera_.width) + static_cast<std::size_t>(x)];
  }

 private:
  camera::CameraModel camera_;
  std::vector<Eigen::Vector2d> table_;
  Grid grid_;
  std::vector<std::uint32_t> cells_;
};

/// f used to convert normalised distances to pixels (and back): the mean of fx and fy.
[[nodiscard]] inline double focal_px(const camera::CameraModel& camera) noexcept {
  return 0.5 * (camera.fx + camera.fy);
}

/// The visible part of one model segment at a pose.
struct ProjectedSegment {
  std::size_t model_index{0};  ///< index into LineModel::segments_m
  /// Endpoints of the visible part in the MODEL frame (a sub-segment of the model segment): the tracker
  /// differentiates the event-to-line distance with respect to the pose through these.
  Eigen::Vector3d a_m{Eigen::Vector3d::Zero()};
  Eigen::Vector3d b_m{Eigen::Vector3d::Zero()};
  /// The same endpoints projected: normalised undistorted image coordinates.
  Eigen::Vector2d a_n{Eigen::Vector2d::Zero()};
  Eigen::Vector2d b_n{Eigen::Vector2d::Zero()};
  /// Distorted pixel chord of the visible part (camera::project_segment; for display and the length gate).
  camera::Segment2 segment_px;
  double length_px{0.0};
};

struct ProjectionOptions {
  double near_m = 1e-3;         ///< segments are clipped to z > near_m in front of the camera
  double min_length_px = 10.0;  ///< visible parts shorter than this are dropped (too few events, unstable)
  double clip_sample_px = 2.0;  ///< sampling step along a segment when clipping its curved image to the sensor
};

/// Projects every model segment with T_cam_model, keeps the part inside the image and in front of the camera.
/// With lens distortion the image border is curved in normalised coordinates: the segment is sampled every
/// ~clip_sample_px and the first and last samples inside the image (refined by bisection) bound the visible
/// part. No hidden-line removal (the model is a wireframe; evsim renders every segment too).
[[nodiscard]] std::vector<ProjectedSegment> project_model(const camera::CameraModel& camera,
                                                          const camera::LineModel& model,
                                                          const camera::Pose& T_cam_model,
                                                          const ProjectionOptions& options = {});

struct AssociationOptions {
  double gate_px = 10.0;         ///< an event further than this from every projected segment is not used
  double ambiguity_ratio = 1.5;  ///< keep an event only if its second-nearest segment is > ratio × the nearest
  double junction_px = 2.0;      ///< ... and further than this (events near two lines, e.g. at a corner)
};

/// One event associated with a projected segment.
struct Association {
  std::uint32_t event_index{0};                  ///< index into the window
  std::uint32_t segment{0};                      ///< index into the projected segments
  Eigen::Vector2d p_n{Eigen::Vector2d::Zero()};  ///< the event, normalised undistorted coordinates
  double distance_px{0.0};                       ///< point-to-segment distance to the associated segment
};

/// Associates each event of the window with its nearest projected segment (point-to-segment distance) when it
/// passes the distance and ambiguity gates. Events outside the map's sensor are ignored. `out` is cleared.
/// Segments further than the largest gate from an event cannot change its decision, so each event is compared
/// only with the segments listed in its cell of a coarse grid (8 px cells); the result equals comparing it with
/// every segment (tests/pose/test_tracker.cpp checks this against the exhaustive loop).
void associate_events(EventSpan events, const UndistortMap& map, const std::vector<ProjectedSegment>& segments,
                      const AssociationOptions& options, std::vector<Association>& out);

/// A window's events as the association reads them, gathered once per window (the tracker associates the same
/// events several times): index into the window, normalised undistorted point, grid cell. Events outside the
/// sensor or without a finite normalised point are left out (they are never associated).
struct GatheredEvents {
  std::vector<std::uint32_t> index;
  std::vector<Eigen::Vector2d> p_n;
  std::vector<std::uint32_t> cell;
};
void gather_events(EventSpan events, const UndistortMap& map, GatheredEvents& out);
/// associate_events on gathered events (the same result).
void associate_events(const GatheredEvents& events, const UndistortMap& map,
                      const std::vector<ProjectedSegment>& segments, const AssociationOptions& options,
                      std::vector<Association>& out);

/// The same decisions by comparing every event with every segment: the reference for tests and benchmarks.
void associate_events_exhaustive(EventSpan events, const UndistortMap& map,
                                 const std::vector<ProjectedSegment>& segments, const AssociationOptions& options,
                                 std::vector<Association>& out);
/// Point-to-segment distance (same units as the inputs).
[[nodiscard]] double point_segment_distance(const Eigen::Vector2d& p, const Eigen::Vector2d& a,
                                            const Eigen::Vector2d& b) noexcept;

}  // namespace evpipe::pose
