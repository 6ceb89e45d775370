#include "evpipe/denoise/stcf.hpp"

#include <limits>

namespace evpipe::denoise {

namespace {
constexpr std::int64_t kNeverPacked = std::numeric_limits<std::int64_t>::min() / 2;
}  // namespace

Stcf::Stcf(const SensorGeometry& geometry, StcfOptions options)
    : geometry_(geometry), options_(options), stride_(geometry.width + 2 * options.radius) {
  check_pixel_budget("stcf", geometry, sizeof(std::int64_t));
  reset();
}

void Stcf::reset() noexcept {
  last_.assign(static_cast<std::size_t>(stride_ * (geometry_.height + 2 * options_.radius)), kNeverPacked);
  score_ = 0.0F;
}

namespace {

// Cells of the (2r+1)² block around `centre` (own pixel included) whose last event is less than tau old and, under
// `pol_mask` = 1, has our polarity. Branch-free per cell; kRadius > 0 unrolls jAER's 3×3 default.
template <int kRadius>
[[gnu::always_inline]] inline int correlated(const std::int64_t* centre, std::int64_t stride, int radius,
                                             std::int64_t t_us, std::int64_t polarity, std::int64_t pol_mask,
                                             std::int64_t tau_us) noexcept {
  const int r = kRadius > 0 ? kRadius : radius;
  int n = 0;
  for (int dy = -r; dy <= r; ++dy) {
    const std::int64_t* row = centre + dy * stride;
    for (int dx = -r; dx <= r; ++dx) {
      const std::int64_t v = row[dx];
      n += static_cast<int>((((v ^ polarity) & pol_mask) == 0) & (t_us - (v >> 1) < tau_us));
    }
  }
  return n;
}

}  // namespace

bool Stcf::accept(const Event& e) noexcept {
  if (!geometry_.contains(e.x, e.y)) {
    score_ = -1.0F;
    return false;
  }
  const int r = options_.radius;
  std::int64_t* centre = last_.data() + (e.y + r) * stride_ + (e.x + r);
  const std::int64_t t = e.t_us;
  const std::int64_t p = e.polarity ? 1 : 0;
  const std::int64_t own = *centre;
  *centre = t * 2 + p;
  if (own == kNeverPacked) {  // first event at this pixel: only stamped
    score_ = -1.0F;
    return options_.let_first_event_through;
  }
  // Polarity mask: with polarity_match a cell's low bit must equal ours; without, it is ignored.
  const std::int64_t pol_mask = options_.polarity_match ? 1 : 0;
  const std::int64_t tau = options_.tau_us;
  // The block is read after stamping our own cell (age 0, our polarity: it always counts), so the own pixel's
  // previous event is added back instead when it is to be counted.
  int n = r == 1 ? correlated<1>(centre, stride_, 1, t, p, pol_mask, tau)
                 : correlated<0>(centre, stride_, r, t, p, pol_mask, tau);
  n -= 1;
  if (!options_.filter_hot_pixels) {
    n += static_cast<int>((((own ^ p) & pol_mask) == 0) & (t - (own >> 1) < tau));
  }
  score_ = static_cast<float>(n);
  return n >= options_.k;
}

FilterSpec stcf_spec() {
  return {"stcf", "spatio-temporal correlation filter, jAER semantics (k = 2, tau 25 ms, polarity match)",
          [](Params& p, const SensorGeometry& g) -> std::unique_ptr<Filter> {
            StcfOptions o;
            const auto radius = p.integer("radius", o.radius, "block radius in pixels (jAER sigmaDistPixels)");
            p.require_range("radius", static_cast<double>(radius), 1, 15);
            o.radius = static_cast<int>(radius);
            const auto k = p.integer("k", o.k, "correlated pixels needed (jAER numMustBeCorrelated)");
            const auto side = 2 * radius + 1;
            p.require_range("k", static_cast<double>(k), 1, static_cast<double>(side * side));
            o.k = static_cast<int>(k);
            o.tau_us = p.integer("tau_us", o.tau_us, "correlation time in microseconds (t - t_pixel < tau_us)");
            p.require_positive("tau_us", static_cast<double>(o.tau_us));
            o.polarity_match = p.boolean("polarity_match", o.polarity_match, "supporting events need our polarity");
            o.filter_hot_pixels = p.boolean("filter_hot_pixels", o.filter_hot_pixels,
                                            "own pixel does not support itself (jAER filterHotPixels)");
            o.let_first_event_through =
                p.boolean("let_first_event_through", o.let_first_event_through, "keep the first event at each pixel");
            if (o.filter_hot_pixels && o.k > side * side - 1) {
              p.fail("k", "must be < block size when filter_hot_pixels is true (own pixel excluded)");
            }
            return std::make_unique<PerEventFilter<Stcf>>("stcf", g, o);
          }};
}

}  // namespace evpipe::denoise
