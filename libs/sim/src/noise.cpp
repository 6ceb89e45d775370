#include "evpipe/sim/noise.hpp"

#include <algorithm>
#include <set>

namespace evpipe::sim {

std::vector<Event> background_activity(const SensorGeometry& g, std::int64_t t0_us, std::int64_t t1_us,
                                       const NoiseOptions& o, std::mt19937_64& rng) {
  std::vector<Event> out;
  if (t1_us <= t0_us) return out;
  const double span_s = static_cast<double>(t1_us - t0_us) * 1e-6;
  // The superposition of independent per-pixel Poisson processes of rate λ is one Poisson process of rate
  // λ·W·H whose events land on a uniformly chosen pixel: draw the total count, then place each event.
  std::poisson_distribution<std::int64_t> count(o.rate_hz_per_pixel * static_cast<double>(g.pixels()) * span_s);
  std::uniform_int_distribution<std::int64_t> t(t0_us, t1_us - 1);
  std::uniform_int_distribution<int> x(0, g.width - 1);
  std::uniform_int_distribution<int> y(0, g.height - 1);
  std::bernoulli_distribution on(o.on_share);
  const std::int64_t n = o.rate_hz_per_pixel > 0 ? count(rng) : 0;
  out.reserve(static_cast<std::size_t>(n));
  for (std::int64_t i = 0; i < n; ++i)
    out.push_back({t(rng), static_cast<std::uint16_t>(x(rng)), static_cast<std::uint16_t>(y(rng)), on(rng)});
  if (o.leak_rate_hz_per_pixel > 0) {
    // Drawn only when enabled, so that recordings without leak noise keep their exact bytes.
    std::poisson_distribution<std::int64_t> leak_count(o.leak_rate_hz_per_pixel * static_cast<double>(g.pixels()) *
                                                       span_s);
    const std::int64_t k = leak_count(rng);
    for (std::int64_t i = 0; i < k; ++i)
      out.push_back({t(rng), static_cast<std::uint16_t>(x(rng)), static_cast<std::uint16_t>(y(rng)), true});
  }
  if (o.hot_pixels > 0 && o.hot_rate_hz > 0) {
    std::poisson_distribution<std::int64_t> hot_count(o.hot_rate_hz * span_s);
    for (int h = 0; h < o.hot_pixels; ++h) {
      const auto hx = static_cast<std::uint16_t>(x(rng));
      const auto hy = static_cast<std::uint16_t>(y(rng));
      const std::int64_t k = hot_count(rng);
      for (std::int64_t i = 0; i < k; ++i) out.push_back({t(rng), hx, hy, on(rng)});
    }
  }
  std::sort(out.begin(), out.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  return out;
}

std::vector<Event> uniform_noise(const SensorGeometry& g, std::int64_t t0_us, std::int64_t span_us, std::size_t n,
                                 std::mt19937_64& rng) {
  std::vector<Event> out;
  out.reserve(n);
  std::uniform_int_distribution<std::int64_t> t(t0_us, t0_us + std::max<std::int64_t>(span_us, 1) - 1);
  std::uniform_int_distribution<int> x(0, g.width - 1);
  std::uniform_int_distribution<int> y(0, g.height - 1);
  std::bernoulli_distribution on(0.5);
  for (std::size_t i = 0; i < n; ++i)
    out.push_back({t(rng), static_cast<std::uint16_t>(x(rng)), static_cast<std::uint16_t>(y(rng)), on(rng)});
  std::sort(out.begin(), out.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
  return out;
}

}  // namespace evpipe::sim
