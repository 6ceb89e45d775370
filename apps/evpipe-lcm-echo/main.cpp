// evpipe-lcm-echo: prints evpipe's LCM messages (pose_t, stats_t) as JSON or text lines, live from an LCM URL or
// from an LCM log file. For operators without a display (lcm-spy is a GUI) and for end-to-end tests.
// Messages are recognised by their LCM fingerprint, so any channel name works; other types print as
// {"channel":..., "type":null, "bytes":N}; a pose_t or stats_t that is invalid, truncated or has an array count
// beyond its bytes as {"channel":..., "type":null, "error":"<type>.<field> ..."}.
// A --log is printed as it is read; at the first event that is not whole (bad sync word, a length beyond the end
// of the file, truncated) the events before it have been printed and the error names the file and byte offset.
// Exit status: 0 done (count reached, timeout without --count, end of log, SIGINT/SIGTERM), 1 LCM or log error (a
// --log that is not an LCM log, or corrupt or truncated) or --count not reached before --timeout, 2 usage error
// (an invalid --url).

#include "evpipe/cli/cli.hpp"
#include "evpipe/core/file.hpp"
#include "evpipe/transport/codec.hpp"
#include "evpipe/transport/lcm_capture.hpp"
#include "evpipe/transport/lcm_publisher.hpp"
#include "evpipe/transport/lcm_url.hpp"
#include "evpipe/transport/text.hpp"

#include <fmt/format.h>

#include <csignal>
#include <cstdio>
#include <string>

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int) {
  g_stop = 1;
}

std::string render(const evpipe::transport::ReceivedMessage& m, bool text) {
  using namespace evpipe::transport;
  try {
    if (auto p = decode_pose(m.data.data(), m.data.size())) {
      return text ? to_text(*p, m.channel) : to_json(*p, m.channel);
    }
    if (auto s = decode_stats(m.data.data(), m.data.size())) {
      return text ? to_text(*s, m.channel) : to_json(*s, m.channel);
    }
  } catch (const DecodeError& e) {
    return text ? fmt::format("{} invalid message: {}", m.channel, e.what())
                : fmt::format(R"({{"channel":"{}","type":null,"error":"{}"}})", m.channel, e.what());
  }
  if (const auto why = wire_error(m.data.data(), m.data.size())) {  // an evpipe type, truncated or corrupt
    return text ? fmt::format("{} invalid message: {}", m.channel, *why)
                : fmt::format(R"({{"channel":"{}","type":null,"error":"{}"}})", m.channel, *why);
  }
  return text ? fmt::format("{} ({} bytes, not an evpipe type)", m.channel, m.data.size())
              : fmt::format(R"({{"channel":"{}","type":null,"bytes":{}}})", m.channel, m.data.size());
}

}  // namespace

int main(int argc, char** argv) {
  std::string url;
  std::string channel = ".*";
  std::string log_path;
  std::size_t count = 0;
  double timeout_s = 0.0;
  bool text = false;
  evpipe::cli::App app{"evpipe-lcm-echo: print evpipe LCM messages (pose_t, stats_t) as JSON lines or text"};
  app.add_option("--url", url, "LCM URL (default: $LCM_DEFAULT_URL, else udpm://239.255.76.67:7667?ttl=0)");
  app.add_option("--channel", channel, "Channel name or regex to subscribe to")->capture_default_str();
  app.add_option("--log", log_path, "Read this LCM log file (lcm-logger) instead of listening");
  app.add_option("-n,--count", count, "Stop after this many messages (0 = no limit)");
  app.add_option("--timeout", timeout_s,
                 "Stop after this many seconds (0 = none); with --count, not reaching the "
                 "count in time is an error")
      ->check(evpipe::cli::non_negative_number());
  app.add_flag("--text", text, "Human-readable lines instead of JSON");
  if (const auto status = app.parse(argc, argv)) return *status;

  std::size_t printed = 0;
  auto print = [&](const evpipe::transport::ReceivedMessage& m) {
    if (count != 0 && printed >= count) return;
    std::fputs((render(m, text) + '\n').c_str(), stdout);
    std::fflush(stdout);
    ++printed;
  };

  if (!log_path.empty()) {
    try {
      // Printed as read: the events before a corrupt or truncated one are printed, then the error (exit 1).
      evpipe::transport::read_lcm_log(log_path, [&](evpipe::transport::ReceivedMessage&& m) { print(m); });
    } catch (const std::exception& e) {
      std::fprintf(stderr, "evpipe-lcm-echo: %s\n", e.what());
      return 1;
    }
    return 0;
  }

  evpipe::transport::LcmUrl parsed;
  if (const auto why = evpipe::transport::check_lcm_url(evpipe::transport::effective_lcm_url(url), false, &parsed)) {
    std::fprintf(stderr, "evpipe-lcm-echo: %s\n", why->c_str());
    return 2;
  }
  if (parsed.provider == "file") {  // LCM's file provider would block on a FIFO: a regular file only
    try {
      evpipe::check_input_file(parsed.target);
    } catch (const evpipe::FileError& e) {
      std::fprintf(stderr, "evpipe-lcm-echo: %s\n", e.what());
      return 1;
    }
  }
  evpipe::transport::LcmCapture cap(url);
  if (!cap.good()) {
    std::fprintf(stderr,
                 "evpipe-lcm-echo: cannot open LCM on %s (for udpm: a multicast route is needed, e.g. "
                 "'ip route add 224.0.0.0/4 dev lo')\n",
                 evpipe::transport::effective_lcm_url(url).c_str());
    return 1;
  }
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  cap.keep_messages(false);
  cap.on_message(print);
  cap.subscribe(channel);
  const auto start = std::chrono::steady_clock::now();
  const auto limit = std::chrono::duration<double>(timeout_s);
  while (g_stop == 0 && (count == 0 || printed < count)) {
    if (timeout_s > 0 && std::chrono::steady_clock::now() - start >= limit) {
      if (count != 0) {
        std::fprintf(stderr, "evpipe-lcm-echo: %zu of %zu message(s) on '%s' within %g s\n", printed, count,
                     channel.c_str(), timeout_s);
        return 1;
      }
      break;
    }
    cap.drain(std::chrono::milliseconds(100));  // short slices so signals and the timeout are seen promptly
  }
  return 0;
}
