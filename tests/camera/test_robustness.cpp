// Mutated and truncated inputs: every loader either succeeds or throws ModelError (never another exception,
// a crash or a hang). Run under ASan/UBSan in CI; the seed is printed.

#include "camera_test_util.hpp"
#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/prior.hpp"
#include "evpipe/camera/trajectory.hpp"

#include <gtest/gtest.h>

#include <fstream>
#include <random>
#include <sstream>

namespace evpipe::camera {
namespace {

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// A random edit: flip a byte, delete a run, duplicate a run, or truncate.
std::string mutate(std::string s, std::mt19937_64& rng) {
  if (s.empty()) return s;
  std::uniform_int_distribution<std::size_t> pos(0, s.size() - 1);
  const int edits = 1 + static_cast<int>(rng() % 4);
  for (int e = 0; e < edits && !s.empty(); ++e) {
    pos = std::uniform_int_distribution<std::size_t>(0, s.size() - 1);
    const std::size_t p = pos(rng);
    switch (rng() % 5) {
      case 0:
        s[p] = static_cast<char>(rng() & 0xFF);
        break;
      case 1:
        s[p] = "0123456789-.,:[]\n -e"[rng() % 20];
        break;
      case 2:
        s.erase(p, 1 + rng() % 16);
        break;
      case 3:
        s.insert(p, s.substr(p, 1 + rng() % 32));
        break;
      default:
        s.resize(p);
        break;
    }
  }
  return s;
}

template <typename Fn>
void expect_only_model_errors(const std::string& original, int rounds, std::mt19937_64& rng, Fn&& parse) {
  int ok = 0;
  int rejected = 0;
  for (int i = 0; i < rounds; ++i) {
    const std::string text = mutate(original, rng);
    try {
      parse(text);
      ++ok;
    } catch (const ModelError&) {
      ++rejected;
    } catch (const std::exception& e) {
      ADD_FAILURE() << "round " << i << ": not a ModelError: " << e.what() << "\n--- input ---\n" << text;
      return;
    }
  }
  std::cout << "accepted " << ok << ", rejected " << rejected << " of " << rounds << " mutated inputs\n";
  EXPECT_GT(rejected, 0);  // the mutations do reach the validation
}

TEST(Robustness, MutatedDxf) {
  auto rng = test::test_rng();
  const std::string dxf = slurp(test::config_file("roadheader-wireframe.dxf"));
  expect_only_model_errors(dxf, 3000, rng, [](const std::string& t) { (void)parse_line_model(t, "m.dxf"); });
}

TEST(Robustness, MutatedYamlModelCameraPrior) {
  auto rng = test::test_rng();
  const std::string model = slurp(test::config_file("target-planar.yaml"));
  expect_only_model_errors(model, 1000, rng, [](const std::string& t) { (void)parse_line_model(t, "m.yaml"); });
  const std::string cam = slurp(test::config_file("davis346.yaml"));
  expect_only_model_errors(cam, 1000, rng, [](const std::string& t) { (void)parse_camera(t, "c.yaml"); });
  const std::string prior = slurp(test::config_file("prior-example.yaml"));
  expect_only_model_errors(prior, 1000, rng, [](const std::string& t) { (void)parse_prior(t, "p.yaml"); });
}

TEST(Robustness, MutatedOpenCvFileStorage) {
  auto rng = test::test_rng();
  const std::string fs =
      "%YAML:1.0\n---\nimage_width: 346\nimage_height: 260\n"
      "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n"
      "   data: [ 243.2, 0., 173.4, 0., 243.2, 128.6, 0., 0., 1. ]\n"
      "distortion_coefficients: !!opencv-matrix\n   rows: 1\n   cols: 5\n   dt: d\n"
      "   data: [ -0.08, 0.01, 0.0002, -0.0001, 0. ]\n";
  expect_only_model_errors(fs, 1000, rng, [](const std::string& t) { (void)parse_camera(t, "cv.yaml"); });
  const std::string xml =
      "<?xml version=\"1.0\"?>\n<opencv_storage>\n<image_width>346</image_width>\n<image_height>260</image_height>\n"
      "<camera_matrix type_id=\"opencv-matrix\">\n  <rows>3</rows>\n  <cols>3</cols>\n  <dt>d</dt>\n"
      "  <data>\n    243.2 0. 173.4 0. 243.2 128.6 0. 0. 1.</data></camera_matrix>\n"
      "<distortion_coefficients type_id=\"opencv-matrix\">\n  <rows>5</rows>\n  <cols>1</cols>\n  <dt>d</dt>\n"
      "  <data>\n    -0.08 0.01 0.0002 -0.0001 0.</data></distortion_coefficients>\n</opencv_storage>\n";
  EXPECT_EQ(parse_camera(xml, "cv.xml").fx, 243.2);
  expect_only_model_errors(xml, 1000, rng, [](const std::string& t) { (void)parse_camera(t, "cv.xml"); });
}

TEST(Robustness, MutatedTrajectoryCsv) {
  auto rng = test::test_rng();
  const std::string csv =
      "t_us,x_m,y_m,z_m,qw,qx,qy,qz,status\n"
      "1000,0.100000,-0.200000,0.800000,1.000000000,0.000000000,0.000000000,0.000000000,tracking\n"
      "2000,0.123457,0.000000,1.000000,0.707106781,0.000000000,0.000000000,0.707106781,tracking\n";
  const std::string path = (::evpipe::testing::temp_dir("camera") / "mutated.csv").string();
  expect_only_model_errors(csv, 1000, rng, [&](const std::string& t) {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << t;
    (void)read_trajectory_csv(path);
  });
}

}  // namespace
}  // namespace evpipe::camera
