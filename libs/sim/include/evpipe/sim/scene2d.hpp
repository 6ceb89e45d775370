#pragma once
// Simple 2D scenes for denoising tests and the bundled demo: bright convex polygons (bars, rectangles)
// moving rigidly over a dark background, seen by a DAVIS-like sensor.
//
// Event model: each pixel samples the scene at its centre; an event fires at the exact (sub-step) time an
// edge crosses the pixel centre: ON when the pixel becomes bright, OFF when it becomes dark. Crossing
// times are found by bisection between simulation steps small enough that no edge moves more than
// `max_step_px` per step. Departures from a real DAVIS346 are listed in docs/simulation.md.

#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "evpipe/core/event.hpp"

namespace evpipe::sim {

/// A convex polygon moving rigidly: vertices are given relative to its centre; the centre moves at constant
/// velocity and the polygon turns about it at constant angular speed.
struct MovingPolygon {
  std::vector<std::pair<double, double>> vertices_px;  ///< counter-clockwise or clockwise, convex
  double cx_px = 0, cy_px = 0;                         ///< centre at t = 0
  double vx_px_s = 0, vy_px_s = 0;                     ///< velocity of the centre
  double angle0_rad = 0;                               ///< rotation at t = 0
  double omega_rad_s = 0;                              ///< angular speed

  [[nodiscard]] bool contains(double x, double y, double t_s) const noexcept;
  /// Largest distance from the centre to a vertex.
  [[nodiscard]] double radius_px() const noexcept;
};

MovingPolygon make_rectangle(double width_px, double height_px);

struct Scene2D {
  SensorGeometry geometry = kDavis346;
  std::vector<MovingPolygon> shapes;
};

struct RenderOptions {
  double max_step_px = 0.25;  ///< largest edge displacement per simulation step
  double jitter_us = 0.0;     ///< std. dev. of Gaussian timestamp jitter
};

/// Signal events of the scene in [t0_us, t1_us) (scene time t = 0 at t0_us), time-ordered.
std::vector<Event> render(const Scene2D& scene, std::int64_t t0_us, std::int64_t t1_us, const RenderOptions& options,
                          std::mt19937_64& rng);

/// Named scenes: "rotating-bar", "translating-rect", "demo" (both), at `speed` times their nominal speed.
/// Throws std::invalid_argument for an unknown name (listing the known ones).
Scene2D named_scene(const std::string& name, double speed = 1.0, SensorGeometry geometry = kDavis346);
std::vector<std::string> scene_names();

}  // namespace evpipe::sim
