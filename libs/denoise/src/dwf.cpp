#include "evpipe/denoise/dwf.hpp"

#include <fmt/format.h>

#include <algorithm>

namespace evpipe::denoise {

Dwf::Dwf(const SensorGeometry& geometry, DwfOptions options)
    : geometry_(geometry),
      options_(options),
      padded_((static_cast<std::size_t>(options.buffer) + kBlock - 1) / kBlock * kBlock) {
  reset();
}

void Dwf::reset() noexcept {
  x_.assign(2 * padded_, kFar);
  y_.assign(2 * padded_, kFar);
  const std::int16_t fill = options_.variant == DwfOptions::Variant::cuke ? 0 : -1;
  const auto n = static_cast<std::ptrdiff_t>(options_.buffer);
  for (const std::size_t w : {std::size_t{0}, std::size_t{1}}) {
    // CUKE: both windows start full of default events at (0, 0); jAER: both full of (-1, -1) (the signal
    // window is then overwritten by the first events).
    const auto begin = static_cast<std::ptrdiff_t>(w * padded_);
    std::fill(x_.begin() + begin, x_.begin() + begin + n, fill);
    std::fill(y_.begin() + begin, y_.begin() + begin + n, fill);
    next_[w] = 0;
  }
  fill_seen_ = 0;
  score_ = 0.0F;
}

void Dwf::push(std::size_t window, std::int16_t x, std::int16_t y) noexcept {
  std::size_t& next = next_[window];
  x_[window * padded_ + next] = x;
  y_[window * padded_ + next] = y;
  next = next + 1 == static_cast<std::size_t>(options_.buffer) ? 0 : next + 1;
}

int Dwf::count_near(std::int16_t x, std::int16_t y) const noexcept {
  const auto r = static_cast<std::int16_t>(options_.l1_radius);
  const std::int16_t* wx = x_.data();
  const std::int16_t* wy = y_.data();
  // One counter per lane of a fixed-size block: the compiler turns the inner loop into straight SIMD code
  // (no scalar tail, no horizontal sum per block). A lane counts at most 2·65 536 / kBlock events: fits int16.
  std::int16_t lane[kBlock] = {};
  for (std::size_t b = 0; b < x_.size(); b += kBlock) {
    for (std::size_t k = 0; k < kBlock; ++k) {
      const auto dx = static_cast<std::int16_t>(wx[b + k] - x);
      const auto dy = static_cast<std::int16_t>(wy[b + k] - y);
      const auto l1 = static_cast<std::int16_t>((dx < 0 ? -dx : dx) + (dy < 0 ? -dy : dy));
      lane[k] = static_cast<std::int16_t>(lane[k] + (l1 <= r ? 1 : 0));
    }
  }
  int n = 0;
  for (const std::int16_t c : lane) {
    n += c;
  }
  return n;
}

bool Dwf::accept(const Event& e) noexcept {
  if (!geometry_.contains(e.x, e.y)) {
    score_ = -1.0F;
    return false;
  }
  const auto x = static_cast<std::int16_t>(e.x);
  const auto y = static_cast<std::int16_t>(e.y);
  if (options_.variant == DwfOptions::Variant::jaer && fill_seen_ < 2 * std::int64_t{options_.buffer}) {
    if (fill_seen_ < options_.buffer) {
      push(0, x, y);
    }
    ++fill_seen_;
    score_ = -1.0F;
    return false;
  }
  const int n = count_near(x, y);
  const bool keep = n >= options_.threshold;
  push(keep ? 0 : 1, x, y);
  score_ = static_cast<float>(n);
  return keep;
}

FilterSpec dwf_spec() {
  return {"dwf", "double window filter, CUKE/E-MLB semantics (36 events per window, L1 <= 9, threshold 1)",
          [](Params& p, const SensorGeometry& g) -> std::unique_ptr<Filter> {
            DwfOptions o;
            o.variant = p.choice("variant", "cuke", {"cuke", "jaer"},
                                 "cuke = CUKE (36 + 36, L1 <= 9, windows pre-filled at (0,0)); jaer = jAER "
                                 "(256 + 256, L1 < 5, first 512 events fill the windows)") == "jaer"
                            ? DwfOptions::Variant::jaer
                            : DwfOptions::Variant::cuke;
            const bool jaer = o.variant == DwfOptions::Variant::jaer;
            if (g.width > DwfOptions::kMaxSensorSide || g.height > DwfOptions::kMaxSensorSide) {
              p.fail("variant",
                     fmt::format("sensor {}x{} is larger than {} px", g.width, g.height, DwfOptions::kMaxSensorSide));
            }
            const auto buffer = p.integer("buffer", jaer ? 256 : 36, "events per window (default: cuke 36, jaer 256)");
            p.require_range("buffer", static_cast<double>(buffer), 1, 1 << 16);
            o.buffer = static_cast<int>(buffer);
            const auto radius = p.integer("l1_radius", jaer ? 4 : 9,
                                          "largest supporting L1 distance, inclusive (default: cuke 9, jaer 4 = "
                                          "jAER disThr 5 strict)");
            p.require_range("l1_radius", static_cast<double>(radius), 0, g.width + g.height);
            o.l1_radius = static_cast<int>(radius);
            const auto threshold = p.integer("threshold", o.threshold, "supporting window events needed");
            p.require_range("threshold", static_cast<double>(threshold), 1, static_cast<double>(2 * buffer));
            o.threshold = static_cast<int>(threshold);
            return std::make_unique<PerEventFilter<Dwf>>("dwf", g, o);
          }};
}

}  // namespace evpipe::denoise
