#include "summary.hpp"

#include "json_quote.hpp"

#include <fmt/format.h>

namespace evpipe::app {

namespace {

std::string rate(double hz) {
  if (hz >= 1e6) return fmt::format("{:.2f} Mev/s", hz / 1e6);
  if (hz >= 1e3) return fmt::format("{:.1f} kev/s", hz / 1e3);
  return fmt::format("{:.0f} ev/s", hz);
}

}  // namespace

std::string format_text(const RunSummary& s) {
  const auto& st = *s.stream;
  std::string o;
  auto line = [&o](const char* k, const std::string& v) { o += fmt::format("  {:<18}{}\n", k, v); };
  o += s.error.empty() ? (s.interrupted ? "evpipe summary (interrupted)\n" : "evpipe summary\n")
                       : "evpipe summary (stopped on an error)\n";
  line("source", fmt::format("{} ({})", s.info.name, s.info.format));
  line("resolution", fmt::format("{} x {}{}", s.info.geometry.width, s.info.geometry.height,
                                 s.info.geometry_known ? "" : " (assumed: not stated by the source)"));
  line("events", fmt::format("{}", st.events()));
  if (st.first_t_us())
    line("duration", fmt::format("{:.6f} s  (t {} .. {} us)", static_cast<double>(st.duration_us()) / 1e6,
                                 *st.first_t_us(), *st.last_t_us()));
  else
    line("duration", "0 s (no events)");
  line("mean rate", rate(st.mean_rate_hz()));
  line("peak rate", fmt::format("{} (busiest {} ms)", rate(st.peak_rate_hz()), st.peak_bin_us() / 1000));
  line("ON share", fmt::format("{:.1f} %", 100.0 * st.on_share()));
  line("out-of-order", fmt::format("{}{}", s.source.out_of_order,
                                   s.source.out_of_order ? (s.out_of_order_dropped ? " (dropped)" : " (kept)") : ""));
  line("discontinuities", fmt::format("{}", s.source.discontinuities));
  line("skipped non-DVS", fmt::format("{}", s.source.skipped_non_dvs));
  if (s.source.invalid_events) line("invalid events", fmt::format("{}", s.source.invalid_events));
  line("corrupt packets", fmt::format("{}", s.source.corrupt_packets));
  if (s.source.truncated_bytes) line("truncated bytes", fmt::format("{}", s.source.truncated_bytes));
  if (s.source.dropped_packets || s.source.dropped_events)
    line("dropped", fmt::format("{} packets, {} events", s.source.dropped_packets, s.source.dropped_events));
  if (s.denoise_filter == "none")
    line("denoise", "none");
  else
    line("denoise",
         fmt::format("{}: kept {} of {} ({:.1f} %), decision latency {} ms", s.denoise_filter, s.denoise_kept,
                     s.denoise_in, s.denoise_in ? 100.0 * static_cast<double>(s.denoise_kept) / s.denoise_in : 0.0,
                     s.denoise_latency_us / 1000.0));
  line("windows", fmt::format("{} of {} ms, hop {} ms ({} events)", s.windows, s.window_us / 1000.0, s.hop_us / 1000.0,
                              s.window_events));
  line("wall time",
       fmt::format("{:.3f} s ({})", s.wall_s, rate(s.wall_s > 0 ? static_cast<double>(st.events()) / s.wall_s : 0.0)));
  if (!s.error.empty()) line("error", s.error);
  return o;
}

std::string format_json(const RunSummary& s) {
  const auto& st = *s.stream;
  return fmt::format(
      "{{\"source\":{},\"format\":\"{}\",\"width\":{},\"height\":{},\"geometry_known\":{},"
      "\"events\":{},\"on_events\":{},\"first_t_us\":{},\"last_t_us\":{},\"duration_us\":{},"
      "\"mean_rate_hz\":{:.3f},\"peak_rate_hz\":{:.3f},\"peak_bin_us\":{},\"on_share\":{:.6f},"
      "\"out_of_order\":{},\"out_of_order_dropped\":{},\"discontinuities\":{},\"skipped_non_dvs\":{},"
      "\"invalid_events\":{},\"corrupt_packets\":{},\"truncated_bytes\":{},\"dropped_packets\":{},"
      "\"dropped_events\":{},\"denoise_filter\":{},\"denoise_in\":{},\"denoise_kept\":{},"
      "\"denoise_latency_us\":{},\"windows\":{},\"window_events\":{},\"window_us\":{},\"hop_us\":{},"
      "\"wall_s\":{:.6f},\"interrupted\":{},\"error\":{}}}\n",
      json_quote(s.info.name), s.info.format, s.info.geometry.width, s.info.geometry.height, s.info.geometry_known,
      st.events(), st.on_events(), st.first_t_us() ? fmt::format("{}", *st.first_t_us()) : "null",
      st.last_t_us() ? fmt::format("{}", *st.last_t_us()) : "null", st.duration_us(), st.mean_rate_hz(),
      st.peak_rate_hz(), st.peak_bin_us(), st.on_share(), s.source.out_of_order, s.out_of_order_dropped,
      s.source.discontinuities, s.source.skipped_non_dvs, s.source.invalid_events, s.source.corrupt_packets,
      s.source.truncated_bytes, s.source.dropped_packets, s.source.dropped_events, json_quote(s.denoise_filter),
      s.denoise_in, s.denoise_kept, s.denoise_latency_us, s.windows, s.window_events, s.window_us, s.hop_us, s.wall_s,
      s.interrupted, json_quote(s.error));
}

}  // namespace evpipe::app
