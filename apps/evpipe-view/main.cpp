// evpipe-view: watch what evpipe sees (issue 22, docs/operations.md "Watching the pipeline"). Subscribes to the
// preview channel (preview_t, evpipe --preview) on any LCM URL and shows each preview: raw events grey, kept events
// by polarity, the model green when tracking, amber when holding, red when lost or initialising, a status band.
//
// Keys: space pause/resume, n step one preview (paused), r raw events on/off, k kept colours on/off, s save PNG,
// q / Esc quit. Without a window: --screenshot FILE --frames N saves the Nth preview and exits; --video FILE writes
// every preview received.
//
// Exit status: 0 done, 1 LCM error, no preview within --timeout, or only messages of another type on the channel,
// 2 usage error (also no display for a window, an invalid --lcm-url).

#include <fmt/format.h>
#include <netdb.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <opencv2/highgui.hpp>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <set>
#include <string>

#include "evpipe/cli/cli.hpp"
#include "evpipe/transport/codec.hpp"
#include "evpipe/transport/lcm_capture.hpp"
#include "evpipe/transport/lcm_publisher.hpp"
#include "evpipe/transport/lcm_url.hpp"
#include "evpipe/transport/preview.hpp"
#include "evpipe/view/render.hpp"
#include "evpipe/view/video.hpp"

namespace {

volatile std::sig_atomic_t g_stop = 0;
void on_signal(int /*sig*/) {
  g_stop = 1;
}

constexpr std::size_t kKeepFrames = 300;  // previews buffered while paused (30 s at 10 Hz)
constexpr const char* kWindow = "evpipe-view";

struct Cli {
  std::string url;
  std::string channel{evpipe::transport::kDefaultPreviewChannel};
  int zoom = 2;
  std::string screenshot;
  std::size_t frames = 0;
  double timeout_s = -1;
  std::string video;
  double video_fps = 10;
  std::string png_dir = ".";
  bool headless = false;
};

/// Whether the X display named by $DISPLAY accepts a connection. OpenCV's Qt backend aborts the process when it
/// cannot connect, so evpipe-view asks first: ":N" is the socket /tmp/.X11-unix/XN, "host:N" TCP port 6000 + N
/// (ssh -X forwards such a display).
bool x_display_reachable(const std::string& display, std::string& why) {
  const auto colon = display.rfind(':');
  if (colon == std::string::npos) {
    why = "DISPLAY='" + display + "' is not of the form [host]:N";
    return false;
  }
  const std::string host = display.substr(0, colon);
  int n = 0;
  try {
    n = std::stoi(display.substr(colon + 1));
  } catch (const std::exception&) {
    why = "DISPLAY='" + display + "' has no display number";
    return false;
  }
  if (host.empty() || host == "unix") {
    const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    const std::string path = "/tmp/.X11-unix/X" + std::to_string(n);
    std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", path.c_str());
    const bool ok = fd >= 0 && ::connect(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) == 0;
    if (fd >= 0) ::close(fd);
    if (!ok) why = "no X server answers on " + path;
    return ok;
  }
  addrinfo hints{};
  hints.ai_socktype = SOCK_STREAM;
  addrinfo* res = nullptr;
  if (::getaddrinfo(host.c_str(), std::to_string(6000 + n).c_str(), &hints, &res) != 0 || res == nullptr) {
    why = "cannot resolve the display host '" + host + "'";
    return false;
  }
  bool ok = false;
  for (addrinfo* a = res; a != nullptr && !ok; a = a->ai_next) {
    const int fd = ::socket(a->ai_family, a->ai_socktype, a->ai_protocol);
    if (fd < 0) continue;
    ok = ::connect(fd, a->ai_addr, a->ai_addrlen) == 0;
    ::close(fd);
  }
  ::freeaddrinfo(res);
  if (!ok) why = "no X server answers on " + host + " port " + std::to_string(6000 + n);
  return ok;
}

std::string join(const std::set<std::string>& names) {
  std::string s;
  for (const auto& n : names) s += (s.empty() ? "" : ", ") + n;
  return s.empty() ? "none" : s;
}

int run(const Cli& cli) {
  using namespace evpipe;
  const bool want_window = !cli.headless;
  if (want_window && std::getenv("DISPLAY") == nullptr && std::getenv("WAYLAND_DISPLAY") == nullptr) {
    std::fprintf(stderr,
                 "evpipe-view: no display (DISPLAY is not set): run it on a desktop, under xvfb-run, or with "
                 "--headless and --screenshot / --video\n");
    return 2;
  }
  if (const char* d = std::getenv("DISPLAY"); want_window && d != nullptr && *d != '\0') {
    std::string why;
    if (!x_display_reachable(d, why)) {
      std::fprintf(stderr, "evpipe-view: no display: %s (DISPLAY=%s); use xvfb-run or --headless\n", why.c_str(), d);
      return 2;
    }
  }
  if (cli.headless && cli.screenshot.empty() && cli.video.empty()) {
    std::fprintf(stderr, "evpipe-view: --headless needs --screenshot or --video (nothing would be shown)\n");
    return 2;
  }
  const std::string url = transport::effective_lcm_url(cli.url);
  if (const auto why = transport::check_lcm_url(url, false)) {  // e.g. file://...?mode=w would truncate a log
    std::fprintf(stderr, "evpipe-view: %s\n", why->c_str());
    return 2;
  }
  transport::LcmCapture capture(cli.url);
  if (!capture.good()) {
    std::fprintf(stderr,
                 "evpipe-view: cannot open LCM on %s (for udpm://: is there a multicast route? see "
                 "docs/operations.md, \"Watching the pipeline\")\n",
                 url.c_str());
    return 1;
  }
  capture.keep_messages(false);
  capture.subscribe(".*");  // every channel: to say which exist when the preview channel stays silent

  std::deque<transport::PreviewRecord> queue;
  std::set<std::string> seen;
  std::size_t wrong_type = 0, invalid = 0;
  std::string last_problem;
  capture.on_message([&](const transport::ReceivedMessage& m) {
    if (m.channel != cli.channel) {
      seen.insert(m.channel);
      return;
    }
    try {
      auto r = transport::decode_preview(m.data.data(), m.data.size());
      if (!r) {
        if (wrong_type++ == 0) {
          last_problem = fmt::format(
              "a message on {} ({} bytes) is not an evpipe preview_t (its LCM fingerprint differs): is {} the preview "
              "channel? evpipe publishes previews with --preview on lcm.preview_channel (default EVPIPE_PREVIEW)",
              m.channel, m.data.size(), m.channel);
          std::fprintf(stderr, "evpipe-view: %s\n", last_problem.c_str());
        }
        return;
      }
      queue.push_back(std::move(*r));
      while (queue.size() > kKeepFrames) queue.pop_front();
    } catch (const transport::DecodeError& e) {
      if (invalid++ == 0) {
        last_problem = fmt::format("an invalid preview on {}: {}", m.channel, e.what());
        std::fprintf(stderr, "evpipe-view: %s\n", last_problem.c_str());
      }
    }
  });

  if (want_window) {
    try {
      cv::namedWindow(kWindow, cv::WINDOW_AUTOSIZE);
    } catch (const cv::Exception& e) {
      std::fprintf(stderr, "evpipe-view: cannot open a window: %s\n", e.what());
      return 2;
    }
  }
  std::optional<view::VideoOut> video;
  if (!cli.video.empty()) video.emplace(cli.video, cli.video_fps);

  view::RenderOptions ro;
  ro.zoom = cli.zoom;
  std::optional<transport::PreviewRecord> current;
  cv::Mat shown = view::render_message({346 * cli.zoom, 260 * cli.zoom + view::status_band_height(ro)},
                                       fmt::format("waiting for previews on {} at {}", cli.channel, url));
  std::size_t frames = 0;
  bool paused = false, step = false, redraw = true;
  const bool bounded = cli.frames > 0;
  // Bounded runs (tests, scripts) give up after 10 s by default; a person watching waits.
  const double timeout_s = cli.timeout_s >= 0 ? cli.timeout_s : (bounded ? 10.0 : 0.0);
  const auto start = std::chrono::steady_clock::now();
  auto last_frame = start;
  int status = 0;
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);

  while (!g_stop) {
    capture.drain(std::chrono::milliseconds(want_window ? 5 : 20));
    while (!queue.empty() && (!paused || step)) {
      current = std::move(queue.front());
      queue.pop_front();
      ++frames;
      last_frame = std::chrono::steady_clock::now();
      redraw = true;
      if (video) video->write(view::render_preview(*current, ro));
      if (step || (bounded && frames >= cli.frames)) break;
    }
    step = false;
    const auto now = std::chrono::steady_clock::now();
    if (redraw) {
      ro.paused = paused;
      if (current) {
        shown = view::render_preview(*current, ro);
      } else {
        shown =
            view::render_message(shown.size(), fmt::format("waiting for previews on {} at {}", cli.channel, url),
                                 last_problem.empty() ? fmt::format("channels seen: {}", join(seen)) : last_problem);
      }
      redraw = false;
    }
    if (bounded && frames >= cli.frames) break;
    const double waited = std::chrono::duration<double>(now - (frames ? last_frame : start)).count();
    if (timeout_s > 0 && waited > timeout_s && !paused) {
      if (frames == 0) {
        if (!last_problem.empty()) {
          std::fprintf(stderr, "evpipe-view: no valid preview within %.0f s: %s\n", timeout_s, last_problem.c_str());
        } else {
          std::fprintf(stderr,
                       "evpipe-view: no message on %s at %s within %.0f s (channels seen: %s). Is evpipe running with "
                       "--preview, is the channel name right (lcm.preview_channel), and does the network carry the "
                       "multicast (TTL, route)?\n",
                       cli.channel.c_str(), url.c_str(), timeout_s, join(seen).c_str());
        }
      } else {
        std::fprintf(stderr, "evpipe-view: previews stopped: %zu of %zu received, none for %.0f s\n", frames,
                     cli.frames, timeout_s);
      }
      status = 1;
      break;
    }
    if (!want_window) {
      if (seen.size() > 1000) seen.clear();
      continue;
    }
    cv::imshow(kWindow, shown);
    const int key = cv::waitKey(1) & 0xFF;
    if (key == 'q' || key == 27) break;
    if (key == ' ') {
      paused = !paused;
      redraw = true;
    } else if (key == 'n') {
      step = true;
    } else if (key == 'r') {
      ro.show_raw = !ro.show_raw;
      redraw = true;
    } else if (key == 'k') {
      ro.show_kept = !ro.show_kept;
      redraw = true;
    } else if (key == 's' && current) {
      const auto path = std::filesystem::path(cli.png_dir) / fmt::format("evpipe-view-{}.png", current->seq);
      if (cv::imwrite(path.string(), shown)) {
        std::fprintf(stderr, "evpipe-view: saved %s\n", path.string().c_str());
      } else {
        std::fprintf(stderr, "evpipe-view: cannot write %s\n", path.string().c_str());
      }
    }
  }
  if (!cli.screenshot.empty() && status == 0) {
    if (!current) {
      std::fprintf(stderr, "evpipe-view: no preview received: no screenshot written\n");
      status = 1;
    } else if (!cv::imwrite(cli.screenshot, shown)) {
      std::fprintf(stderr, "evpipe-view: cannot write the screenshot %s\n", cli.screenshot.c_str());
      status = 1;
    } else {
      std::fprintf(stderr, "evpipe-view: %zu preview(s); screenshot %s\n", frames, cli.screenshot.c_str());
    }
  }
  if (video) {
    video->close();
    std::fprintf(stderr, "evpipe-view: video: %lld frames written to %s\n", static_cast<long long>(video->frames()),
                 video->path().c_str());
  }
  if (want_window) cv::destroyAllWindows();
  return status;
}

}  // namespace

int main(int argc, char** argv) {
  Cli cli;
  evpipe::cli::App app{"evpipe-view: watch evpipe's preview (evpipe --preview) live from any LCM URL"};
  app.add_option("--lcm-url,--url", cli.url,
                 "LCM URL (default: $LCM_DEFAULT_URL, else udpm://239.255.76.67:7667?ttl=0)");
  app.add_option("--channel", cli.channel, "Preview channel (evpipe's lcm.preview_channel)")->capture_default_str();
  app.add_option("--zoom", cli.zoom, "Screen pixels per sensor pixel")
      ->check(evpipe::cli::range(1, 8))
      ->capture_default_str();
  app.add_option("--screenshot", cli.screenshot, "Save the last shown picture to this PNG at the end");
  app.add_option("--frames", cli.frames, "Stop after this many previews (0 = run until q / Ctrl-C)");
  app.add_option("--timeout", cli.timeout_s,
                 "Give up when no preview came for this many seconds (default: 10 with --frames, else wait)");
  app.add_option("--video", cli.video, "Write every preview received to this video (.mp4 or .avi)");
  app.add_option("--video-fps", cli.video_fps, "Frame rate of --video (default: 10, the preview rate)")
      ->check(evpipe::cli::positive_number());
  app.add_option("--png-dir", cli.png_dir, "Folder for the PNGs the s key saves (default: .)");
  app.add_flag("--headless", cli.headless, "No window (with --screenshot or --video)");
  if (const auto status = app.parse(argc, argv)) return *status;
  if (cli.screenshot.empty() && cli.frames == 0 && cli.headless && cli.video.empty()) {
    std::fprintf(stderr, "evpipe-view: --headless needs --screenshot or --video\n");
    return 2;
  }
  try {
    return run(cli);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "evpipe-view: %s\n", e.what());
    return 1;
  }
}
