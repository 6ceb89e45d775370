#include "evpipe/camera/prior.hpp"

#include "evpipe/camera/error.hpp"
#include "text_file.hpp"
#include "yaml_util.hpp"

#include <fmt/format.h>

#include <stdexcept>

namespace evpipe::camera {
namespace {
constexpr std::uintmax_t kMaxPriorFileBytes = 1u << 20;  // a run configuration is a few kB
}

PosePrior parse_prior(std::string_view text, const std::string& source_name) {
  const std::string& file = source_name;
  const YAML::Node root = detail::parse_yaml(text, file);
  const YAML::Node node = detail::require_section(root, file, "prior");
  detail::reject_unknown_keys(node, {"position", "orientation", "position_tolerance", "angle_tolerance_deg"}, file,
                              "prior");
  PosePrior prior;

  const YAML::Node position = node["position"];
  if (!position) throw ModelError(file, "prior.position", "missing ([x, y, z] in metres, camera frame)");
  const auto p = detail::to_doubles(position, file, "prior.position");
  if (p.size() != 3)
    throw ModelError(file, "prior.position", fmt::format("expected 3 numbers [x, y, z], got {}", p.size()));
  prior.pose.t_cam_model_m = Eigen::Vector3d(p[0], p[1], p[2]);

  const YAML::Node orientation = node["orientation"];
  if (!orientation) throw ModelError(file, "prior.orientation", "missing ([qw, qx, qy, qz])");
  const auto q = detail::to_doubles(orientation, file, "prior.orientation");
  if (q.size() != 4) {
    throw ModelError(file, "prior.orientation", fmt::format("expected 4 numbers [qw, qx, qy, qz], got {}", q.size()));
  }
  try {
    // Through the wire conversion so that the stored quaternion is the canonical one (unit norm, qw >= 0).
    prior.pose.q_cam_model = from_wire(to_wire(from_wire(q[0], q[1], q[2], q[3])));
  } catch (const std::invalid_argument&) {
    throw ModelError(file, "prior.orientation", "quaternion has zero norm");
  }

  if (const auto tol = detail::optional_double(node, "position_tolerance", file, "prior")) {
    if (!(*tol > 0.0)) throw ModelError(file, "prior.position_tolerance", fmt::format("must be > 0, got {}", *tol));
    prior.position_tolerance_m = *tol;
  }
  if (const auto tol = detail::optional_double(node, "angle_tolerance_deg", file, "prior")) {
    if (!(*tol > 0.0) || *tol > 180.0) {
      throw ModelError(file, "prior.angle_tolerance_deg", fmt::format("must be in (0, 180], got {}", *tol));
    }
    prior.angle_tolerance_deg = *tol;
  }
  return prior;
}

PosePrior load_prior(const std::string& path) {
  return parse_prior(detail::read_text_file(path, kMaxPriorFileBytes), path);
}

}  // namespace evpipe::camera
