#include "evpipe/denoise/hotpixel.hpp"

#include <algorithm>
#include <cmath>

namespace evpipe::denoise {

HotPixel::HotPixel(const SensorGeometry& geometry, HotPixelOptions options)
    : geometry_(geometry),
      options_(options),
      stride_(geometry.width + 2),
      min_count_(
          static_cast<std::uint32_t>(std::ceil(options.min_rate_hz * static_cast<double>(options.period_us) * 1e-6))) {
  check_pixel_budget("hotpixel", geometry, 13);  // count, hot, quiet, ratio, neighbours, ever
  const auto n = static_cast<std::size_t>(stride_ * (geometry.height + 2));
  neighbours_.assign(n, 0);
  for (int y = 0; y < geometry.height; ++y) {
    for (int x = 0; x < geometry.width; ++x) {
      int k = 0;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          k += ((dx != 0 || dy != 0) && geometry.contains(x + dx, y + dy)) ? 1 : 0;
        }
      }
      neighbours_[index(x, y)] = static_cast<std::uint8_t>(k);
    }
  }
  reset();
}

void HotPixel::reset() noexcept {
  const std::size_t n = neighbours_.size();
  count_.assign(n, 0);
  hot_.assign(n, 0);
  quiet_.assign(n, 0);
  ratio_.assign(n, 0.0F);
  ever_.assign(n, 0);
  started_ = false;
  period_end_us_ = 0;
  hot_now_ = 0;
  hot_ever_ = 0;
  dropped_ = 0;
  periods_closed_ = 0;
  score_ = 0.0F;
}

bool HotPixel::is_hot(int x, int y) const noexcept {
  return geometry_.contains(x, y) && hot_[index(x, y)] != 0;
}

namespace {
std::uint32_t neighbour_sum(const std::uint32_t* c, std::int64_t stride) noexcept {
  return c[-stride - 1] + c[-stride] + c[-stride + 1] + c[-1] + c[1] + c[stride - 1] + c[stride] + c[stride + 1];
}
}  // namespace

float HotPixel::ratio_at(std::size_t i) const noexcept {
  const double mean = static_cast<double>(neighbour_sum(&count_[i], stride_)) / neighbours_[i];
  return static_cast<float>(count_[i] / std::max(mean, 1.0));
}

bool HotPixel::hot_test(std::size_t i) const noexcept {
  const std::uint32_t c = count_[i];
  // c >= ratio · sum / neighbours, without dividing
  return c >= min_count_ && static_cast<double>(c) * neighbours_[i] >=
                                options_.ratio * static_cast<double>(neighbour_sum(&count_[i], stride_));
}

void HotPixel::close_periods(std::int64_t t_us) noexcept {
  // Periods [end − period, end) ending at or before t_us: the first holds the counts, the others are empty.
  const std::int64_t closed = (t_us - period_end_us_) / options_.period_us + 1;
  period_end_us_ += closed * options_.period_us;
  periods_closed_ += static_cast<std::uint64_t>(closed);
  const auto cool = static_cast<std::int64_t>(options_.cool_periods);
  for (int y = 0; y < geometry_.height; ++y) {
    for (int x = 0; x < geometry_.width; ++x) {
      const std::size_t i = index(x, y);
      const bool hot_in_period = hot_test(i);
      // Every empty period after the first is one more failed test.
      std::int64_t quiet = hot_in_period ? closed - 1 : std::int64_t{quiet_[i]} + closed;
      if (hot_in_period && !hot_[i]) {
        hot_[i] = 1;
        ++hot_now_;
        if (!ever_[i]) {
          ever_[i] = 1;
          ++hot_ever_;
        }
      }
      if (hot_[i] && quiet >= cool) {
        hot_[i] = 0;
        --hot_now_;
        quiet = 0;
      }
      quiet_[i] = hot_[i] ? static_cast<std::uint16_t>(quiet) : std::uint16_t{0};
      ratio_[i] = closed == 1 ? ratio_at(i) : 0.0F;
    }
  }
  std::fill(count_.begin(), count_.end(), 0U);
}

bool HotPixel::accept(const Event& e) noexcept {
  if (!geometry_.contains(e.x, e.y)) {
    score_ = 0.0F;
    return false;
  }
  if (!started_) {
    started_ = true;
    period_end_us_ = e.t_us + options_.period_us;
  } else if (e.t_us >= period_end_us_) {
    close_periods(e.t_us);
  }
  const std::size_t i = index(e.x, e.y);
  const std::uint32_t c = ++count_[i];
  if (hot_[i] == 0) {
    if (c < min_count_ || !hot_test(i)) {
      score_ = -ratio_[i];
      return true;
    }
    hot_[i] = 1;  // crossed the bound online, within the current period
    quiet_[i] = 0;
    ++hot_now_;
    if (!ever_[i]) {
      ever_[i] = 1;
      ++hot_ever_;
    }
    ratio_[i] = ratio_at(i);
  }
  ++dropped_;
  score_ = -ratio_[i];
  return false;
}

std::vector<ReportItem> HotPixel::report() const {
  return {{"hot_pixels", static_cast<double>(hot_now_)},
          {"hot_pixels_ever", static_cast<double>(hot_ever_)},
          {"hot_events_dropped", static_cast<double>(dropped_)},
          {"periods_closed", static_cast<double>(periods_closed_)}};
}

FilterSpec hotpixel_spec() {
  return {"hotpixel", "learns hot (stuck) pixels online from per-period rates and drops their events",
          [](Params& p, const SensorGeometry& g) -> std::unique_ptr<Filter> {
            HotPixelOptions o;
            o.period_us = p.integer("period_us", o.period_us, "counting period in microseconds");
            p.require_positive("period_us", static_cast<double>(o.period_us));
            o.min_rate_hz = p.real("min_rate_hz", o.min_rate_hz, "a hot pixel fires at least this often (Hz)");
            p.require_positive("min_rate_hz", o.min_rate_hz);
            if (o.min_rate_hz * static_cast<double>(o.period_us) * 1e-6 < 2.0) {
              p.fail("min_rate_hz", "min_rate_hz * period must be at least 2 events (raise it or period_us)");
            }
            o.ratio = p.real("ratio", o.ratio, "... and at least ratio x the mean rate of its 8 neighbours");
            p.require_range("ratio", o.ratio, 1.0, 1e6);
            const auto cool = p.integer("cool_periods", o.cool_periods,
                                        "a hot pixel is released after this many periods failing the test");
            p.require_range("cool_periods", static_cast<double>(cool), 1, 60'000);
            o.cool_periods = static_cast<int>(cool);
            return std::make_unique<PerEventFilter<HotPixel>>("hotpixel", g, o);
          }};
}

}  // namespace evpipe::denoise
