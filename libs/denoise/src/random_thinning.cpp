#include "evpipe/denoise/random_thinning.hpp"

#include <cmath>

namespace evpipe::denoise {

bool RandomThinning::accept(const Event& /*e*/) noexcept {
  // splitmix64: one 64-bit state step per event; the top 53 bits make a uniform double in [0, 1).
  state_ += 0x9E3779B97F4A7C15ULL;
  std::uint64_t z = state_;
  z = (z ^ (z >> 30U)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27U)) * 0x94D049BB133111EBULL;
  z ^= z >> 31U;
  const double u = static_cast<double>(z >> 11U) * 0x1.0p-53;
  return u < options_.keep_fraction;
}

FilterSpec random_spec() {
  return {"random", "random thinning (not a denoiser): the structure-neutral reference for kept-share effects",
          [](Params& p, const SensorGeometry& /*g*/) -> std::unique_ptr<Filter> {
            RandomThinningOptions o;
            o.keep_fraction = p.real("keep_fraction", o.keep_fraction, "probability of keeping each event, in [0, 1]");
            p.require_range("keep_fraction", o.keep_fraction, 0.0, 1.0);
            const std::int64_t seed = p.integer("seed", 1, "random seed (same seed, same decisions)");
            if (seed < 0) {
              p.fail("seed", "must be >= 0");
            }
            o.seed = static_cast<std::uint64_t>(seed);
            return std::make_unique<PerEventFilter<RandomThinning>>("random", o);
          }};
}

}  // namespace evpipe::denoise
