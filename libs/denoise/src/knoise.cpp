#include "evpipe/denoise/knoise.hpp"

#include <limits>

namespace evpipe::denoise {

namespace {
constexpr std::int64_t kNever = std::numeric_limits<std::int64_t>::min() / 2;  // t − kNever cannot overflow
}  // namespace

Knoise::Knoise(const SensorGeometry& geometry, KnoiseOptions options)
    : geometry_(geometry),
      options_(options),
      cols_(static_cast<std::size_t>(geometry.width) + 2),
      rows_(static_cast<std::size_t>(geometry.height) + 2) {
  reset();
}

void Knoise::reset() noexcept {
  // dv-processing and CUKE value-initialise their cells: t = 0, coordinates 0, polarity OFF.
  for (auto* cells : {&cols_, &rows_}) {
    for (Cell& c : *cells) {
      c = Cell{0, 0, 0};
    }
    cells->front().t_us = kNever;
    cells->back().t_us = kNever;
  }
  score_ = 0.0F;
}

bool Knoise::accept(const Event& e) noexcept {
  if (!geometry_.contains(e.x, e.y)) {
    score_ = 0.0F;
    return false;
  }
  const std::int32_t x = e.x;
  const std::int32_t y = e.y;
  const std::int32_t p = e.polarity ? 1 : 0;
  const std::int64_t t = e.t_us;
  const std::int64_t d = options_.duration_us;
  // A cell at neighbour offset `off` supports when it is recent, of the same polarity and its coordinate is
  // within 1 of ours; at offset 0 (our own column/row) the CUKE variant needs it 1 away (not our own pixel).
  const std::int32_t own_min = options_.variant == KnoiseOptions::Variant::cuke ? 1 : 0;
  auto support = [&](const Cell& c, std::int32_t own, bool centre) noexcept -> int {
    const std::int32_t dist = c.pos > own ? c.pos - own : own - c.pos;
    const bool near = dist <= 1 && (!centre || dist >= own_min);
    return (near && c.polarity == p && t - c.t_us <= d) ? 1 : 0;
  };
  Cell* col = cols_.data() + x + 1;
  Cell* row = rows_.data() + y + 1;
  const int n = support(col[-1], y, false) + support(col[0], y, true) + support(col[1], y, false) +
                support(row[-1], x, false) + support(row[0], x, true) + support(row[1], x, false);
  col[0] = Cell{t, y, p};
  row[0] = Cell{t, x, p};
  score_ = static_cast<float>(n);
  return n >= options_.supporters;
}

FilterSpec knoise_spec() {
  return {"knoise", "KNoise O(N)-memory filter, dv-processing 2.0.4 semantics (paper: 1000 us, 1 supporter)",
          [](Params& p, const SensorGeometry& g) -> std::unique_ptr<Filter> {
            KnoiseOptions o;
            o.duration_us =
                p.integer("duration_us", o.duration_us, "support window in microseconds (t - t_cell <= duration_us)");
            p.require_positive("duration_us", static_cast<double>(o.duration_us));
            const auto supporters = p.integer("supporters", o.supporters, "supporting column/row cells needed (1..6)");
            p.require_range("supporters", static_cast<double>(supporters), 1, 6);
            o.supporters = static_cast<int>(supporters);
            o.variant = p.choice("variant", "dv", {"dv", "cuke"},
                                 "dv = dv-processing (own pixel supports), cuke = CUKE/E-MLB (own pixel "
                                 "excluded)") == "cuke"
                            ? KnoiseOptions::Variant::cuke
                            : KnoiseOptions::Variant::dv;
            return std::make_unique<PerEventFilter<Knoise>>("knoise", g, o);
          }};
}

}  // namespace evpipe::denoise
