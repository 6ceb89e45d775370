#include "evpipe/denoise/dwf.hpp"

namespace evpipe::denoise {

Dwf::Dwf(const SensorGeometry& geometry, DwfOptions options) : geometry_(geometry), options_(options) {
  reset();
}

void Dwf::Window::push(std::int32_t px, std::int32_t py) noexcept {
  x[next] = px;
  y[next] = py;
  next = next + 1 == x.size() ? 0 : next + 1;
}

void Dwf::reset() noexcept {
  const auto n = static_cast<std::size_t>(options_.buffer);
  const std::int32_t fill = options_.variant == DwfOptions::Variant::cuke ? 0 : -1;
  for (Window* w : {&signal_, &noise_}) {
    w->x.assign(n, fill);
    w->y.assign(n, fill);
    w->next = 0;
  }
  fill_seen_ = 0;
  score_ = 0.0F;
}

int Dwf::count_near(const Window& w, std::int32_t x, std::int32_t y) const noexcept {
  const std::int32_t r = options_.l1_radius;
  const std::int32_t* wx = w.x.data();
  const std::int32_t* wy = w.y.data();
  int n = 0;
  for (std::size_t i = 0; i < w.x.size(); ++i) {
    const std::int32_t dx = wx[i] - x;
    const std::int32_t dy = wy[i] - y;
    n += ((dx < 0 ? -dx : dx) + (dy < 0 ? -dy : dy) <= r) ? 1 : 0;
  }
  return n;
}

bool Dwf::accept(const Event& e) noexcept {
  if (!geometry_.contains(e.x, e.y)) {
    score_ = -1.0F;
    return false;
  }
  const std::int32_t x = e.x;
  const std::int32_t y = e.y;
  if (options_.variant == DwfOptions::Variant::jaer && fill_seen_ < 2 * std::int64_t{options_.buffer}) {
    if (fill_seen_ < options_.buffer) {
      signal_.push(x, y);
    }
    ++fill_seen_;
    score_ = -1.0F;
    return false;
  }
  const int n = count_near(signal_, x, y) + count_near(noise_, x, y);
  const bool keep = n >= options_.threshold;
  (keep ? signal_ : noise_).push(x, y);
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
