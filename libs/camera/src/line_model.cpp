// load_line_model() dispatch, the YAML line model, and project_segment().

#include "evpipe/camera/line_model.hpp"

#include "evpipe/camera/error.hpp"
#include "line_model_detail.hpp"
#include "text_file.hpp"
#include "yaml_util.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace evpipe::camera {
namespace {

constexpr std::uintmax_t kMaxModelBytes = 64u << 20;  // DXF exports of whole machines can be tens of MB
constexpr std::size_t kMaxYamlModelBytes = 4u << 20;  // yaml-cpp needs ~100x the text in nodes

double units_per_metre(const YAML::Node& units, const std::string& file) {
  if (!units) throw ModelError(file, "model.units", "missing (mm or m)");
  if (!units.IsScalar()) throw ModelError(file, "model.units", "must be mm or m");
  const std::string& u = units.Scalar();
  if (u == "mm") return 1000.0;
  if (u == "m") return 1.0;
  throw ModelError(file, "model.units", fmt::format("unknown units '{}' (expected mm or m)", detail::excerpt(u)));
}

LineModel parse_line_model_yaml(std::string_view text, const std::string& file) {
  if (text.size() > kMaxYamlModelBytes) {
    throw ModelError(file, "",
                     fmt::format("YAML line model of {} bytes is over the {} accepted (use DXF for big models)",
                                 text.size(), kMaxYamlModelBytes));
  }
  const YAML::Node root = detail::parse_yaml(text, file);
  const YAML::Node model = detail::require_section(root, file, "model");
  detail::reject_unknown_keys(model, {"name", "units", "lines"}, file, "model");

  LineModel out;
  if (const YAML::Node name = model["name"]; name && !name.IsNull()) {
    if (!name.IsScalar()) throw ModelError(file, "model.name", "must be text");
    out.name = name.Scalar();
  } else {
    out.name = detail::stem_of(file);
  }
  const double per_m = units_per_metre(model["units"], file);

  const YAML::Node lines = model["lines"];
  if (!lines) throw ModelError(file, "model.lines", "missing");
  if (!lines.IsSequence()) throw ModelError(file, "model.lines", "must be a list of [x1, y1, z1, x2, y2, z2] rows");
  if (lines.size() == 0) throw ModelError(file, "model.lines", "no segments (at least 1 is needed)");
  out.segments_m.reserve(lines.size());
  for (std::size_t i = 0; i < lines.size(); ++i) {
    const std::string field = fmt::format("model.lines[{}]", i);
    const std::vector<double> v = detail::to_doubles(lines[i], file, field);
    if (v.size() != 6) {
      throw ModelError(file, field, fmt::format("expected 6 numbers (x1, y1, z1, x2, y2, z2), got {}", v.size()));
    }
    Segment3 s{detail::to_metres(v[0], v[1], v[2], per_m), detail::to_metres(v[3], v[4], v[5], per_m)};
    if (!(s.length_m() >= kMinSegmentLength_m)) throw ModelError(file, field, "zero-length segment");
    out.segments_m.push_back(s);
  }
  return out;
}

}  // namespace

LineModel parse_line_model(std::string_view text, const std::string& source_name, std::vector<std::string>* notes) {
  if (detail::strip_bom(text).starts_with("AutoCAD Binary DXF")) {
    throw ModelError(source_name, "", "binary DXF is not supported: save the drawing as ASCII DXF");
  }
  if (detail::looks_like_dxf(text)) return detail::parse_line_model_dxf(text, source_name, notes);
  return parse_line_model_yaml(text, source_name);
}

LineModel load_line_model(const std::string& path, std::vector<std::string>* notes) {
  const std::string text = detail::read_text_file(path, kMaxModelBytes);
  return parse_line_model(text, path, notes);
}

std::optional<Segment2> project_segment(const CameraModel& camera, const Pose& T_cam_model,
                                        const Segment3& segment_model, double near_m) {
  near_m = std::max(near_m, 1e-6);  // project() needs z > 1e-9; a crossing at ~0 would be useless anyway
  Eigen::Vector3d a_cam = T_cam_model.apply(segment_model.a_m);
  Eigen::Vector3d b_cam = T_cam_model.apply(segment_model.b_m);
  const bool a_in = a_cam.z() > near_m;
  const bool b_in = b_cam.z() > near_m;
  if (!a_in && !b_in) return std::nullopt;
  if (!a_in || !b_in) {
    // Replace the endpoint behind the near plane by the crossing point; dz != 0 as exactly one end is in front.
    const double s = (near_m - a_cam.z()) / (b_cam.z() - a_cam.z());
    const Eigen::Vector3d crossing = a_cam + s * (b_cam - a_cam);
    (a_in ? b_cam : a_cam) = crossing;
    // The crossing lies on z = near_m up to rounding; nudge it to the front so project() accepts it.
    auto& moved = a_in ? b_cam : a_cam;
    if (!(moved.z() > near_m)) moved.z() = std::nextafter(near_m, 1e300);
  }
  const auto a_px = camera.project(a_cam);
  const auto b_px = camera.project(b_cam);
  if (!a_px || !b_px) return std::nullopt;
  return Segment2{*a_px, *b_px};
}

}  // namespace evpipe::camera
