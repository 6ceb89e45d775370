#include "evpipe/sim/scene2d.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace evpipe::sim {

namespace {

/// A polygon's pose at one time: computed once per simulation step instead of once per pixel (the cos/sin
/// dominated the 2D render). The arithmetic is exactly that of the per-call version, so the events do not
/// change by a bit.
struct Placed {
  const MovingPolygon* polygon;
  double c, s;    // cos, sin of the rotation
  double cx, cy;  // centre
};

Placed place(const MovingPolygon& p, double t_s) {
  const double a = p.angle0_rad + p.omega_rad_s * t_s;
  return {&p, std::cos(a), std::sin(a), p.cx_px + p.vx_px_s * t_s, p.cy_px + p.vy_px_s * t_s};
}

bool inside(const Placed& q, double x, double y) noexcept {
  // Transform the point into the polygon's frame (inverse rotation about the moving centre).
  const double dx = x - q.cx;
  const double dy = y - q.cy;
  const double px = q.c * dx + q.s * dy;
  const double py = -q.s * dx + q.c * dy;
  // Convex: inside iff on the same side of every edge.
  int sign = 0;
  const auto& v = q.polygon->vertices_px;
  const std::size_t n = v.size();
  for (std::size_t i = 0; i < n; ++i) {
    const auto [x0, y0] = v[i];
    const auto [x1, y1] = v[(i + 1) % n];
    const double cross = (x1 - x0) * (py - y0) - (y1 - y0) * (px - x0);
    const int sg = cross > 0 ? 1 : (cross < 0 ? -1 : 0);
    if (sg == 0) continue;
    if (sign == 0) sign = sg;
    if (sg != sign) return false;
  }
  return true;
}

}  // namespace

bool MovingPolygon::contains(double x, double y, double t_s) const noexcept {
  return inside(place(*this, t_s), x, y);
}

double MovingPolygon::radius_px() const noexcept {
  double r = 0;
  for (const auto& [x, y] : vertices_px) r = std::max(r, std::hypot(x, y));
  return r;
}

MovingPolygon make_rectangle(double width_px, double height_px) {
  MovingPolygon p;
  const double w = width_px / 2;
  const double h = height_px / 2;
  p.vertices_px = {{-w, -h}, {w, -h}, {w, h}, {-w, h}};
  return p;
}

namespace {

bool bright(const Scene2D& scene, double x, double y, double t_s) {
  for (const auto& s : scene.shapes)
    if (s.contains(x, y, t_s)) return true;
  return false;
}

}  // namespace

std::vector<Event> render(const Scene2D& scene, std::int64_t t0_us, std::int64_t t1_us, const RenderOptions& options,
                          std::mt19937_64& rng) {
  std::vector<Event> out;
  if (t1_us <= t0_us || scene.shapes.empty()) return out;
  double max_speed = 1e-9;
  for (const auto& s : scene.shapes)
    max_speed = std::max(max_speed, std::hypot(s.vx_px_s, s.vy_px_s) + std::abs(s.omega_rad_s) * s.radius_px());
  const double step_s = std::max(1e-6, options.max_step_px / max_speed);
  const double t_end_s = static_cast<double>(t1_us - t0_us) * 1e-6;
  std::normal_distribution<double> jitter(0.0, options.jitter_us);
  const int W = scene.geometry.width;
  const int H = scene.geometry.height;

  for (double ta = 0; ta < t_end_s; ta += step_s) {
    const double tb = std::min(ta + step_s, t_end_s);
    // Pixels that can change in [ta, tb]: the union of every shape's bounding circle at both ends.
    for (const auto& s : scene.shapes) {
      const Placed at_a = place(s, ta);
      const Placed at_b = place(s, tb);
      const double r = s.radius_px() + 1.0;
      const double xa = s.cx_px + s.vx_px_s * ta, ya = s.cy_px + s.vy_px_s * ta;
      const double xb = s.cx_px + s.vx_px_s * tb, yb = s.cy_px + s.vy_px_s * tb;
      const int x_lo = std::max(0, static_cast<int>(std::floor(std::min(xa, xb) - r)));
      const int x_hi = std::min(W - 1, static_cast<int>(std::ceil(std::max(xa, xb) + r)));
      const int y_lo = std::max(0, static_cast<int>(std::floor(std::min(ya, yb) - r)));
      const int y_hi = std::min(H - 1, static_cast<int>(std::ceil(std::max(ya, yb) + r)));
      for (int y = y_lo; y <= y_hi; ++y) {
        for (int x = x_lo; x <= x_hi; ++x) {
          const double px = x + 0.5;
          const double py = y + 0.5;
          // Only this shape's changes are looked for here; the union decides the brightness, so a pixel
          // covered by two shapes is checked once per shape but emits only when the union changes.
          if (inside(at_a, px, py) == inside(at_b, px, py)) continue;
          const bool before = bright(scene, px, py, ta);
          const bool after = bright(scene, px, py, tb);
          if (before == after) continue;
          // Avoid a duplicate when another shape also changed this pixel in the same step.
          bool first_shape = true;
          for (const auto& other : scene.shapes) {
            if (&other == &s) break;
            if (other.contains(px, py, ta) != other.contains(px, py, tb)) first_shape = false;
          }
          if (!first_shape) continue;
          double lo = ta, hi = tb;
          for (int it = 0; it < 20; ++it) {
            const double mid = 0.5 * (lo + hi);
            (bright(scene, px, py, mid) == before ? lo : hi) = mid;
          }
          double t_us = static_cast<double>(t0_us) + hi * 1e6;
          if (options.jitter_us > 0) t_us += jitter(rng);
          const auto t = std::clamp<std::int64_t>(std::llround(t_us), t0_us, t1_us - 1);
          out.push_back({t, static_cast<std::uint16_t>(x), static_cast<std::uint16_t>(y), after});
        }
      }
    }
  }
  std::stable_sort(out.begin(), out.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  return out;
}

std::vector<std::string> scene_names() {
  return {"rotating-bar", "translating-rect", "demo"};
}

Scene2D named_scene(const std::string& name, double speed, SensorGeometry geometry) {
  Scene2D scene;
  scene.geometry = geometry;
  const double cx = geometry.width / 2.0;
  const double cy = geometry.height / 2.0;
  auto bar = [&] {
    auto b = make_rectangle(0.6 * geometry.height, 6);
    b.cx_px = cx;
    b.cy_px = cy;
    b.omega_rad_s = std::numbers::pi * speed;  // half a turn per second
    return b;
  };
  auto rect = [&] {
    auto r = make_rectangle(40, 30);
    r.cx_px = 30;
    r.cy_px = 0.25 * geometry.height;
    r.vx_px_s = 120.0 * speed;
    r.angle0_rad = 0.2;
    return r;
  };
  if (name == "rotating-bar") {
    scene.shapes = {bar()};
  } else if (name == "translating-rect") {
    scene.shapes = {rect()};
  } else if (name == "demo") {
    scene.shapes = {bar(), rect()};
  } else {
    std::string known;
    for (const auto& n : scene_names()) known += (known.empty() ? "" : ", ") + n;
    throw std::invalid_argument("unknown scene '" + name + "' (known: " + known + ")");
  }
  return scene;
}

}  // namespace evpipe::sim
