// to_yaml(): the camera, line model and prior files that the loaders read back exactly.

#include "evpipe/camera/yaml_writer.hpp"

#include <fmt/format.h>

#include <cmath>
#include <iterator>
#include <limits>
#include <stdexcept>

namespace evpipe::camera {
namespace {

/// Shortest text that reads back to the same double (fmt's default for "{}").
std::string num(double v, std::string_view what) {
  if (!std::isfinite(v)) throw std::invalid_argument(fmt::format("to_yaml: {} is not finite ({})", what, v));
  return fmt::format("{}", v + 0.0);  // + 0.0: -0.0 is written as 0
}

/// The millimetre value written for a coordinate x_m: the loader computes mm / 1000, so pick, among the
/// doubles next to x_m * 1000, the one with the shortest text whose division gives back x_m exactly.
std::string millimetres(double x_m) {
  if (!std::isfinite(x_m)) throw std::invalid_argument(fmt::format("to_yaml: coordinate is not finite ({})", x_m));
  const double centre = x_m * 1000.0;
  std::string best;
  double lo = centre;
  double hi = centre;
  auto consider = [&](double mm) {
    if (mm / 1000.0 != x_m) return;
    std::string s = fmt::format("{}", mm + 0.0);
    if (best.empty() || s.size() < best.size()) best = std::move(s);
  };
  consider(centre);
  for (int k = 0; k < 4; ++k) {  // x * 1000 is within an ulp or two of every candidate that exists
    lo = std::nextafter(lo, -std::numeric_limits<double>::infinity());
    hi = std::nextafter(hi, std::numeric_limits<double>::infinity());
    consider(lo);
    consider(hi);
  }
  // None reads back exactly (only possible for a model not read from a mm file): the nearest, one ulp off.
  return best.empty() ? fmt::format("{}", centre + 0.0) : best;
}

/// The canonical wire quaternion that parse_prior() reproduces: a fixed point of to_wire(from_wire(.)).
WireQuaternion canonical_wire(const Eigen::Quaterniond& q) {
  WireQuaternion w = to_wire(q);
  for (int i = 0; i < 8; ++i) {  // normalising a unit quaternion changes at most the last bit: 1-2 rounds
    const WireQuaternion next = to_wire(from_wire(w));
    if (next.qw == w.qw && next.qx == w.qx && next.qy == w.qy && next.qz == w.qz) break;
    w = next;
  }
  return w;
}

}  // namespace

std::string yaml_quoted(std::string_view s) {
  std::string out = "\"";
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (u < 0x20 || u == 0x7f) {
      out += fmt::format("\\x{:02x}", u);
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string to_yaml(const CameraModel& c) {
  std::string out = "camera:\n";
  auto line = [&out](std::string_view key, const std::string& value) { out += fmt::format("  {}: {}\n", key, value); };
  line("width", std::to_string(c.width));
  line("height", std::to_string(c.height));
  line("fx", num(c.fx, "fx"));
  line("fy", num(c.fy, "fy"));
  line("cx", num(c.cx, "cx"));
  line("cy", num(c.cy, "cy"));
  line("distortion", fmt::format("[{}, {}, {}, {}, {}]", num(c.k1, "k1"), num(c.k2, "k2"), num(c.p1, "p1"),
                                 num(c.p2, "p2"), num(c.k3, "k3")));
  return out;
}

std::string to_yaml(const LineModel& model, std::string_view units) {
  const bool mm = units == "mm";
  if (!mm && units != "m") {
    throw std::invalid_argument(fmt::format("to_yaml: unknown units '{}' (expected mm or m)", units));
  }
  std::string out = fmt::format("model:\n  name: {}\n  units: {}\n  lines:\n", yaml_quoted(model.name), units);
  auto coord = [mm](double v) { return mm ? millimetres(v) : num(v, "coordinate"); };
  for (const Segment3& s : model.segments_m) {
    out += fmt::format("    - [{}, {}, {}, {}, {}, {}]\n", coord(s.a_m.x()), coord(s.a_m.y()), coord(s.a_m.z()),
                       coord(s.b_m.x()), coord(s.b_m.y()), coord(s.b_m.z()));
  }
  return out;
}

std::string to_yaml(const PosePrior& prior) {
  const Eigen::Vector3d& t = prior.pose.t_cam_model_m;
  const WireQuaternion q = canonical_wire(prior.pose.q_cam_model);
  std::string out = "prior:\n";
  out += fmt::format("  position: [{}, {}, {}]\n", num(t.x(), "position x"), num(t.y(), "position y"),
                     num(t.z(), "position z"));
  out += fmt::format("  orientation: [{}, {}, {}, {}]\n", num(q.qw, "qw"), num(q.qx, "qx"), num(q.qy, "qy"),
                     num(q.qz, "qz"));
  out += fmt::format("  position_tolerance: {}\n", num(prior.position_tolerance_m, "position_tolerance"));
  out += fmt::format("  angle_tolerance_deg: {}\n", num(prior.angle_tolerance_deg, "angle_tolerance_deg"));
  return out;
}

}  // namespace evpipe::camera
