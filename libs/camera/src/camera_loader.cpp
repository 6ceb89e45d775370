// load_camera(): evpipe YAML (yaml-cpp) or OpenCV FileStorage (cv::FileStorage), chosen by content.

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/error.hpp"
#include "evpipe/core/event.hpp"
#include "text_file.hpp"
#include "yaml_util.hpp"

#include <fmt/format.h>
#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>
#include <tuple>
#include <utility>
#include <vector>

namespace evpipe::camera {
namespace {

constexpr std::uintmax_t kMaxCalibrationBytes = 1u << 20;  // a calibration is a few hundred bytes
constexpr long long kMaxImageSide_px = kMaxSensorSide;     // the largest sensor evpipe accepts (core/event.hpp)
// A focal length is plausible when the field of view across the larger image side is between 0.1 and 179 degrees
// (fx >= side / 229 and fx <= side * 573): fx: 1e-300 or 1e300 is a broken calibration, not a lens.
constexpr double kMinFov_deg = 0.1;
constexpr double kMaxFov_deg = 179.0;

/// OpenCV's own YAML header ("%YAML:1.0", with a colon, which yaml-cpp rejects), its XML and JSON flavours, or
/// its matrix tag anywhere: then cv::FileStorage reads the file.
bool looks_like_filestorage(std::string_view text) {
  const std::string_view t = detail::trim(detail::strip_bom(text));
  if (t.starts_with("%YAML:") || t.starts_with("<?xml") || t.starts_with("<opencv_storage")) return true;
  return text.find("opencv-matrix") != std::string_view::npos;
}

void set_distortion(CameraModel& cam, const std::vector<double>& d, const std::string& file, const std::string& field) {
  if (d.size() != 4 && d.size() != 5) {
    throw ModelError(file, field, fmt::format("expected 4 or 5 coefficients (k1 k2 p1 p2 [k3]), got {}", d.size()));
  }
  cam.k1 = d[0];
  cam.k2 = d[1];
  cam.p1 = d[2];
  cam.p2 = d[3];
  cam.k3 = d.size() == 5 ? d[4] : 0.0;
}

void check_positive(double v, const std::string& file, const std::string& field) {
  if (!(v > 0.0)) throw ModelError(file, field, fmt::format("must be > 0, got {}", v));
}

/// Issue 17: fx 1e-300 was accepted. Checked once width and height are known.
void check_plausible(const CameraModel& cam, const std::string& file, const std::string& fx_field,
                     const std::string& fy_field, const std::string& cx_field, const std::string& cy_field) {
  const double side = std::max(cam.width, cam.height);
  constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
  const double f_min = side / (2.0 * std::tan(kMaxFov_deg / 2.0 * kDegToRad));
  const double f_max = side / (2.0 * std::tan(kMinFov_deg / 2.0 * kDegToRad));
  for (const auto& [f, field] : {std::pair{cam.fx, &fx_field}, std::pair{cam.fy, &fy_field}}) {
    if (!(f >= f_min && f <= f_max))
      throw ModelError(file, *field,
                       fmt::format("{} px is not a plausible focal length for a {}x{} image (expected {:.3g} to {:.3g} "
                                   "px: a field of view of {} to {} degrees)",
                                   f, cam.width, cam.height, f_min, f_max, kMinFov_deg, kMaxFov_deg));
  }
  for (const auto& [c, n, field] :
       {std::tuple{cam.cx, cam.width, &cx_field}, std::tuple{cam.cy, cam.height, &cy_field}}) {
    if (!(c >= -n && c <= 2.0 * n))
      throw ModelError(file, *field,
                       fmt::format("principal point {} px is far outside the {}x{} image (expected {} to {})", c,
                                   cam.width, cam.height, -n, 2 * n));
  }
}

void check_side(long long v, const std::string& file, const std::string& field) {
  if (v <= 0 || v > kMaxImageSide_px) {
    throw ModelError(file, field, fmt::format("must be a positive pixel count (1..{}), got {}", kMaxImageSide_px, v));
  }
}

CameraModel parse_evpipe_yaml(const YAML::Node& root, const std::string& file) {
  const YAML::Node cam_node = detail::require_section(root, file, "camera");
  detail::reject_unknown_keys(cam_node, {"width", "height", "fx", "fy", "cx", "cy", "distortion"}, file, "camera");
  CameraModel cam;
  const long long width = detail::require_integer(cam_node, "width", file, "camera");
  check_side(width, file, "camera.width");
  const long long height = detail::require_integer(cam_node, "height", file, "camera");
  check_side(height, file, "camera.height");
  cam.width = static_cast<int>(width);
  cam.height = static_cast<int>(height);
  cam.fx = detail::require_double(cam_node, "fx", file, "camera");
  check_positive(cam.fx, file, "camera.fx");
  cam.fy = detail::require_double(cam_node, "fy", file, "camera");
  check_positive(cam.fy, file, "camera.fy");
  cam.cx = detail::require_double(cam_node, "cx", file, "camera");
  cam.cy = detail::require_double(cam_node, "cy", file, "camera");
  if (const YAML::Node d = cam_node["distortion"]; d && !d.IsNull()) {
    set_distortion(cam, detail::to_doubles(d, file, "camera.distortion"), file, "camera.distortion");
  }
  check_plausible(cam, file, "camera.fx", "camera.fy", "camera.cx", "camera.cy");
  return cam;
}

// ---- OpenCV FileStorage ----------------------------------------------------------------------------------

cv::FileNode find_calibration_root(const cv::FileStorage& fs, const std::string& file) {
  cv::FileNode root = fs.root();
  // FileNode::operator[] asserts on a non-map: check first.
  if (!root.isMap()) {
    throw ModelError(file, "", "expected a map with camera_matrix, distortion_coefficients, image_width, image_height");
  }
  if (!root["camera_matrix"].empty()) return root;
  // Some tools nest the calibration one level down (e.g. under the camera's name).
  for (auto it = root.begin(); it != root.end(); ++it) {
    const cv::FileNode child = *it;
    if (child.isMap() && !child["camera_matrix"].empty()) return child;
  }
  return root;
}

cv::Mat read_matrix(const cv::FileNode& parent, const char* key, const std::string& file) {
  const cv::FileNode node = parent[key];
  if (node.empty()) throw ModelError(file, key, "missing");
  if (node.isMap()) {
    // OpenCV allocates rows x cols before it checks the data against them: check the sizes first, so that a
    // small file cannot ask for gigabytes. A calibration matrix is at most 3x3, a coefficient vector 1x14.
    constexpr int kMaxSide = 16;
    const cv::FileNode rows = node["rows"];
    const cv::FileNode cols = node["cols"];
    const cv::FileNode data = node["data"];
    if (!rows.isInt() || !cols.isInt() || static_cast<int>(rows) < 1 || static_cast<int>(cols) < 1 ||
        static_cast<int>(rows) > kMaxSide || static_cast<int>(cols) > kMaxSide) {
      throw ModelError(file, key, fmt::format("opencv-matrix needs integer rows and cols in 1..{}", kMaxSide));
    }
    const std::size_t elements = static_cast<std::size_t>(static_cast<int>(rows)) * static_cast<int>(cols);
    if (!data.isSeq() || data.size() != elements) {
      throw ModelError(file, key, fmt::format("opencv-matrix data must hold rows x cols = {} numbers", elements));
    }
  }
  cv::Mat m;
  try {
    node >> m;
  } catch (const cv::Exception& e) {
    throw ModelError(file, key, fmt::format("not a readable opencv-matrix: {}", e.err));
  }
  if (m.empty()) {
    // A plain sequence ("[a, b, c]") instead of an opencv-matrix.
    if (node.isSeq()) {
      std::vector<double> v;
      for (auto it = node.begin(); it != node.end(); ++it) {
        if (!(*it).isReal() && !(*it).isInt()) throw ModelError(file, key, "must hold numbers");
        v.push_back(static_cast<double>(*it));
      }
      return cv::Mat(v, true).reshape(1, 1);
    }
    throw ModelError(file, key, "must be an opencv-matrix");
  }
  cv::Mat d;
  m.convertTo(d, CV_64F);
  return d;
}

long long read_int(const cv::FileNode& parent, const char* key, const std::string& file) {
  const cv::FileNode node = parent[key];
  if (node.empty()) throw ModelError(file, key, "missing");
  if (node.isInt()) return static_cast<int>(node);
  if (node.isReal()) {
    const double v = static_cast<double>(node);
    if (std::isfinite(v) && v == std::floor(v) && std::abs(v) < 1e9) return static_cast<long long>(v);
  }
  throw ModelError(file, key, "must be an integer");
}

CameraModel read_filestorage(const cv::FileStorage& fs, const std::string& file) {
  const cv::FileNode root = find_calibration_root(fs, file);

  CameraModel cam;
  const cv::Mat K = read_matrix(root, "camera_matrix", file);
  if (K.rows != 3 || K.cols != 3) {
    throw ModelError(file, "camera_matrix", fmt::format("must be 3x3, got {}x{}", K.rows, K.cols));
  }
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) {
      if (!std::isfinite(K.at<double>(r, c))) {
        throw ModelError(file, fmt::format("camera_matrix[{},{}]", r, c), "not a finite number");
      }
    }
  }
  cam.fx = K.at<double>(0, 0);
  check_positive(cam.fx, file, "camera_matrix[0,0] (fx)");
  cam.fy = K.at<double>(1, 1);
  check_positive(cam.fy, file, "camera_matrix[1,1] (fy)");
  cam.cx = K.at<double>(0, 2);
  cam.cy = K.at<double>(1, 2);
  if (K.at<double>(0, 1) != 0.0) {
    throw ModelError(file, "camera_matrix[0,1]", fmt::format("skew must be 0, got {}", K.at<double>(0, 1)));
  }
  if (K.at<double>(1, 0) != 0.0 || K.at<double>(2, 0) != 0.0 || K.at<double>(2, 1) != 0.0 ||
      K.at<double>(2, 2) != 1.0) {
    throw ModelError(file, "camera_matrix", "last row must be [0, 0, 1] and [1,0] must be 0");
  }

  const cv::Mat D = read_matrix(root, "distortion_coefficients", file);
  if (D.rows != 1 && D.cols != 1) {
    throw ModelError(file, "distortion_coefficients", fmt::format("must be a vector, got {}x{}", D.rows, D.cols));
  }
  std::vector<double> d;
  for (int i = 0; i < static_cast<int>(D.total()); ++i) {
    const double v = D.at<double>(i);
    if (!std::isfinite(v)) throw ModelError(file, fmt::format("distortion_coefficients[{}]", i), "not a finite number");
    d.push_back(v);
  }
  set_distortion(cam, d, file, "distortion_coefficients");

  const long long width = read_int(root, "image_width", file);
  check_side(width, file, "image_width");
  const long long height = read_int(root, "image_height", file);
  check_side(height, file, "image_height");
  cam.width = static_cast<int>(width);
  cam.height = static_cast<int>(height);
  check_plausible(cam, file, "camera_matrix[0,0] (fx)", "camera_matrix[1,1] (fy)", "camera_matrix[0,2] (cx)",
                  "camera_matrix[1,2] (cy)");
  return cam;
}

/// OpenCV 4.6's XML parser reads through a null pointer when the text ends inside a tag after an attribute's
/// '=' (e.g. a file truncated at `<camera_matrix type_id=`): found by tests/camera/test_robustness.cpp. Refuse
/// such text before OpenCV sees it: the document must end with the closing root tag, and inside tags every
/// '=' must be followed (after spaces) by a quote.
void check_xml_before_opencv(std::string_view text, const std::string& file) {
  if (!detail::trim(text).ends_with("</opencv_storage>")) {
    throw ModelError(file, "", "XML FileStorage does not end with </opencv_storage> (truncated?)");
  }
  bool in_tag = false;
  char quote = 0;
  for (std::size_t i = 0; i < text.size(); ++i) {
    const char c = text[i];
    if (quote != 0) {
      if (c == quote) quote = 0;
    } else if (!in_tag) {
      if (c == '<') {
        if (text.substr(i).starts_with("<!--")) {  // skip comments: they may contain anything
          const auto end = text.find("-->", i + 4);
          if (end == std::string_view::npos) throw ModelError(file, "", "XML comment without -->");
          i = end + 2;
        } else {
          in_tag = true;
        }
      }
    } else if (c == '>') {
      in_tag = false;
    } else if (c == '"' || c == '\'') {
      quote = c;
    } else if (c == '=') {
      std::size_t j = i + 1;
      while (j < text.size() && (text[j] == ' ' || text[j] == '\t' || text[j] == '\r' || text[j] == '\n')) ++j;
      if (j >= text.size() || (text[j] != '"' && text[j] != '\'')) {
        throw ModelError(file, "", "XML attribute value not in quotes");
      }
    }
  }
  if (in_tag || quote != 0) throw ModelError(file, "", "XML ends inside a tag");
}

CameraModel parse_filestorage(std::string_view text, const std::string& file) {
  if (detail::trim(detail::strip_bom(text)).starts_with("<")) check_xml_before_opencv(detail::strip_bom(text), file);
  cv::FileStorage fs;
  try {
    // MEMORY: the text is the content, not a file name (we already read it, with a size cap).
    if (!fs.open(std::string(detail::strip_bom(text)), cv::FileStorage::READ | cv::FileStorage::MEMORY)) {
      throw ModelError(file, "", "OpenCV FileStorage could not parse the file");
    }
  } catch (const ModelError&) {
    throw;
  } catch (const cv::Exception& e) {
    throw ModelError(file, "", fmt::format("OpenCV FileStorage could not parse the file: {}", e.err));
  } catch (const std::exception& e) {  // OpenCV 4.6's parser can throw std::length_error on malformed keys
    throw ModelError(file, "", fmt::format("OpenCV FileStorage could not parse the file: {}", e.what()));
  }
  try {
    return read_filestorage(fs, file);
  } catch (const ModelError&) {
    throw;
  } catch (const cv::Exception& e) {
    // OpenCV asserts on shapes it did not expect (a scalar where a map should be, ...).
    throw ModelError(file, "", fmt::format("OpenCV FileStorage: {}", e.err));
  } catch (const std::exception& e) {
    throw ModelError(file, "", fmt::format("OpenCV FileStorage: {}", e.what()));
  }
}

}  // namespace

CameraModel parse_camera(std::string_view text, const std::string& source_name) {
  if (looks_like_filestorage(text)) return parse_filestorage(text, source_name);
  const YAML::Node root = detail::parse_yaml(text, source_name);
  // Standard-YAML FileStorage content without OpenCV's header (no "camera:" but a "camera_matrix:").
  if (root.IsMap() && !root["camera"] && root["camera_matrix"]) return parse_filestorage(text, source_name);
  return parse_evpipe_yaml(root, source_name);
}

CameraModel load_camera(const std::string& path) {
  const std::string text = detail::read_text_file(path, kMaxCalibrationBytes);
  return parse_camera(text, path);
}

}  // namespace evpipe::camera
