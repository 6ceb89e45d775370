#include "evpipe/camera/trajectory.hpp"

#include "evpipe/camera/error.hpp"
#include "text_file.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>

namespace evpipe::camera {
namespace {

constexpr std::size_t kMaxLineBytes = 1u << 20;  // a trajectory row is ~100 bytes; caps memory on garbage input

/// Line-by-line reading with a cap on the line length (std::getline would grow without bound on a file
/// without newlines).
class BoundedLineReader {
 public:
  BoundedLineReader(std::istream& in, const std::string& file) : in_(in), file_(file) {}

  bool next(std::string& line) {
    line.clear();
    if (eof_) return false;
    ++line_no_;
    while (true) {
      const int c = in_.get();
      if (c == std::char_traits<char>::eof()) {
        if (in_.bad()) throw ModelError(file_, fmt::format("line {}", line_no_), "read error");
        eof_ = true;
        return !line.empty();
      }
      if (c == '\n') break;
      if (line.size() >= kMaxLineBytes) {
        throw ModelError(file_, fmt::format("line {}", line_no_), fmt::format("longer than {} bytes", kMaxLineBytes));
      }
      line.push_back(static_cast<char>(c));
    }
    if (!line.empty() && line.back() == '\r') line.pop_back();
    return true;
  }
  [[nodiscard]] std::size_t line_no() const { return line_no_; }

 private:
  std::istream& in_;
  const std::string& file_;
  std::size_t line_no_{0};
  bool eof_{false};
};

std::vector<std::string_view> split_cells(std::string_view line) {
  std::vector<std::string_view> cells;
  std::size_t pos = 0;
  while (true) {
    const auto comma = line.find(',', pos);
    cells.push_back(
        detail::trim(line.substr(pos, comma == std::string_view::npos ? std::string_view::npos : comma - pos)));
    if (comma == std::string_view::npos) break;
    pos = comma + 1;
  }
  return cells;
}

bool skippable(std::string_view line) {
  const auto t = detail::trim(line);
  return t.empty() || t.front() == '#';
}

/// Reads up to the first line that is not empty or a comment (the header) into `line`; throws when there is none.
void read_header_line(BoundedLineReader& reader, std::string& line, const std::string& path) {
  while (reader.next(line))
    if (!skippable(line)) return;
  throw ModelError(path, "", "empty file: no header line t_us,x_m,y_m,z_m,qw,qx,qy,qz");
}

}  // namespace

std::vector<StampedPose> read_trajectory_csv(const std::string& path) {
  detail::check_input(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ModelError(path, "", fmt::format("cannot open: {}", std::strerror(errno)));
  BoundedLineReader reader(in, path);
  std::string line;

  // Header: the eight columns by name, in any order; other columns are ignored.
  read_header_line(reader, line, path);
  const std::size_t header_line = reader.line_no();
  const std::string header_text(detail::strip_bom(line));
  const std::vector<std::string_view> header = split_cells(header_text);
  std::array<std::size_t, 8> column{};
  for (std::size_t k = 0; k < kTrajectoryColumns.size(); ++k) {
    const auto first = std::find(header.begin(), header.end(), kTrajectoryColumns[k]);
    if (first == header.end()) {
      throw ModelError(path, fmt::format("line {}", header_line),
                       fmt::format("missing column {}", kTrajectoryColumns[k]));
    }
    if (std::find(first + 1, header.end(), kTrajectoryColumns[k]) != header.end()) {
      throw ModelError(path, fmt::format("line {}", header_line),
                       fmt::format("column {} appears more than once", kTrajectoryColumns[k]));
    }
    column[k] = static_cast<std::size_t>(first - header.begin());
  }

  std::vector<StampedPose> out;
  while (reader.next(line)) {
    if (skippable(line)) continue;
    const std::string where = fmt::format("line {}", reader.line_no());
    const std::vector<std::string_view> cells = split_cells(line);
    if (cells.size() != header.size()) {
      throw ModelError(path, where,
                       fmt::format("{} cells, but the header has {} columns", cells.size(), header.size()));
    }
    StampedPose sp;
    const auto t = detail::parse_int64(cells[column[0]]);
    if (!t) {
      throw ModelError(
          path, where,
          fmt::format("column t_us: not an integer number of microseconds: '{}'", detail::excerpt(cells[column[0]])));
    }
    sp.t_us = *t;
    if (!out.empty() && sp.t_us < out.back().t_us) {
      throw ModelError(path, where,
                       fmt::format("column t_us: {} is before the previous row's {} (rows must be in time order)",
                                   sp.t_us, out.back().t_us));
    }
    double v[7];
    for (std::size_t k = 1; k < 8; ++k) {
      const auto d = detail::parse_double(cells[column[k]]);
      if (!d) {
        throw ModelError(path, where,
                         fmt::format("column {}: not a finite number: '{}'", kTrajectoryColumns[k],
                                     detail::excerpt(cells[column[k]])));
      }
      v[k - 1] = *d;
    }
    sp.pose.t_cam_model_m = Eigen::Vector3d(v[0], v[1], v[2]);
    try {
      sp.pose.q_cam_model = from_wire(to_wire(from_wire(v[3], v[4], v[5], v[6])));
    } catch (const std::invalid_argument&) {
      throw ModelError(path, where, "columns qw,qx,qy,qz: quaternion has zero norm");
    }
    out.push_back(sp);
  }
  return out;
}

std::optional<std::vector<std::string>> read_trajectory_column(const std::string& path, std::string_view column) {
  detail::check_input(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ModelError(path, "", fmt::format("cannot open: {}", std::strerror(errno)));
  BoundedLineReader reader(in, path);
  std::string line;
  read_header_line(reader, line, path);
  const std::string header_text(detail::strip_bom(line));
  const std::vector<std::string_view> header = split_cells(header_text);
  const auto it = std::find(header.begin(), header.end(), column);
  if (it == header.end()) return std::nullopt;
  const auto index = static_cast<std::size_t>(it - header.begin());
  std::vector<std::string> out;
  while (reader.next(line)) {
    if (skippable(line)) continue;
    const std::vector<std::string_view> cells = split_cells(line);
    if (cells.size() != header.size()) {
      throw ModelError(path, fmt::format("line {}", reader.line_no()),
                       fmt::format("{} cells, but the header has {} columns", cells.size(), header.size()));
    }
    out.emplace_back(cells[index]);
  }
  return out;
}

namespace {

/// "qw,qx,qy,qz" with 9 decimals. read_trajectory_csv() normalises the quaternion it parses, and the rounding to 9
/// decimals leaves a norm of 1 +- 2e-9, so a row read back and written again could change in the last digit.
/// Iterate to a text whose read-back prints as the same text: then write -> read -> write is byte-identical
/// (evsim renders from its ground truth read back, and a trajectory fed back in reproduces the file).
std::string quaternion_cells(const Eigen::Quaterniond& q_in) {
  WireQuaternion q = to_wire(q_in);
  std::string text = fmt::format("{:.9f},{:.9f},{:.9f},{:.9f}", q.qw, q.qx, q.qy, q.qz);
  for (int i = 0; i < 4; ++i) {  // converges in one or two rounds
    double v[4] = {};
    std::string_view rest = text;
    for (double& x : v) {
      const auto comma = rest.find(',');
      x = detail::parse_double(rest.substr(0, comma)).value_or(0.0);
      rest = comma == std::string_view::npos ? std::string_view{} : rest.substr(comma + 1);
    }
    q = to_wire(from_wire(to_wire(from_wire(v[0], v[1], v[2], v[3]))));  // what the reader stores, in wire form
    std::string again = fmt::format("{:.9f},{:.9f},{:.9f},{:.9f}", q.qw, q.qx, q.qy, q.qz);
    if (again == text) break;
    text = std::move(again);
  }
  return text;
}

}  // namespace

namespace {

void write_whole(std::FILE* f, const std::string& path, const char* data, std::size_t n) {
  // One row (or the header) into the emptied buffer, then flushed: one write(2) of whole rows.
  if (std::fwrite(data, 1, n, f) != n || std::fflush(f) != 0)
    throw std::runtime_error(fmt::format("{}: write error: {}", path, std::strerror(errno)));
}

}  // namespace

TrajectoryCsvWriter::TrajectoryCsvWriter(const std::string& path, const std::vector<std::string>& extra_columns,
                                         std::span<const std::string> inputs)
    : path_(path), extra_count_(extra_columns.size()), out_(open_output_file(path, inputs)) {
  std::string header = "t_us,x_m,y_m,z_m,qw,qx,qy,qz";
  for (const auto& c : extra_columns) {
    if (c.find_first_of(",\r\n") != std::string::npos) {
      throw std::invalid_argument(fmt::format("{}: extra column name '{}' contains a comma or newline", path_, c));
    }
    header += ',' + c;
  }
  header += '\n';
  write_whole(out_.get(), path_, header.data(), header.size());
}

void TrajectoryCsvWriter::write(const StampedPose& sp, std::span<const std::string> extra_values) {
  if (extra_values.size() != extra_count_) {
    throw std::invalid_argument(
        fmt::format("{}: {} extra values for {} extra columns", path_, extra_values.size(), extra_count_));
  }
  const Eigen::Vector3d& t = sp.pose.t_cam_model_m;
  if (!t.allFinite() || !sp.pose.q_cam_model.coeffs().allFinite()) {
    throw std::invalid_argument(fmt::format("{}: pose at t_us {} is not finite", path_, sp.t_us));
  }
  fmt::memory_buffer row;
  fmt::format_to(std::back_inserter(row), "{},{:.6f},{:.6f},{:.6f},{}", sp.t_us, t.x(), t.y(), t.z(),
                 quaternion_cells(sp.pose.q_cam_model));
  for (const auto& e : extra_values) {
    if (e.find_first_of(",\r\n") != std::string::npos) {
      throw std::invalid_argument(fmt::format("{}: extra value '{}' contains a comma or newline", path_, e));
    }
    row.push_back(',');
    row.append(e);
  }
  row.push_back('\n');
  write_whole(out_.get(), path_, row.data(), row.size());
}

void TrajectoryCsvWriter::flush() {
  if (std::fflush(out_.get()) != 0)
    throw std::runtime_error(fmt::format("{}: write error: {}", path_, std::strerror(errno)));
}

std::optional<Pose> interpolate(const std::vector<StampedPose>& trajectory, std::int64_t t_us) {
  if (trajectory.empty() || t_us < trajectory.front().t_us || t_us > trajectory.back().t_us) return std::nullopt;
  // First row strictly after t_us; the row before it is at or before t_us.
  const auto after = std::upper_bound(trajectory.begin(), trajectory.end(), t_us,
                                      [](std::int64_t t, const StampedPose& sp) { return t < sp.t_us; });
  const StampedPose& before = *(after - 1);
  if (before.t_us == t_us || after == trajectory.end()) return before.pose;
  return interpolate(before, *after, t_us);
}

}  // namespace evpipe::camera
