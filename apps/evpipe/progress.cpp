#include "progress.hpp"

#include <unistd.h>

#include <fmt/format.h>
#include <algorithm>
#include <cstdio>
#include <string>

namespace evpipe::app {

ProgressBar::ProgressBar(bool enabled) : active_(enabled && ::isatty(STDERR_FILENO) == 1) {}

void ProgressBar::update(std::optional<double> fraction, std::uint64_t events, std::int64_t stream_time_us,
                         std::string_view extra) {
  if (!active_) return;
  const auto now = Clock::now();
  if (now - last_draw_ < std::chrono::milliseconds(100)) return;
  last_draw_ = now;
  const double dt = std::chrono::duration<double>(now - last_rate_t_).count();
  if (dt >= 0.5) {
    rate_mevs_ = static_cast<double>(events - last_events_) / dt / 1e6;
    last_events_ = events;
    last_rate_t_ = now;
  }
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  std::string bar;
  if (fraction) {
    constexpr int width = 30;
    const int filled = std::clamp(static_cast<int>(*fraction * width + 0.5), 0, width);
    bar = fmt::format("[{:#<{}}{:.<{}}] {:5.1f}%", "", filled, "", width - filled, *fraction * 100);
  } else {
    bar = "[live]";
  }
  std::fprintf(stderr, "\r%s  elapsed %6.1f s  stream %8.2f s  %6.2f Mev/s  %llu ev  %.*s\x1b[K", bar.c_str(), elapsed,
               static_cast<double>(stream_time_us) / 1e6, rate_mevs_, static_cast<unsigned long long>(events),
               static_cast<int>(extra.size()), extra.data());
  std::fflush(stderr);
}

void ProgressBar::finish() {
  if (!active_) return;
  std::fprintf(stderr, "\r\x1b[K");
  std::fflush(stderr);
}

}  // namespace evpipe::app
