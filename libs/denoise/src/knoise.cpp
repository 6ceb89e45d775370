#include "evpipe/denoise/knoise.hpp"

#include <limits>
#include <utility>

namespace evpipe::denoise {

namespace {
constexpr std::int64_t kNever = std::numeric_limits<std::int64_t>::min() / 2;  // t − kNever cannot overflow
}  // namespace

Knoise::Knoise(const SensorGeometry& geometry, KnoiseOptions options) : geometry_(geometry), options_(options) {
  reset();
}

void Knoise::reset() noexcept {
  // dv-processing and CUKE value-initialise their cells: t = 0, coordinate 0, polarity OFF (key 0).
  for (const auto& [lines, n] : {std::pair{&cols_, geometry_.width}, std::pair{&rows_, geometry_.height}}) {
    const auto size = static_cast<std::size_t>(n) + 3;
    lines->t_us.assign(size, 0);
    lines->key.assign(size, 0);
    lines->t_us[0] = lines->t_us[size - 2] = lines->t_us[size - 1] = kNever;
  }
  score_ = 0.0F;
}

int Knoise::count3(const Lines& lines, std::size_t first, std::int32_t key, std::int64_t oldest_us) const noexcept {
  int n = 0;
  for (std::size_t i = 0; i < 3; ++i) {
    // Branch-free: the outcome is data-dependent, so branches would mispredict.
    const auto u = static_cast<std::uint32_t>(lines.key[first + i] - key + 2);  // 0, 2, 4 when near, same polarity
    // The CUKE variant does not let our own pixel support us: our own line's cell must be 1 away (u 0 or 4).
    const bool own_line_cuke = i == 1 && options_.variant == KnoiseOptions::Variant::cuke;
    const bool near = own_line_cuke ? (u == 0U) | (u == 4U) : (u <= 4U) & ((u & 1U) == 0U);
    n += static_cast<int>(near & (lines.t_us[first + i] >= oldest_us));
  }
  return n;
}

bool Knoise::accept(const Event& e) noexcept {
  if (!geometry_.contains(e.x, e.y)) {
    score_ = 0.0F;
    return false;
  }
  const std::int32_t p = e.polarity ? 1 : 0;
  const std::int32_t kx = 2 * std::int32_t{e.x} + p;
  const std::int32_t ky = 2 * std::int32_t{e.y} + p;
  const std::int64_t oldest_us = e.t_us - options_.duration_us;  // t − c.t <= duration  <=>  c.t >= oldest
  // Columns x−1..x+1 (padded index x..x+2) are tested against our row, rows y−1..y+1 against our column.
  const int n = count3(cols_, e.x, ky, oldest_us) + count3(rows_, e.y, kx, oldest_us);
  cols_.t_us[std::size_t{e.x} + 1] = e.t_us;
  cols_.key[std::size_t{e.x} + 1] = ky;
  rows_.t_us[std::size_t{e.y} + 1] = e.t_us;
  rows_.key[std::size_t{e.y} + 1] = kx;
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
