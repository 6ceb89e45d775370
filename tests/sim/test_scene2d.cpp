#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "evpipe/sim/scene2d.hpp"

using namespace evpipe;

namespace {

// Distance from (x, y) to the boundary of a moving polygon at time t_s.
double boundary_distance(const sim::MovingPolygon& p, double x, double y, double t_s) {
  const double a = p.angle0_rad + p.omega_rad_s * t_s;
  const double dx = x - (p.cx_px + p.vx_px_s * t_s);
  const double dy = y - (p.cy_px + p.vy_px_s * t_s);
  const double px = std::cos(a) * dx + std::sin(a) * dy;
  const double py = -std::sin(a) * dx + std::cos(a) * dy;
  double best = 1e9;
  const auto n = p.vertices_px.size();
  for (std::size_t i = 0; i < n; ++i) {
    const auto [x0, y0] = p.vertices_px[i];
    const auto [x1, y1] = p.vertices_px[(i + 1) % n];
    const double ex = x1 - x0, ey = y1 - y0;
    const double u = std::clamp(((px - x0) * ex + (py - y0) * ey) / (ex * ex + ey * ey), 0.0, 1.0);
    best = std::min(best, std::hypot(px - (x0 + u * ex), py - (y0 + u * ey)));
  }
  return best;
}

}  // namespace

TEST(Scene2D, EveryEventLiesOnAnEdgeAtItsTime) {
  for (const auto& name : sim::scene_names()) {
    SCOPED_TRACE(name);
    const auto scene = sim::named_scene(name);
    std::mt19937_64 rng(1);
    const auto ev = sim::render(scene, 0, 300'000, {}, rng);
    ASSERT_GT(ev.size(), 1000U);
    for (std::size_t i = 0; i < ev.size(); ++i) {
      const auto& e = ev[i];
      if (i) {
        ASSERT_LE(ev[i - 1].t_us, e.t_us);
      }
      double d = 1e9;
      for (const auto& s : scene.shapes)
        d = std::min(d, boundary_distance(s, e.x + 0.5, e.y + 0.5, static_cast<double>(e.t_us) * 1e-6));
      // Timestamps are rounded to 1 us: the edge moves < 0.05 px in that time at these speeds.
      ASSERT_LT(d, 0.1) << "event " << i << " at t=" << e.t_us << " (" << e.x << "," << e.y << ")";
      // ON when the pixel became bright: just after the event it is inside some shape.
      bool inside_after = false;
      for (const auto& s : scene.shapes)
        inside_after = inside_after || s.contains(e.x + 0.5, e.y + 0.5, static_cast<double>(e.t_us + 2) * 1e-6);
      ASSERT_EQ(e.polarity, inside_after) << "event " << i;
    }
  }
}

TEST(Scene2D, TranslatingRectangleEventCount) {
  // A 40x30 rectangle moving along x at 120 px/s for 0.1 s sweeps 12 px with its two vertical edges
  // (tilted 0.2 rad, so ~ (30 cos + 40 sin) rows): each crossing fires once.
  const auto scene = sim::named_scene("translating-rect");
  std::mt19937_64 rng(1);
  const auto ev = sim::render(scene, 0, 100'000, {}, rng);
  std::size_t on = 0;
  for (const auto& e : ev) on += e.polarity;
  const double rows = 30 * std::cos(0.2) + 40 * std::sin(0.2);
  EXPECT_NEAR(static_cast<double>(on), 12.0 * rows, 0.1 * 12.0 * rows);
  EXPECT_NEAR(static_cast<double>(ev.size() - on), 12.0 * rows, 0.1 * 12.0 * rows);
}

TEST(Scene2D, UnknownSceneIsRejected) {
  EXPECT_THROW(sim::named_scene("nope"), std::invalid_argument);
}
