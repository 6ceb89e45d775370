#include "evpipe/denoise/filter.hpp"

#include <fmt/format.h>
#include <algorithm>
#include <stdexcept>

namespace evpipe::denoise {

void check_pixel_budget(std::string_view filter, const SensorGeometry& geometry, std::size_t bytes_per_pixel) {
  if (!within_sensor_limits(geometry))
    throw std::invalid_argument(fmt::format("{}: a {}x{} sensor is beyond the largest evpipe accepts ({}x{})", filter,
                                            geometry.width, geometry.height, kMaxSensorSide, kMaxSensorSide));
  const std::size_t bytes = bytes_per_pixel * geometry.pixels();
  if (bytes > kMaxFilterStateBytes)
    throw std::invalid_argument(fmt::format(
        "{}: its per-pixel state for a {}x{} sensor would take {} MiB, over the "
        "{} MiB budget of a filter ({} bytes per pixel of the largest sensor)",
        filter, geometry.width, geometry.height, bytes >> 20, kMaxFilterStateBytes >> 20, kMaxFilterBytesPerPixel));
}

Decisions run_filter(Filter& filter, EventSpan events, std::size_t chunk_events) {
  Decisions out;
  out.keep.reserve(events.size());
  if (filter.has_score()) {
    out.score.reserve(events.size());
  }
  const std::size_t step = chunk_events == 0 ? std::max<std::size_t>(events.size(), 1) : chunk_events;
  for (std::size_t i = 0; i < events.size(); i += step) {
    filter.push(events.subspan(i, std::min(step, events.size() - i)), out);
  }
  filter.finish(out);
  return out;
}

std::size_t count_kept(const Decisions& decisions) noexcept {
  return static_cast<std::size_t>(std::count(decisions.keep.begin(), decisions.keep.end(), std::uint8_t{1}));
}

}  // namespace evpipe::denoise
