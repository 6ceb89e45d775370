#pragma once
// Pinhole camera with OpenCV's radial-tangential ("plumb bob") distortion, and its loader.
//
// Pixel convention (OpenCV): pixel (u, v) has its centre at integer coordinates; u to the right, v down; the
// image covers [-0.5, width - 0.5) x [-0.5, height - 0.5). Normalised coordinates are x = X/Z, y = Y/Z in the
// camera frame (x right, y down, z forward). Distortion of a normalised point (x, y), r² = x² + y²:
//   radial = 1 + k1 r² + k2 r⁴ + k3 r⁶
//   x_d = x radial + 2 p1 x y + p2 (r² + 2x²)
//   y_d = y radial + p1 (r² + 2y²) + 2 p2 x y
//   u = fx x_d + cx,   v = fy y_d + cy
// which is what cv::projectPoints computes for 4 or 5 coefficients (k1 k2 p1 p2 [k3]).

#include <Eigen/Core>

#include <optional>
#include <string>
#include <string_view>

namespace evpipe::camera {

struct CameraModel {
  int width{346};   ///< pixels
  int height{260};  ///< pixels
  double fx{0.0};   ///< focal length, pixels
  double fy{0.0};
  double cx{0.0};  ///< principal point, pixels
  double cy{0.0};
  double k1{0.0};  ///< OpenCV distortion coefficients, order k1 k2 p1 p2 k3
  double k2{0.0};
  double p1{0.0};
  double p2{0.0};
  double k3{0.0};

  /// Pixel of a point in the camera frame, distortion applied. nullopt when the point is not in front of the
  /// camera (z <= 1e-9 m) or lies beyond the fold of the radial distortion (d(r·radial)/dr <= 0 at its
  /// normalised radius r: there the model is not invertible and a point far outside the field of view would
  /// otherwise land inside the image; never the case for the shipped DAVIS346 calibration). The result is not
  /// clipped to the image: see in_image(). Elsewhere identical to cv::projectPoints.
  [[nodiscard]] std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& p_cam) const;

  /// Normalised undistorted → normalised distorted (the formula above, without K).
  [[nodiscard]] Eigen::Vector2d distort(const Eigen::Vector2d& xy) const;
  /// Inverse of distort(): Newton's method with the analytic 2x2 Jacobian, starting at xy_d, with step halving
  /// when a step does not reduce the residual. Stops when the step is below 1e-12 in normalised units
  /// (~2.4e-10 px at f = 243 px); at most 20 iterations. At the image corners it takes 4 iterations for the
  /// shipped DAVIS346 calibration and 5 for a strong one (k1 = -0.35, k2 = 0.12, k3 = -0.015); the pixel round
  /// trip is ~1e-13 px over the whole image for both (tested with a 1e-6 px bound). Beyond the fold of a
  /// strong distortion there is no inverse and the last iterate is returned.
  [[nodiscard]] Eigen::Vector2d undistort_normalised(const Eigen::Vector2d& xy_d) const;

  /// Pixel → normalised undistorted coordinates (K⁻¹ then undistort_normalised()): what the pose solvers use.
  [[nodiscard]] Eigen::Vector2d pixel_to_normalised(const Eigen::Vector2d& px) const;
  /// Normalised undistorted coordinates → pixel (distort() then K).
  [[nodiscard]] Eigen::Vector2d normalised_to_pixel(const Eigen::Vector2d& xy) const;
  /// Distorted (measured) pixel → where an ideal pinhole camera with the same K would see it (pixels).
  [[nodiscard]] Eigen::Vector2d undistort(const Eigen::Vector2d& px) const;

  /// True when the pixel lies in [-0.5, width - 0.5) x [-0.5, height - 0.5), i.e. rounds to a sensor pixel.
  [[nodiscard]] bool in_image(const Eigen::Vector2d& px) const;

  [[nodiscard]] bool has_distortion() const { return k1 != 0.0 || k2 != 0.0 || p1 != 0.0 || p2 != 0.0 || k3 != 0.0; }
  friend bool operator==(const CameraModel&, const CameraModel&) = default;
};

/// Loads a calibration file, format chosen by content:
///  - OpenCV FileStorage (YAML with the "%YAML:1.0" header, XML "<?xml"/"<opencv_storage>", JSON, or any text
///    containing "opencv-matrix", as written by cv::FileStorage, OpenCV's and DV's calibration tools):
///    camera_matrix (3x3), distortion_coefficients (4 or 5 values), image_width, image_height, read with
///    cv::FileStorage. The keys are looked up at the top level, then in the first top-level map holding a
///    camera_matrix.
///  - otherwise the evpipe YAML: a top-level `camera:` map with width, height, fx, fy, cx, cy and optional
///    distortion (k1 k2 p1 p2 [k3]; absent = none). Other top-level keys are ignored (a camera section may
///    live in a bigger file); unknown keys inside `camera:` are errors (a misspelt key must not be ignored).
/// Distortion: 4 values (k3 = 0) or 5; any other count is rejected. width/height must be in 1..65535, fx and
/// fy > 0, all numbers finite.
/// @throws ModelError naming the file and the field, e.g. "cam.yaml: camera.fx: must be > 0, got -3".
[[nodiscard]] CameraModel load_camera(const std::string& path);
/// The same from text already in memory; source_name is used in error messages.
[[nodiscard]] CameraModel parse_camera(std::string_view text, const std::string& source_name);

}  // namespace evpipe::camera
