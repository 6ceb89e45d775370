#pragma once
// Synthetic windows of a line target with a known pose for the line-detector and initialiser tests: a
// constant twist (translation + rotation about the model's centre) so that every edge moves, rendered with
// libs/sim, plus optional background activity. Shared by tests/pose and tests/bench/bench_pose_init.cpp
// (needs EVPIPE_SOURCE_DIR defined).

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <random>
#include <string>
#include <vector>

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/sim/noise.hpp"
#include "evpipe/sim/target3d.hpp"

namespace evpipe::pose_test {

struct Window {
  camera::CameraModel cam;
  camera::LineModel model;
  camera::Pose truth;  ///< T_cam_model at the middle of the window
  std::vector<Event> events;
  std::size_t signal_events{0};
};

struct WindowSpec {
  std::string model_file = "target-planar.yaml";
  double distance_m = 0.8;
  double noise_hz = 0.0;     ///< background activity per pixel
  double speed_m_s = 0.15;   ///< translation speed, in a random direction of the image plane
  double spin_deg_s = 30.0;  ///< rotation speed about a random axis through the model centre
  double tilt_deg = 15.0;    ///< random tilt of the base orientation away from the default view
  std::int64_t window_us = 30'000;
  std::uint64_t seed = 1;
};

inline camera::CameraModel davis346() {
  return camera::load_camera((std::filesystem::path(EVPIPE_SOURCE_DIR) / "config" / "davis346.yaml").string());
}
inline camera::LineModel load_model(const std::string& file) {
  return camera::load_line_model((std::filesystem::path(EVPIPE_SOURCE_DIR) / "config" / file).string());
}

inline Eigen::Vector3d random_unit(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  // One draw per statement (argument evaluation order is unspecified: the same seed, the same scene with every
  // compiler); z first keeps the scenes GCC generated before.
  const double z = n(rng);
  const double y = n(rng);
  const double x = n(rng);
  return Eigen::Vector3d(x, y, z).normalized();
}

inline Window make_window(const WindowSpec& spec) {
  Window w;
  w.cam = davis346();
  w.model = load_model(spec.model_file);
  std::mt19937_64 rng(spec.seed);
  const Eigen::Quaterniond tilt(Eigen::AngleAxisd(spec.tilt_deg * M_PI / 180.0, random_unit(rng)));
  const camera::Pose base = sim::facing_pose(w.model, spec.distance_m, tilt * sim::default_view(w.model));
  const Eigen::Vector3d pivot_cam = base.apply(sim::bbox_centre(w.model));
  std::uniform_real_distribution<double> ang(0.0, 2.0 * M_PI);
  const double a = ang(rng);
  const Eigen::Vector3d v = spec.speed_m_s * Eigen::Vector3d(std::cos(a), std::sin(a), 0.0);
  const Eigen::Vector3d axis = random_unit(rng);
  const double omega = spec.spin_deg_s * M_PI / 180.0;
  // T(t): the model turns about its centre at omega and drifts at v; t = 0 is the window's middle.
  const auto pose_at = [&](double t_s) {
    const Eigen::Quaterniond Rw(Eigen::AngleAxisd(omega * t_s, axis));
    camera::Pose p;
    p.q_cam_model = (Rw * base.q_cam_model).normalized();
    p.t_cam_model_m = Rw * (base.t_cam_model_m - pivot_cam) + pivot_cam + v * t_s;
    return p;
  };
  sim::TargetScene scene;
  scene.camera = w.cam;
  scene.model = w.model;
  const std::int64_t half = spec.window_us / 2;
  for (std::int64_t t = -half - 2000; t <= half + 2000; t += 500) {
    scene.trajectory.push_back({t + half, pose_at(static_cast<double>(t) * 1e-6)});
  }
  w.truth = pose_at(0.0);
  std::vector<Event> sig = sim::render_target(scene, 0, spec.window_us, rng);
  w.signal_events = sig.size();
  if (spec.noise_hz > 0.0) {
    sim::NoiseOptions no;
    no.rate_hz_per_pixel = spec.noise_hz;
    std::vector<Event> noise =
        sim::background_activity(SensorGeometry{w.cam.width, w.cam.height}, 0, spec.window_us, no, rng);
    std::vector<Event> all;
    all.reserve(sig.size() + noise.size());
    std::merge(sig.begin(), sig.end(), noise.begin(), noise.end(), std::back_inserter(all),
               [](const Event& l, const Event& r) { return l.t_us < r.t_us; });
    w.events = std::move(all);
  } else {
    w.events = std::move(sig);
  }
  return w;
}

}  // namespace evpipe::pose_test
