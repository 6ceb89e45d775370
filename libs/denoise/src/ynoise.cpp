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

bool Ynoise::accept(const Event& e) noexcept {
  if (!geometry_.contains(e.x, e.y)) {
    score_ = 0.0F;
    return false;
  }
  std::int64_t* centre = last_.data() + (e.y + radius_) * stride_ + (e.x + radius_);
  const std::int64_t t = e.t_us;
  const std::int64_t p = e.polarity ? 1 : 0;
  const std::int64_t d = options_.duration_us;
  int density = 0;
  for (int dy = -radius_; dy <= radius_; ++dy) {
    const std::int64_t* row = centre + dy * stride_;
    for (int dx = -radius_; dx <= radius_; ++dx) {
      const std::int64_t v = row[dx];
      // v >> 1 is the time (arithmetic shift: floor, exact for t·2 + p), v & 1 the polarity.
      density += ((v & 1) == p && t - (v >> 1) <= d) ? 1 : 0;
    }
  }
  *centre = pack(t, e.polarity);
  score_ = static_cast<float>(density);
  return density >= options_.threshold;
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
