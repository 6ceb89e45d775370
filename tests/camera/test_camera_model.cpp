// CameraModel: projection against cv::projectPoints, undistortion round trips, loaders (evpipe YAML and
// OpenCV FileStorage), and loader errors naming file and field.

#include "camera_test_util.hpp"
#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/pose.hpp"

#include <gtest/gtest.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

#include <cmath>
#include <random>

namespace evpipe::camera {
namespace {

using test::model_error_message;
using test::test_rng;
using test::write_file;
using ::testing::HasSubstr;

CameraModel davis346() {
  CameraModel c;
  c.width = 346;
  c.height = 260;
  c.fx = 243.2;
  c.fy = 243.2;
  c.cx = 173.4;
  c.cy = 128.6;
  c.k1 = -0.08;
  c.k2 = 0.01;
  c.p1 = 0.0002;
  c.p2 = -0.0001;
  c.k3 = 0.0;
  return c;
}

/// A strong wide-angle distortion, still invertible over the whole image.
CameraModel strong() {
  CameraModel c = davis346();
  c.fx = 226.4;
  c.fy = 226.2;
  c.k1 = -0.35;
  c.k2 = 0.12;
  c.p1 = 0.001;
  c.p2 = -0.002;
  c.k3 = -0.015;
  return c;
}

cv::Mat camera_matrix(const CameraModel& c) {
  return (cv::Mat_<double>(3, 3) << c.fx, 0.0, c.cx, 0.0, c.fy, c.cy, 0.0, 0.0, 1.0);
}
cv::Mat dist_coeffs(const CameraModel& c) {
  return (cv::Mat_<double>(1, 5) << c.k1, c.k2, c.p1, c.p2, c.k3);
}

void expect_projection_matches_opencv(const CameraModel& cam, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> tan_half_fov(-0.8, 0.8);
  std::uniform_real_distribution<double> depth(0.2, 5.0);
  std::uniform_real_distribution<double> angle(-3.0, 3.0);
  // A random pose too, so that the rotation convention is checked against OpenCV's rvec/tvec.
  const Eigen::Vector3d rvec_e(angle(rng) * 0.2, angle(rng) * 0.2, angle(rng) * 0.2);
  Pose T;
  T.q_cam_model = Eigen::Quaterniond(Eigen::AngleAxisd(rvec_e.norm(), rvec_e.normalized()));
  T.t_cam_model_m = Eigen::Vector3d(0.05, -0.02, 0.1);
  std::vector<cv::Point3d> object;
  std::vector<Eigen::Vector3d> model_points;
  for (int i = 0; i < 2000; ++i) {
    const double z = depth(rng);
    const Eigen::Vector3d p_cam(tan_half_fov(rng) * z, tan_half_fov(rng) * z, z);
    const Eigen::Vector3d p_model = T.inverse().apply(p_cam);
    model_points.push_back(p_model);
    object.emplace_back(p_model.x(), p_model.y(), p_model.z());
  }
  std::vector<cv::Point2d> image;
  const cv::Mat rvec = (cv::Mat_<double>(3, 1) << rvec_e.x(), rvec_e.y(), rvec_e.z());
  const cv::Mat tvec = (cv::Mat_<double>(3, 1) << 0.05, -0.02, 0.1);
  cv::projectPoints(object, rvec, tvec, camera_matrix(cam), dist_coeffs(cam), image);
  double max_err_px = 0.0;
  for (std::size_t i = 0; i < object.size(); ++i) {
    const auto px = cam.project(T.apply(model_points[i]));
    ASSERT_TRUE(px.has_value()) << i;
    max_err_px = std::max(max_err_px, (*px - Eigen::Vector2d(image[i].x, image[i].y)).norm());
  }
  std::cout << "max |project - cv::projectPoints| = " << max_err_px << " px\n";
  EXPECT_LT(max_err_px, 1e-9);
}

TEST(CameraModelProjection, MatchesOpenCvProjectPoints) {
  auto rng = test_rng();
  expect_projection_matches_opencv(davis346(), rng);
  expect_projection_matches_opencv(strong(), rng);
  CameraModel pinhole = davis346();
  pinhole.k1 = pinhole.k2 = pinhole.p1 = pinhole.p2 = pinhole.k3 = 0.0;
  expect_projection_matches_opencv(pinhole, rng);
}

TEST(CameraModelProjection, BehindTheCameraAndBeyondTheFold) {
  const CameraModel cam = davis346();
  EXPECT_FALSE(cam.project({0.0, 0.0, 0.0}).has_value());
  EXPECT_FALSE(cam.project({0.1, 0.1, -1.0}).has_value());
  EXPECT_FALSE(cam.project({0.0, 0.0, 1e-9}).has_value());
  EXPECT_FALSE(cam.project({0.0, 0.0, std::nan("")}).has_value());
  EXPECT_TRUE(cam.project({0.0, 0.0, 2e-9}).has_value());
  const auto centre = cam.project({0.0, 0.0, 1.0});
  ASSERT_TRUE(centre.has_value());
  EXPECT_EQ(*centre, Eigen::Vector2d(173.4, 128.6));
  // k1 = -0.3: r(1 + k1 r²) folds back at 1 - 0.9 r² = 0, r = 1.054. A point at r = 1.2 (50 deg off axis)
  // would otherwise be drawn inside the image.
  CameraModel folded = davis346();
  folded.k1 = -0.3;
  folded.k2 = folded.p1 = folded.p2 = folded.k3 = 0.0;
  EXPECT_TRUE(folded.project({1.0, 0.0, 1.0}).has_value());
  EXPECT_FALSE(folded.project({1.2, 0.0, 1.0}).has_value());
}

/// A 2 px grid over the image plus its whole border at 0.5 px steps (the distortion is largest at the border
/// and the corners): pixel → normalised → pixel again.
double max_round_trip_error_px(const CameraModel& cam) {
  std::vector<Eigen::Vector2d> pixels;
  const double u_max = cam.width - 0.5;
  const double v_max = cam.height - 0.5;
  for (int j = 0; j <= cam.height / 2; ++j) {
    for (int i = 0; i <= cam.width / 2; ++i) pixels.emplace_back(-0.5 + 2.0 * i, -0.5 + 2.0 * j);
  }
  for (int i = 0; i <= 2 * cam.width; ++i) {
    pixels.emplace_back(-0.5 + 0.5 * i, -0.5);
    pixels.emplace_back(-0.5 + 0.5 * i, v_max);
  }
  for (int j = 0; j <= 2 * cam.height; ++j) {
    pixels.emplace_back(-0.5, -0.5 + 0.5 * j);
    pixels.emplace_back(u_max, -0.5 + 0.5 * j);
  }
  double max_err = 0.0;
  for (const Eigen::Vector2d& px : pixels) {
    const Eigen::Vector2d back = cam.normalised_to_pixel(cam.pixel_to_normalised(px));
    max_err = std::max(max_err, (back - px).norm());
    // undistort() is the same in pixels: re-distorting gives the measured pixel back.
    const Eigen::Vector2d ideal = cam.undistort(px);
    const Eigen::Vector2d xy((ideal.x() - cam.cx) / cam.fx, (ideal.y() - cam.cy) / cam.fy);
    max_err = std::max(max_err, (cam.normalised_to_pixel(xy) - px).norm());
  }
  return max_err;
}

TEST(CameraModelUndistort, RoundTripOverTheWholeImage) {
  const double davis_err = max_round_trip_error_px(davis346());
  const double strong_err = max_round_trip_error_px(strong());
  std::cout << "max round trip error: shipped DAVIS346 " << davis_err << " px, strong " << strong_err << " px\n";
  EXPECT_LT(davis_err, 1e-6);
  EXPECT_LT(strong_err, 1e-6);
  // undistort_normalised(distort(x)) = x as well.
  const CameraModel cam = strong();
  for (int j = -12; j <= 12; ++j) {
    for (int i = -16; i <= 16; ++i) {
      const double x = 0.05 * i;
      const double y = 0.05 * j;
      const Eigen::Vector2d xy(x, y);
      ASSERT_LT((cam.undistort_normalised(cam.distort(xy)) - xy).norm() * cam.fx, 1e-6) << x << " " << y;
    }
  }
}

TEST(CameraModelUndistort, AgreesWithOpenCvUndistortPoints) {
  const CameraModel cam = davis346();
  std::vector<cv::Point2d> pixels;
  for (int v = 0; v < cam.height; v += 13) {
    for (int u = 0; u < cam.width; u += 17) pixels.emplace_back(u, v);
  }
  pixels.emplace_back(0.0, 0.0);
  pixels.emplace_back(345.0, 259.0);
  std::vector<cv::Point2d> normalised;
  // OpenCV iterates a fixed point; give it enough iterations to converge far below our tolerance.
  cv::undistortPoints(pixels, normalised, camera_matrix(cam), dist_coeffs(cam), cv::noArray(), cv::noArray(),
                      cv::TermCriteria(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 200, 1e-15));
  for (std::size_t i = 0; i < pixels.size(); ++i) {
    const Eigen::Vector2d ours = cam.pixel_to_normalised({pixels[i].x, pixels[i].y});
    EXPECT_LT((ours - Eigen::Vector2d(normalised[i].x, normalised[i].y)).norm() * cam.fx, 1e-6) << i;
  }
}

TEST(CameraModel, InImage) {
  const CameraModel cam = davis346();
  EXPECT_TRUE(cam.in_image({0.0, 0.0}));
  EXPECT_TRUE(cam.in_image({-0.5, -0.5}));
  EXPECT_TRUE(cam.in_image({345.49, 259.49}));
  EXPECT_FALSE(cam.in_image({345.5, 100.0}));
  EXPECT_FALSE(cam.in_image({100.0, 259.5}));
  EXPECT_FALSE(cam.in_image({-0.51, 10.0}));
  EXPECT_FALSE(cam.in_image({std::nan(""), 10.0}));
}

// ---- loaders ---------------------------------------------------------------------------------------------

TEST(CameraLoader, ShippedDavis346) {
  const CameraModel cam = load_camera(test::config_file("davis346.yaml"));
  EXPECT_EQ(cam, davis346());
}

TEST(CameraLoader, EvpipeYamlWithFourCoefficientsAndWithout) {
  const CameraModel four = parse_camera(
      "camera:\n  width: 640\n  height: 480\n  fx: 500\n  fy: 501\n  cx: 320\n  cy: 240\n"
      "  distortion: [0.1, -0.2, 0.001, 0.002]\n",
      "cam.yaml");
  EXPECT_EQ(four.width, 640);
  EXPECT_EQ(four.fy, 501.0);
  EXPECT_EQ(four.k2, -0.2);
  EXPECT_EQ(four.p2, 0.002);
  EXPECT_EQ(four.k3, 0.0);
  const CameraModel none =
      parse_camera("log: {level: info}\ncamera: {width: 346, height: 260, fx: 265, fy: 265, cx: 173, cy: 130}\n", "x");
  EXPECT_FALSE(none.has_distortion());
  EXPECT_EQ(none.cx, 173.0);
}

/// Writes `cam` with cv::FileStorage (as OpenCV's calibration sample does) and loads it back.
CameraModel filestorage_round_trip(const CameraModel& cam, const std::string& name, int n_coeffs) {
  const auto path = (::evpipe::testing::temp_dir("camera") / name).string();
  {
    cv::FileStorage fs(path, cv::FileStorage::WRITE);
    fs << "calibration_time"
       << "2025-04-07";
    fs << "image_width" << cam.width;
    fs << "image_height" << cam.height;
    fs << "camera_matrix" << camera_matrix(cam);
    fs << "distortion_coefficients" << dist_coeffs(cam).colRange(0, n_coeffs).t();  // OpenCV writes 5x1
    fs << "avg_reprojection_error" << 0.21;
  }
  return load_camera(path);
}

TEST(CameraLoader, OpenCvFileStorageYamlXmlJson) {
  const CameraModel cam = davis346();
  EXPECT_EQ(filestorage_round_trip(cam, "opencv.yaml", 5), cam);
  EXPECT_EQ(filestorage_round_trip(cam, "opencv.xml", 5), cam);
  EXPECT_EQ(filestorage_round_trip(cam, "opencv.json", 5), cam);
  CameraModel four = strong();
  four.k3 = 0.0;
  EXPECT_EQ(filestorage_round_trip(four, "opencv4.yaml", 4), four);
  // The YAML flavour really starts with OpenCV's header, which yaml-cpp cannot read.
  std::ifstream in(::evpipe::testing::temp_dir("camera") / "opencv.yaml");
  std::string first;
  std::getline(in, first);
  EXPECT_EQ(first, "%YAML:1.0");
}

TEST(CameraLoader, OpenCvFileStorageNestedUnderAName) {
  const std::string text =
      "%YAML:1.0\n---\nDAVIS346_00000499:\n   image_width: 346\n   image_height: 260\n"
      "   camera_matrix: !!opencv-matrix\n      rows: 3\n      cols: 3\n      dt: d\n"
      "      data: [ 243.2, 0., 173.4, 0., 243.2, 128.6, 0., 0., 1. ]\n"
      "   distortion_coefficients: !!opencv-matrix\n      rows: 1\n      cols: 5\n      dt: d\n"
      "      data: [ -0.08, 0.01, 0.0002, -0.0001, 0. ]\n";
  EXPECT_EQ(parse_camera(text, "nested.yaml"), davis346());
}

TEST(CameraLoaderErrors, NameFileAndField) {
  const std::string ok_tail = "  cx: 173\n  cy: 130\n  distortion: [0, 0, 0, 0, 0]\n";
  EXPECT_EQ(model_error_message([&] {
              (void)parse_camera("camera:\n  width: 346\n  height: 260\n  fx: -3\n  fy: 265\n" + ok_tail, "cam.yaml");
            }),
            "cam.yaml: camera.fx: must be > 0, got -3");
  EXPECT_EQ(model_error_message(
                [&] { (void)parse_camera("camera:\n  width: 346\n  height: 260\n  fy: 265\n" + ok_tail, "cam.yaml"); }),
            "cam.yaml: camera.fx: missing");
  EXPECT_EQ(model_error_message([&] {
              (void)parse_camera(
                  "camera:\n  width: 346\n  height: 260\n  fx: 265\n  fy: 265\n  cx: 173\n  cy: 130\n"
                  "  distortion: [0.1, 0.01, 0.0]\n",
                  "cam.yaml");
            }),
            "cam.yaml: camera.distortion: expected 4 or 5 coefficients (k1 k2 p1 p2 [k3]), got 3");
  EXPECT_EQ(model_error_message([&] {
              (void)parse_camera("camera:\n  width: 0\n  height: 260\n  fx: 265\n  fy: 265\n" + ok_tail, "cam.yaml");
            }),
            "cam.yaml: camera.width: must be a positive pixel count (1..2048), got 0");
  EXPECT_EQ(model_error_message([&] {
              (void)parse_camera("camera:\n  width: 346.5\n  height: 260\n  fx: 265\n  fy: 265\n" + ok_tail,
                                 "cam.yaml");
            }),
            "cam.yaml: camera.width: not an integer: '346.5'");
  EXPECT_EQ(model_error_message([&] {
              (void)parse_camera("camera:\n  width: 346\n  height: 260\n  fx: abc\n  fy: 265\n" + ok_tail, "cam.yaml");
            }),
            "cam.yaml: camera.fx: not a finite number: 'abc'");
  EXPECT_EQ(model_error_message([&] {
              (void)parse_camera("camera:\n  width: 346\n  height: 260\n  fx: .inf\n  fy: 265\n" + ok_tail, "cam.yaml");
            }),
            "cam.yaml: camera.fx: not a finite number: '.inf'");
  EXPECT_THAT(model_error_message([&] {
                (void)parse_camera("camera:\n  width: 346\n  height: 260\n  fx: 1\n  fy: 1\n  focal: 3\n" + ok_tail,
                                   "cam.yaml");
              }),
              HasSubstr("cam.yaml: camera.focal: unknown key"));
  EXPECT_EQ(model_error_message([&] { (void)parse_camera("log: {}\n", "cam.yaml"); }), "cam.yaml: camera: missing");
  EXPECT_THAT(model_error_message([&] { (void)parse_camera("camera: [1, 2\n", "cam.yaml"); }),
              HasSubstr("cam.yaml: YAML syntax error at line"));
}

TEST(CameraLoaderErrors, FileStorageAndFiles) {
  // 8 coefficients (OpenCV's rational model) are refused by count.
  const std::string k_ok =
      "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 243., 0., 173., 0., 243., 130., "
      "0., 0., 1. ]\n";
  const std::string d8 =
      "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 8\n   dt: d\n   data: [ 0., 0., 0., 0., 0., 0., "
      "0., 0. ]\n";
  const std::string d5 =
      "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n   data: [ 0., 0., 0., 0., 0. ]\n";
  const std::string wh = "image_width: 346\nimage_height: 260\n";
  EXPECT_EQ(model_error_message([&] { (void)parse_camera("%YAML:1.0\n" + wh + k_ok + d8, "cv.yaml"); }),
            "cv.yaml: distortion_coefficients: expected 4 or 5 coefficients (k1 k2 p1 p2 [k3]), got 8");
  EXPECT_EQ(model_error_message([&] { (void)parse_camera("%YAML:1.0\n" + wh + d5, "cv.yaml"); }),
            "cv.yaml: camera_matrix: missing");
  EXPECT_EQ(model_error_message([&] { (void)parse_camera("%YAML:1.0\nimage_width: 346\n" + k_ok + d5, "cv.yaml"); }),
            "cv.yaml: image_height: missing");
  const std::string k_neg =
      "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ -243., 0., 173., 0., 243., 130., "
      "0., 0., 1. ]\n";
  EXPECT_EQ(model_error_message([&] { (void)parse_camera("%YAML:1.0\n" + wh + k_neg + d5, "cv.yaml"); }),
            "cv.yaml: camera_matrix[0,0] (fx): must be > 0, got -243");
  EXPECT_THAT(model_error_message([&] { (void)parse_camera("%YAML:1.0\ncamera_matrix: [1, 2\n", "cv.yaml"); }),
              HasSubstr("cv.yaml: OpenCV FileStorage could not parse the file"));
  // Truncated XML crashes OpenCV 4.6's parser: refused before OpenCV sees it.
  EXPECT_EQ(model_error_message([] { (void)parse_camera("<?xml version=", "cv.xml"); }),
            "cv.xml: XML FileStorage does not end with </opencv_storage> (truncated?)");
  EXPECT_EQ(model_error_message([] {
              (void)parse_camera("<?xml version=\"1.0\"?>\n<opencv_storage>\n<a b= \n</opencv_storage>\n", "cv.xml");
            }),
            "cv.xml: XML attribute value not in quotes");
  // A huge declared size is refused before OpenCV allocates it.
  const std::string k_huge =
      "camera_matrix: !!opencv-matrix\n   rows: 100000\n   cols: 100000\n   dt: d\n   data: [ 1. ]\n";
  EXPECT_EQ(model_error_message([&] { (void)parse_camera("%YAML:1.0\n" + wh + k_huge + d5, "cv.yaml"); }),
            "cv.yaml: camera_matrix: opencv-matrix needs integer rows and cols in 1..16");
  const std::string k_short =
      "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: [ 1., 0., 1. ]\n";
  EXPECT_EQ(model_error_message([&] { (void)parse_camera("%YAML:1.0\n" + wh + k_short + d5, "cv.yaml"); }),
            "cv.yaml: camera_matrix: opencv-matrix data must hold rows x cols = 9 numbers");
  // Through the file loader: the message names the path.
  const std::string path =
      write_file("bad-cam.yaml", "camera:\n  width: 346\n  height: 260\n  fx: -3\n  fy: 1\n  cx: 1\n  cy: 1\n");
  EXPECT_EQ(model_error_message([&] { (void)load_camera(path); }), path + ": camera.fx: must be > 0, got -3");
  EXPECT_THAT(model_error_message([&] { (void)load_camera("/nonexistent/cam.yaml"); }),
              HasSubstr("/nonexistent/cam.yaml: cannot open"));
}

// Issue 17: implausible calibrations (fx 1e-300) and sensor sizes beyond the largest evpipe accepts were loaded.
TEST(CameraLoaderErrors, ImplausibleFocalLengthPrincipalPointAndSize) {
  const auto cam = [](const std::string& wh, const std::string& f, const std::string& c) {
    return "camera:\n" + wh + "  fx: " + f + "\n  fy: 265\n" + c + "  distortion: [0, 0, 0, 0, 0]\n";
  };
  const std::string wh = "  width: 346\n  height: 260\n";
  const std::string cc = "  cx: 173\n  cy: 130\n";
  EXPECT_THAT(model_error_message([&] { (void)parse_camera(cam(wh, "1e-300", cc), "cam.yaml"); }),
              HasSubstr("cam.yaml: camera.fx: 1e-300 px is not a plausible focal length for a 346x260 image"));
  EXPECT_THAT(model_error_message([&] { (void)parse_camera(cam(wh, "1e300", cc), "cam.yaml"); }),
              HasSubstr("cam.yaml: camera.fx: "));
  EXPECT_THAT(model_error_message([&] { (void)parse_camera(cam(wh, "265", "  cx: 5000\n  cy: 130\n"), "cam.yaml"); }),
              HasSubstr("cam.yaml: camera.cx: principal point 5000 px is far outside"));
  EXPECT_THAT(
      model_error_message([&] { (void)parse_camera(cam("  width: 4096\n  height: 260\n", "265", cc), "cam.yaml"); }),
      HasSubstr("cam.yaml: camera.width: must be a positive pixel count (1..2048), got 4096"));
  // Plausible ends: a 179-degree fisheye and a long lens.
  EXPECT_NO_THROW((void)parse_camera(cam(wh, "2", cc), "cam.yaml"));
  EXPECT_NO_THROW((void)parse_camera(cam(wh, "100000", cc), "cam.yaml"));
}

}  // namespace
}  // namespace evpipe::camera
