#include "evpipe/denoise/ynoise.hpp"

#include <algorithm>
#include <limits>

namespace evpipe::denoise {

namespace {
// Packed "never": its time half is far in the past (t − never cannot overflow for any sensor time).
constexpr std::int64_t kNeverPacked = std::numeric_limits<std::int64_t>::min() / 2;

constexpr std::int64_t pack(std::int64_t t_us, bool polarity) noexcept {
  return t_us * 2 + (polarity ? 1 : 0);
}
}  // namespace

Ynoise::Ynoise(const SensorGeometry& geometry, YnoiseOptions options)
    : geometry_(geometry), options_(options), radius_((options.window - 1) / 2), stride_(geometry.width + 2 * radius_) {
  check_pixel_budget("ynoise", geometry, sizeof(std::int64_t));
  reset();
}

void Ynoise::reset() noexcept {
  last_.assign(static_cast<std::size_t>(stride_ * (geometry_.height + 2 * radius_)), kNeverPacked);
  if (options_.zero_init) {
    for (int y = 0; y < geometry_.height; ++y) {
      std::fill_n(last_.begin() + (y + radius_) * stride_ + radius_, geometry_.width, pack(0, false));
    }
  }
  score_ = 0.0F;
}

namespace {

// Density over the (2r+1)² window around `centre`: cells whose last event has our polarity and is at most
// `duration_us` old. Branch-free per cell; kRadius > 0 unrolls the paper's 3×3 case, 0 takes `radius` at run time.
template <int kRadius>
[[gnu::always_inline]] inline int density(const std::int64_t* centre, std::int64_t stride, int radius,
                                          std::int64_t t_us, std::int64_t polarity, std::int64_t duration_us) noexcept {
  const int r = kRadius > 0 ? kRadius : radius;
  int n = 0;
  for (int dy = -r; dy <= r; ++dy) {
    const std::int64_t* row = centre + dy * stride;
    for (int dx = -r; dx <= r; ++dx) {
      const std::int64_t v = row[dx];
      // v >> 1 is the time (arithmetic shift: floor, exact for t·2 + p), v & 1 the polarity.
      n += static_cast<int>(((v & 1) == polarity) & (t_us - (v >> 1) <= duration_us));
    }
  }
  return n;
}

}  // namespace

bool Ynoise::accept(const Event& e) noexcept {
  if (!geometry_.contains(e.x, e.y)) {
    score_ = 0.0F;
    return false;
  }
  std::int64_t* centre = last_.data() + (e.y + radius_) * stride_ + (e.x + radius_);
  const std::int64_t p = e.polarity ? 1 : 0;
  const int n = radius_ == 1 ? density<1>(centre, stride_, 1, e.t_us, p, options_.duration_us)
                             : density<0>(centre, stride_, radius_, e.t_us, p, options_.duration_us);
  *centre = pack(e.t_us, e.polarity);
  score_ = static_cast<float>(n);
  return n >= options_.threshold;
}

FilterSpec ynoise_spec() {
  return {"ynoise", "YNoise event-density filter, CUKE/E-MLB semantics (paper: 10 ms, L = 3, threshold 1)",
          [](Params& p, const SensorGeometry& g) -> std::unique_ptr<Filter> {
            YnoiseOptions o;
            o.duration_us =
                p.integer("duration_us", o.duration_us, "support window in microseconds (t - t_pixel <= duration_us)");
            p.require_positive("duration_us", static_cast<double>(o.duration_us));
            const auto window = p.integer("L", o.window, "window side in pixels, odd (radius (L-1)/2)");
            p.require_range("L", static_cast<double>(window), 1, 31);
            if (window % 2 == 0) {
              p.fail("L", "must be odd");
            }
            o.window = static_cast<int>(window);
            const auto threshold =
                p.integer("threshold", o.threshold, "density (same-polarity recent pixels, own included) needed");
            p.require_range("threshold", static_cast<double>(threshold), 1, static_cast<double>(window * window));
            o.threshold = static_cast<int>(threshold);
            o.zero_init = p.choice("init", "zero", {"zero", "never"},
                                   "maps at start: zero = CUKE (t = 0, OFF: OFF events before duration_us "
                                   "pass), never = no start-up artefact") == "zero";
            return std::make_unique<PerEventFilter<Ynoise>>("ynoise", g, o);
          }};
}

}  // namespace evpipe::denoise
