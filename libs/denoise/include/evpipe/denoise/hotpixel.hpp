#pragma once
// Hot-pixel filter: learns stuck / hot pixels online (the paper's §2.2 "thermal noise": a damaged pixel keeps
// firing; its output is blocked) and drops every event of a pixel while it is marked hot. Meant to run in front
// of any other filter (`evdenoise --filter hotpixel,curvature`), so that hot pixels neither pass nor support
// their neighbours.
//
// Causal and bounded by the sensor: one event counter per pixel over consecutive periods of `period_us`
// (the first starts at the first event). A pixel is HOT when, over a period, its count n satisfies
//     n >= min_rate_hz · period   and   n >= ratio · (mean count of its in-sensor 8-neighbours),
// so a busy moving edge, whose neighbours are busy too, is not hot. The test runs
//   * at the end of every period, on the period's counts, for every pixel;
//   * online, on the running counts of the current period, as soon as a pixel's count reaches the rate bound
//     (the event that crosses it is already dropped), so a hot pixel is caught within its first
//     min_rate_hz · period events, not one period later.
// A hot pixel stays hot while it keeps passing the test; after `cool_periods` consecutive closed periods in which
// it fails, it is released. Periods without any event count as quiet periods.

#include <cstdint>
#include <vector>

#include "evpipe/core/event.hpp"
#include "evpipe/denoise/filter.hpp"
#include "evpipe/denoise/registry.hpp"

namespace evpipe::denoise {

struct HotPixelOptions {
  std::int64_t period_us = 1'000'000;
  double min_rate_hz = 50.0;
  double ratio = 5.0;
  int cool_periods = 3;
};

class HotPixel {
 public:
  HotPixel(const SensorGeometry& geometry, HotPixelOptions options);
  [[nodiscard]] bool accept(const Event& e) noexcept;
  /// Minus the pixel's count ratio to its neighbours' mean (over the last closed period, or when it was marked
  /// hot online); higher = more signal-like.
  [[nodiscard]] float last_score() const noexcept { return score_; }
  void reset() noexcept;
  /// hot_pixels (currently masked), hot_pixels_ever, hot_events_dropped, periods_closed.
  [[nodiscard]] std::vector<ReportItem> report() const;

  /// Whether pixel (x, y) is masked now.
  [[nodiscard]] bool is_hot(int x, int y) const noexcept;
  [[nodiscard]] std::size_t hot_pixels() const noexcept { return hot_now_; }

 private:
  [[nodiscard]] std::size_t index(int x, int y) const noexcept {
    return static_cast<std::size_t>((y + 1) * stride_ + (x + 1));
  }
  /// Count over mean neighbour count; the neighbour mean is floored at one event per period so the ratio stays
  /// finite on a quiet background.
  [[nodiscard]] float ratio_at(std::size_t i) const noexcept;
  [[nodiscard]] bool hot_test(std::size_t i) const noexcept;
  void close_periods(std::int64_t t_us) noexcept;

  SensorGeometry geometry_;
  HotPixelOptions options_;
  std::int64_t stride_;
  std::uint32_t min_count_;  // ceil(min_rate_hz · period)
  // Per pixel, padded by one on every side (padding counts stay 0): count in the current period, hot flag,
  // closed periods failed in a row while hot, last ratio (the score), neighbours inside the sensor.
  std::vector<std::uint32_t> count_;
  std::vector<std::uint8_t> hot_;
  std::vector<std::uint16_t> quiet_;
  std::vector<float> ratio_;
  std::vector<std::uint8_t> neighbours_;
  bool started_ = false;
  std::int64_t period_end_us_ = 0;
  std::size_t hot_now_ = 0;
  std::size_t hot_ever_ = 0;
  std::vector<std::uint8_t> ever_;  // pixel was hot at least once
  std::uint64_t dropped_ = 0;
  std::uint64_t periods_closed_ = 0;
  float score_ = 0.0F;
};

FilterSpec hotpixel_spec();

}  // namespace evpipe::denoise
