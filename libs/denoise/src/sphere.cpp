#include "evpipe/denoise/sphere.hpp"

#include <fmt/format.h>

#include <cmath>
#include <stdexcept>

namespace evpipe::denoise {

namespace {

std::int64_t isqrt(std::int64_t v) noexcept {
  auto r = static_cast<std::int64_t>(std::sqrt(static_cast<long double>(v)));
  while (r * r > v) --r;
  while ((r + 1) * (r + 1) <= v) ++r;
  return r;
}

}  // namespace

Sphere::Sphere(double radius_px, std::int64_t lt_us, bool inclusive)
    : radius_px_(radius_px), lt_us_(lt_us), inclusive_(inclusive) {
  if (!(radius_px > 0.0) || !(radius_px <= kMaxSphereRadiusPx)) {
    throw std::invalid_argument(fmt::format("sphere radius {} px: must be in (0, {}]", radius_px, kMaxSphereRadiusPx));
  }
  if (lt_us < 1 || lt_us > kMaxSphereLtUs) {
    throw std::invalid_argument(fmt::format("sphere Lt {} us: must be in [1, {}]", lt_us, kMaxSphereLtUs));
  }
  // r²Lt² in long double (64-bit mantissa): exact for every radius that is a short binary fraction, and
  // within one ulp otherwise, which is the accuracy the real-valued radius carries anyway.
  const long double lt = static_cast<long double>(lt_us);
  const long double r2lt2 = static_cast<long double>(radius_px) * radius_px * lt * lt;
  const auto floor_v = static_cast<std::int64_t>(std::floor(r2lt2));
  limit_ = (!inclusive && static_cast<long double>(floor_v) == r2lt2) ? floor_v - 1 : floor_v;

  const std::int64_t lt2 = lt_us * lt_us;
  extent_px_ = 0;
  while ((extent_px_ + 1) * (extent_px_ + 1) * lt2 <= limit_) ++extent_px_;
  const int side = 2 * extent_px_ + 1;
  index_.assign(static_cast<std::size_t>(side * side), -1);

  auto site_at = [&](int dx, int dy) {
    return SphereSite{dx, dy, isqrt(limit_ - static_cast<std::int64_t>(dx * dx + dy * dy) * lt2)};
  };
  sites_.push_back(site_at(0, 0));
  // Row-major over the "negative" half (dy < 0, or dy = 0 and dx < 0), each followed by its antipode.
  for (int dy = -extent_px_; dy <= 0; ++dy) {
    for (int dx = -extent_px_; dx <= extent_px_; ++dx) {
      if (dy == 0 && dx >= 0) break;
      if (static_cast<std::int64_t>(dx * dx + dy * dy) * lt2 > limit_) continue;
      sites_.push_back(site_at(dx, dy));
      sites_.push_back(site_at(-dx, -dy));
    }
  }
  if (sites_.size() > static_cast<std::size_t>(kMaxSphereSites)) {
    throw std::logic_error("sphere: more than 64 sites");  // unreachable for radius ≤ 4
  }
  for (std::size_t i = 0; i < sites_.size(); ++i) {
    const auto& s = sites_[i];
    index_[static_cast<std::size_t>((s.dy + extent_px_) * side + (s.dx + extent_px_))] = static_cast<int>(i);
  }
}

int Sphere::site_index(int dx, int dy) const noexcept {
  if (dx < -extent_px_ || dx > extent_px_ || dy < -extent_px_ || dy > extent_px_) return -1;
  const int side = 2 * extent_px_ + 1;
  return index_[static_cast<std::size_t>((dy + extent_px_) * side + (dx + extent_px_))];
}

bool Sphere::contains(int dx, int dy, std::int64_t dt_us) const noexcept {
  const int s = site_index(dx, dy);
  return s >= 0 && dt_us <= sites_[static_cast<std::size_t>(s)].half_width_us &&
         dt_us >= -sites_[static_cast<std::size_t>(s)].half_width_us;
}

}  // namespace evpipe::denoise
