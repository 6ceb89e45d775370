#pragma once
// Fast synthetic signal for denoising tests and benchmarks: bars rotating about their centres, with exact
// (analytic) edge-crossing times. libs/sim's renderer bisects crossing times numerically, which is too slow
// for the 10 Mev/s streams the benchmarks need; the events here follow the same model (an event when an edge
// crosses a pixel centre: ON entering the bar, OFF leaving it).
//
// A pixel at distance r ∈ (h, L/2] from a bar's centre (half-width h, length L) and at polar angle φ is
// inside the bar when the bar's angle θ(t) = θ0 + ωt satisfies |sin(φ − θ)| ≤ h / r, i.e. while
// θ ∈ [φ − δ, φ + δ] (mod π) with δ = asin(h / r); it enters at θ = φ − δ + kπ and leaves at φ + δ + kπ
// (ω > 0; mirrored for ω < 0). Total rate: ω·L²/2 events/s per bar.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <vector>

#include "evpipe/core/event.hpp"

namespace evpipe::testing {

struct RotatingBar {
  double cx_px, cy_px;
  double length_px;
  double half_width_px;
  double omega_rad_s;
  double angle0_rad;
};

/// Events of the bars in [t0_us, t1_us), time-ordered (ties by pixel).
inline std::vector<Event> rotating_bar_events(const std::vector<RotatingBar>& bars, const SensorGeometry& g,
                                              std::int64_t t0_us, std::int64_t t1_us) {
  std::vector<Event> out;
  const double pi = std::numbers::pi;
  for (const auto& b : bars) {
    const double half_len = b.length_px / 2.0;
    const int x0 = std::max(0, static_cast<int>(std::floor(b.cx_px - half_len)));
    const int x1 = std::min(g.width - 1, static_cast<int>(std::ceil(b.cx_px + half_len)));
    const int y0 = std::max(0, static_cast<int>(std::floor(b.cy_px - half_len)));
    const int y1 = std::min(g.height - 1, static_cast<int>(std::ceil(b.cy_px + half_len)));
    const double w = std::abs(b.omega_rad_s);
    const double dir = b.omega_rad_s >= 0 ? 1.0 : -1.0;
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const double dx = x - b.cx_px, dy = y - b.cy_px;
        const double r = std::hypot(dx, dy);
        if (r <= b.half_width_px || r > half_len) continue;
        // In the bar's rotating frame the pixel's angle moves at −ω: work with ψ = dir·(φ − θ0).
        const double psi = dir * (std::atan2(dy, dx) - b.angle0_rad);
        const double delta = std::asin(b.half_width_px / r);
        for (const auto& [edge, on] : {std::pair{psi - delta, true}, std::pair{psi + delta, false}}) {
          // Crossing when w·t = edge + kπ.
          const double t_first_s = static_cast<double>(t0_us) * 1e-6;
          double k = std::ceil((w * t_first_s - edge) / pi);
          while (true) {
            const double t_s = (edge + k * pi) / w;
            const auto t_us = static_cast<std::int64_t>(std::llround(t_s * 1e6));
            if (t_us >= t1_us) break;
            if (t_us >= t0_us) out.push_back({t_us, static_cast<std::uint16_t>(x), static_cast<std::uint16_t>(y), on});
            k += 1.0;
          }
        }
      }
    }
  }
  std::sort(out.begin(), out.end(), [](const Event& a, const Event& b) {
    return a.t_us != b.t_us ? a.t_us < b.t_us : (a.y != b.y ? a.y < b.y : a.x < b.x);
  });
  return out;
}

/// A 4×3 grid of bars of length 80 px filling a DAVIS346, rotating at `omega_rad_s` (alternating
/// directions, ±10 % spread): about 12·ω·3200·(1 + 0.55) events/s... ≈ 6·10⁴·ω.
inline std::vector<RotatingBar> bar_grid(double omega_rad_s) {
  std::vector<RotatingBar> bars;
  for (int j = 0; j < 3; ++j) {
    for (int i = 0; i < 4; ++i) {
      const int k = i + 4 * j;
      bars.push_back({43.0 + 86.5 * i, 43.0 + 87.0 * j, 80.0, 4.0,
                      omega_rad_s * (1.0 + 0.1 * (k % 3)) * ((i + j) % 2 != 0 ? 1.0 : -1.0), 0.3 * k});
    }
  }
  return bars;
}

}  // namespace evpipe::testing
