#include "evpipe/denoise/baf.hpp"

#include <algorithm>
#include <limits>

namespace evpipe::denoise {

namespace {
constexpr std::int64_t kNever = std::numeric_limits<std::int64_t>::min() / 2;  // t − kNever cannot overflow
}  // namespace

Baf::Baf(const SensorGeometry& geometry, BafOptions options)
    : geometry_(geometry), options_(options), stride_(geometry.width + 2) {
  check_pixel_budget("baf", geometry, sizeof(std::int64_t));
  reset();
}

void Baf::reset() noexcept {
  last_t_us_.assign(static_cast<std::size_t>(stride_ * (geometry_.height + 2)), kNever);
  if (options_.zero_init) {
    for (int y = 0; y < geometry_.height; ++y) {
      std::fill_n(last_t_us_.begin() + (y + 1) * stride_ + 1, geometry_.width, std::int64_t{0});
    }
  }
}

bool Baf::accept(const Event& e) noexcept {
  if (!geometry_.contains(e.x, e.y)) {
    score_ = -std::numeric_limits<float>::max();
    return false;
  }
  std::int64_t* centre = last_t_us_.data() + (e.y + 1) * stride_ + (e.x + 1);
  const std::int64_t* up = centre - stride_;
  const std::int64_t* down = centre + stride_;
  const std::int64_t newest = std::max({up[-1], up[0], up[1], centre[-1], centre[1], down[-1], down[0], down[1]});
  *centre = e.t_us;
  score_ = newest <= kNever ? -std::numeric_limits<float>::max() : -static_cast<float>(e.t_us - newest);
  return e.t_us - newest < options_.duration_us;  // strict, as dv-processing
}

FilterSpec baf_spec() {
  return {"baf", "background-activity filter, dv-processing 2.0.4 semantics (paper: 2000 us)",
          [](Params& p, const SensorGeometry& g) -> std::unique_ptr<Filter> {
            BafOptions o;
            o.duration_us = p.integer("duration_us", o.duration_us, "support window in microseconds");
            p.require_positive("duration_us", static_cast<double>(o.duration_us));
            o.zero_init = p.choice("init", "zero", {"zero", "never"},
                                   "time surface at start: zero = dv-processing (events before duration_us "
                                   "pass), never = no start-up artefact") == "zero";
            return std::make_unique<PerEventFilter<Baf>>("baf", g, o);
          }};
}

}  // namespace evpipe::denoise
