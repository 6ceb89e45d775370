#pragma once
// Trajectory CSV (interfaces.md): header "t_us,x_m,y_m,z_m,qw,qx,qy,qz" (+ optional extra columns), one
// pose T_cam_model per row, positions in metres.

#include "evpipe/camera/pose.hpp"
#include "evpipe/core/file.hpp"

#include <array>
#include <cstdint>
#include <fstream>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace evpipe::camera {

/// The eight columns every trajectory CSV has, in the order evpipe writes them.
inline constexpr std::array<std::string_view, 8> kTrajectoryColumns = {"t_us", "x_m", "y_m", "z_m",
                                                                       "qw",   "qx",  "qy",  "qz"};

/// Reads a trajectory CSV. The first line is the header; the eight columns are found by name, in any order;
/// other columns are ignored. Cells are separated by commas, surrounding spaces ignored (no quoting). Empty
/// lines and lines starting with '#' are skipped. t_us must be an integer and non-decreasing from row to row;
/// the other cells finite numbers; quaternions are normalised (a zero quaternion is an error). Rows are
/// stored with qw >= 0.
/// @throws ModelError naming the file, the line and the column: "traj.csv: line 7: column qw: not a number: 'x'",
///         "traj.csv: line 1: missing column qw".
[[nodiscard]] std::vector<StampedPose> read_trajectory_csv(const std::string& path);

/// The cells of one extra column (e.g. evpipe's "status") of a trajectory CSV, one per pose row, in the order
/// read_trajectory_csv() returns the rows (same skipped lines), trimmed; nullopt when the header has no such
/// column. Only the row structure is checked (cell counts), not the pose cells: read_trajectory_csv() does that.
/// @throws ModelError naming the file and line, like read_trajectory_csv().
[[nodiscard]] std::optional<std::vector<std::string>> read_trajectory_column(const std::string& path,
                                                                             std::string_view column);

/// Writes a trajectory CSV: header t_us,x_m,y_m,z_m,qw,qx,qy,qz[,extra...], then one row per write():
/// t_us as an integer, positions with 6 decimals (1 µm), quaternion (unit, qw >= 0) with 9 decimals, chosen (in
/// the last digit) so that write → read_trajectory_csv() → write gives the same bytes.
/// Durability: the header and every row go to the file whole, each in one write, as write() is called (nothing waits
/// in a buffer of the process): a program killed (SIGKILL, watchdog abort, OOM) loses no row it wrote, and leaves no
/// partial row unless the kernel itself was cut short (power loss: no fsync).
class TrajectoryCsvWriter {
 public:
  /// Creates/truncates the file and writes the header. extra_columns are appended after the eight. `inputs`: the
  /// program's input files, which the output must not be (refused before truncating; evpipe/core/file.hpp).
  /// @throws std::runtime_error (evpipe::FileError) naming the file if it cannot be opened or is an input.
  explicit TrajectoryCsvWriter(const std::string& path, const std::vector<std::string>& extra_columns = {},
                               std::span<const std::string> inputs = {});

  /// One row. extra_values must have one entry per extra column (std::invalid_argument otherwise); they are
  /// written verbatim, so they must not contain commas or newlines.
  /// @throws std::runtime_error naming the file on a write error.
  void write(const StampedPose& pose, std::span<const std::string> extra_values = {});
  void flush();

  [[nodiscard]] const std::string& path() const { return path_; }

 private:
  std::string path_;
  std::size_t extra_count_{0};
  UniqueFile out_;
};

/// The pose at t_us, interpolated (slerp + linear) between the two rows around it, found by binary search.
/// The trajectory must be sorted by t_us (read_trajectory_csv() guarantees it). nullopt when t_us lies outside
/// [front().t_us, back().t_us] or the trajectory is empty. An exact stamp returns that row's pose.
[[nodiscard]] std::optional<Pose> interpolate(const std::vector<StampedPose>& trajectory, std::int64_t t_us);

}  // namespace evpipe::camera
