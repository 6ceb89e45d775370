// evpipe: DAVIS346 event stream (live over USB, or a replayed recording) → denoise (`significance` by default; the
// paper's curvature filter on request) → 30 ms sliding windows → pose (OPnL initialisation, MM tracking) → LCM, one
// thread per stage (libs/stages on libs/runtime, docs/architecture.md); sd_notify READY/STATUS/WATCHDOG under systemd;
// a summary at the end.
//
// Exit status: 0 success (also after SIGINT/SIGTERM/SIGHUP), 1 runtime error (bad file, device, an LCM log of which
// nothing could be written), 2 usage or configuration error (also an output that is one of the inputs, an invalid
// LCM URL).
//
// Signals (docs/operations.md, "Signals"): TERM, INT and HUP stop the run (drain, summary, exit 0); PIPE is ignored
// (a closed stdout is a write error, reported on stderr); USR1 logs the status line. The poses CSV and the LCM log
// are written whole row by row, so a kill loses no row already published.

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <thread>
#include <vector>

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/error.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/trajectory.hpp"
#include "evpipe/cli/cli.hpp"
#include "evpipe/config/run_config.hpp"
#include "evpipe/core/error.hpp"
#include "evpipe/core/file.hpp"
#include "evpipe/denoise/registry.hpp"
#include "evpipe/io/reader.hpp"
#include "evpipe/metrics/trajectory.hpp"
#include "evpipe/runtime/paced_source.hpp"
#include "evpipe/service/logging.hpp"
#include "evpipe/service/notify.hpp"
#include "evpipe/service/supervisor.hpp"
#include "evpipe/stages/lcm_sink.hpp"
#include "evpipe/stages/pipeline.hpp"
#include "evpipe/stages/pose_processor.hpp"
#include "evpipe/transport/lcm_publisher.hpp"
#include "evpipe/transport/lcm_url.hpp"
#include "live.hpp"
#include "preview.hpp"
#include "progress.hpp"
#include "summary.hpp"

namespace {

std::atomic<bool> g_stop{false};
// The running pipeline: a signal asks it to drain and stop (request_stop() only stores atomics; it also ends a paced
// replay's sleep, which a silent stretch of a recording could otherwise make as long as the silence).
std::atomic<evpipe::stages::Pipeline*> g_pipeline{nullptr};
extern "C" void on_signal(int /*sig*/) {
  g_stop.store(true);
  if (auto* p = g_pipeline.load()) p->request_stop();
}
// SIGUSR1: the main loop logs the status line (a handler may not log).
std::atomic<bool> g_status_request{false};
extern "C" void on_usr1(int /*sig*/) {
  g_status_request.store(true);
}

// The pipeline's stages in StageStats order (docs/architecture.md).
constexpr std::array<std::string_view, 4> kStageNames = {"source", "denoise", "pose", "publish"};

struct Cli {
  std::string config_path;
  std::string replay;
  std::string speed;
  std::string camera, model, prior, poses_out;
  std::string log_level;
  std::string denoise;
  std::string ground_truth;
  std::optional<std::string> lcm_url;
  bool no_lcm = false;
  bool json = false;
  bool no_progress = false;
  bool print_config = false;
  // The operator's view (issue 22, preview.hpp)
  bool preview = false;
  std::optional<double> preview_hz;
  std::string video;
  double video_fps = 0;
  int png_every = 0;
  std::string png_dir = ".";
};

evpipe::io::ReaderOptions reader_options(const evpipe::config::SourceConfig& s) {
  evpipe::io::ReaderOptions o;
  o.batch_events = static_cast<std::size_t>(s.batch_events);
  o.out_of_order = s.drop_out_of_order ? evpipe::io::OutOfOrderPolicy::drop : evpipe::io::OutOfOrderPolicy::keep;
  o.discontinuity_us = s.discontinuity_us;
  o.aedat2_flip_y = s.aedat2_flip_y;
  o.aedat2_flip_x = s.aedat2_flip_x;
  o.default_geometry = {s.default_width, s.default_height};
  auto count = std::make_shared<std::uint64_t>(0);
  o.on_warning = [count](const evpipe::Warning& w) {
    // Rate-limited: the counts are in the summary anyway.
    if (++*count <= 20) spdlog::warn("{}", w.message());
    if (*count == 20) spdlog::warn("further reader warnings are counted in the summary, not logged");
  };
  return o;
}

// A file in `dir` named like a --png-every still (evpipe-NNNNNN.png) that is one of `files` (links followed), as
// "<still> is <file>"; nullopt when none (or `dir` does not exist yet).
std::optional<std::string> still_collision(const std::string& dir, const std::vector<std::string>& files) {
  namespace fs = std::filesystem;
  std::error_code ec;
  for (auto it = fs::directory_iterator(dir, ec); !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const std::string name = it->path().filename().string();
    constexpr std::string_view kPrefix = "evpipe-", kSuffix = ".png";
    if (name.size() < kPrefix.size() + 6 + kSuffix.size() || !name.starts_with(kPrefix) || !name.ends_with(kSuffix))
      continue;
    const std::string_view digits =
        std::string_view(name).substr(kPrefix.size(), name.size() - kPrefix.size() - kSuffix.size());
    if (!std::all_of(digits.begin(), digits.end(), [](char c) { return c >= '0' && c <= '9'; })) continue;
    for (const std::string& f : files) {
      std::error_code eq;
      if (!f.empty() && fs::equivalent(it->path(), f, eq)) return it->path().string() + " is " + f;
    }
  }
  return std::nullopt;
}

// Does cfg ask for initialisation on a worker thread (pose.init_worker, "auto" resolved)?
bool init_on_worker(const evpipe::config::RunConfig& cfg) {
  const std::string& w = cfg.pose.init_worker;
  if (w == "on") return true;
  if (w == "off") return false;
  return !(!cfg.source.replay.empty() && !cfg.source.speed);  // auto: not for a replay at --speed max
}

// The pose stage's options from the run configuration.
evpipe::stages::PoseProcessorOptions pose_options(const evpipe::config::RunConfig& cfg,
                                                  const std::vector<std::string>& inputs) {
  evpipe::stages::PoseProcessorOptions o;
  o.camera = cfg.pose.camera;
  o.model = cfg.pose.model;
  o.prior = cfg.pose.prior;
  o.poses_out = cfg.pose.poses_out;
  o.inputs = inputs;
  o.estimator.lost_after_windows = cfg.pose.lost_after_windows;
  o.estimator.filter.enabled = cfg.pose.fuse_windows;
  o.estimator.track.verification.leave_one_out = cfg.pose.require_redundancy;
  o.estimator.init.verification.leave_one_out = cfg.pose.require_redundancy;
  const std::string& da = cfg.pose.direct_alignment;
  o.estimator.init.direct_alignment = da == "auto"                 ? evpipe::pose::DirectAlignment::automatic
                                      : da == "on" || da == "true" ? evpipe::pose::DirectAlignment::on
                                                                   : evpipe::pose::DirectAlignment::off;
  o.estimator.filter.max_acceleration_m_s2 = cfg.pose.max_acceleration_m_s2;
  o.estimator.filter.max_angular_acceleration_deg_s2 = cfg.pose.max_angular_acceleration_deg_s2;
  o.estimator.track.window_us = cfg.window.length_us;  // the windows the pipeline cuts (and catch-up slices)
  o.estimator.track.step_us = cfg.window.hop_us;
  o.init_worker = init_on_worker(cfg);
  o.init_worker_nice = cfg.pose.init_worker_nice;
  return o;
}

// The summary's accuracy block: ATE of the valid poses against the ground truth (replay only).
void add_ate(evpipe::app::RunSummary& summary, const std::vector<evpipe::camera::StampedPose>& truth,
             const std::vector<evpipe::camera::StampedPose>& poses) {
  const auto eval = evpipe::metrics::evaluate_trajectory(poses, truth);
  summary.ate_poses = eval.poses_evaluated;
  if (eval.ate_mm) summary.ate_mm = *eval.ate_mm;
  if (eval.rotation_deg) summary.rotation_deg = *eval.rotation_deg;
  summary.ground_truth_given = true;
}

int run(const Cli& cli) {
  using namespace evpipe;
  config::RunConfig cfg;
  try {
    if (!cli.config_path.empty()) cfg = config::load_config(cli.config_path);
    if (!cli.replay.empty()) cfg.source.replay = cli.replay;
    if (!cli.speed.empty()) cfg.source.speed = config::parse_speed(cli.speed, "--speed");
    if (!cli.camera.empty()) cfg.pose.camera = cli.camera;
    if (!cli.model.empty()) cfg.pose.model = cli.model;
    if (!cli.prior.empty()) cfg.pose.prior = cli.prior;
    if (!cli.poses_out.empty()) cfg.pose.poses_out = cli.poses_out;
    if (!cli.ground_truth.empty()) cfg.pose.ground_truth = cli.ground_truth;
    if (!cli.log_level.empty()) cfg.log.level = cli.log_level;
    if (!cli.denoise.empty()) cfg.denoise.filter = cli.denoise;
    if (cli.lcm_url) cfg.lcm.url = *cli.lcm_url;
    if (cli.no_lcm) cfg.lcm.enabled = false;
    if (cli.preview) cfg.lcm.preview = true;
    if (cli.preview_hz) {
      cfg.lcm.preview = true;
      cfg.lcm.preview_hz = *cli.preview_hz;
    }
    cfg.validate();
    if (!cfg.pose.ground_truth.empty() && cfg.source.replay.empty())
      throw config::ConfigError("pose.ground_truth (--ground-truth): only for a replay (--replay)");
    // preview_t on the pose or statistics channel would reach the controller's subscription as another type.
    if (cfg.lcm.preview &&
        (cfg.lcm.preview_channel == cfg.lcm.pose_channel || cfg.lcm.preview_channel == cfg.lcm.stats_channel))
      throw config::ConfigError(
          fmt::format("lcm.preview_channel: '{}' is also the pose or statistics channel", cfg.lcm.preview_channel));
  } catch (const config::ConfigError& e) {
    std::fprintf(stderr, "evpipe: configuration error: %s\n", e.what());
    return 2;
  }
  spdlog::set_level(spdlog::level::from_str(cfg.log.level));
  app::set_libcaer_log_level(cfg.log.level);  // libcaer's own log follows --log-level / log.level
  // The program's input files: no output (poses CSV, LCM log) may be one of them (docs/operations.md, "Files").
  const std::vector<std::string> inputs = {cli.config_path, cfg.source.replay, cfg.pose.camera,
                                           cfg.pose.model,  cfg.pose.prior,    cfg.pose.ground_truth};
  if (cfg.lcm.enabled) {
    if (const auto why = transport::check_lcm_url(transport::effective_lcm_url(cfg.lcm.url), true)) {
      std::fprintf(stderr, "evpipe: configuration error: lcm.url (--lcm-url): %s\n", why->c_str());
      return 2;
    }
  }
  if (cli.print_config) {
    std::cout << cfg.to_yaml() << "\n";
    return 0;
  }
  spdlog::debug("effective configuration:\n{}", cfg.to_yaml());

  // The pose stage runs when a camera and a model are configured; a prior, an output CSV or ground truth
  // without them is a configuration error (create() says which is missing).
  std::unique_ptr<stages::PoseProcessor> pose_stage;
  std::vector<camera::StampedPose> truth;
  const auto& pc = cfg.pose;
  if (!pc.camera.empty() || !pc.model.empty() || !pc.prior.empty() || !pc.poses_out.empty() ||
      !pc.ground_truth.empty()) {
    try {
      pose_stage = stages::PoseProcessor::create(pose_options(cfg, inputs));
      if (!pc.ground_truth.empty()) {
        truth = camera::read_trajectory_csv(pc.ground_truth);
        if (truth.empty()) {
          throw std::invalid_argument(fmt::format(
              "pose.ground_truth: {}: no trajectory row (nothing to score the poses against)", pc.ground_truth));
        }
      }
    } catch (const std::invalid_argument& e) {
      std::fprintf(stderr, "evpipe: configuration error: %s\n", e.what());
      return 2;
    } catch (const camera::ModelError& e) {
      std::fprintf(stderr, "evpipe: configuration error: %s\n", e.what());
      return 2;
    }
  }

  const bool live = cfg.source.replay.empty();
  std::unique_ptr<EventSource> source;
  try {
    if (!live) {
      auto reader = io::open_reader(cfg.source.replay, reader_options(cfg.source));
      if (cfg.source.speed) {
        source = std::make_unique<runtime::PacedSource>(std::move(reader), *cfg.source.speed);
      } else {
        source = std::move(reader);
      }
    } else {
      source = app::open_live_source(cfg.device, cfg.log.level);
    }
  } catch (const SourceError& e) {
    std::fprintf(stderr, "evpipe: %s\n", e.what());
    return 1;
  }
  if (pose_stage && !pc.camera.empty()) {
    // Issue 17: a calibration of another size (640x480 on a 346x260 recording) gave wrong poses without a word. An
    // error when the recording or camera states its size; a warning when the reader assumed it.
    try {
      const auto cam = camera::load_camera(pc.camera);
      const auto& g = source->info().geometry;
      if (cam.width != g.width || cam.height != g.height) {
        const auto why = fmt::format("pose.camera: {}: the calibration is for a {}x{} sensor, the {} is {}x{}{}",
                                     pc.camera, cam.width, cam.height, live ? "camera" : "recording", g.width, g.height,
                                     source->info().geometry_known ? "" : " (assumed: source.default_width/height)");
        if (source->info().geometry_known) {
          std::fprintf(stderr, "evpipe: configuration error: %s\n", why.c_str());
          return 2;
        }
        spdlog::warn("{}", why);
      }
    } catch (const camera::ModelError& e) {
      std::fprintf(stderr, "evpipe: configuration error: %s\n", e.what());
      return 2;
    }
  }
  // The preview (LCM preview_t, --video, --png-every) sees the raw events through this wrapper (preview.hpp).
  bool preview_lcm = cfg.lcm.preview && cfg.lcm.enabled;
  if (cfg.lcm.preview && !cfg.lcm.enabled) spdlog::warn("LCM preview: off, because LCM is off (--no-lcm, lcm.enabled)");
  if (transport::LcmUrl u; preview_lcm &&
                           !transport::check_lcm_url(transport::effective_lcm_url(cfg.lcm.url), true, &u) &&
                           u.provider == "file") {
    // The publisher writes that log; a second writer would clobber it (and a log is no place for pictures).
    spdlog::warn("LCM preview: off, because lcm.url is an LCM log file (watch a live run over udpm instead)");
    preview_lcm = false;
  }
  if (!cli.video.empty()) {
    try {
      check_output_file(cli.video, inputs);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "evpipe: configuration error: --video: %s\n", e.what());
      return 2;
    }
  }
  const bool preview_on = preview_lcm || !cli.video.empty() || cli.png_every > 0;
  // Built once the source knows the sensor size; parameter errors are configuration errors.
  std::unique_ptr<denoise::Filter> filter;
  if (cfg.denoise.filter != "none") {
    try {
      const auto params = cfg.denoise.pipeline_params();
      filter = denoise::make_filter_chain(cfg.denoise.filter, params, source->info().geometry);
      std::string text;
      for (const auto& [k, v] : params) text += fmt::format("{}{}={}", text.empty() ? "" : " ", k, v);
      spdlog::info("denoise: {}{}{}", cfg.denoise.filter, text.empty() ? "" : " with ", text);
    } catch (const std::invalid_argument& e) {
      std::fprintf(stderr, "evpipe: configuration error: denoise: %s\n", e.what());
      return 2;
    }
  }
  spdlog::info("{} {} ({}, {}x{})", live ? "reading" : "replaying", source->info().name, source->info().format,
               source->info().geometry.width, source->info().geometry.height);

  // LCM: a missing multicast route is a degraded, retried state, never a reason not to run (operations.md).
  std::unique_ptr<transport::LcmPublisher> publisher;
  if (cfg.lcm.enabled) {
    transport::LcmPublisherOptions lo;
    lo.url = cfg.lcm.url;
    lo.pose_channel = cfg.lcm.pose_channel;
    lo.stats_channel = cfg.lcm.stats_channel;
    lo.inputs = inputs;
    lo.inputs.push_back(cfg.pose.poses_out);
    publisher = std::make_unique<transport::LcmPublisher>(lo);
    if (!publisher->can_recover()) {  // a log file that cannot be created: nothing to retry
      std::fprintf(stderr, "evpipe: configuration error: lcm.url (--lcm-url): %s\n", publisher->last_error().c_str());
      return 2;
    }
    spdlog::info("LCM: {} on {} (poses) and {} (statistics){}", transport::effective_lcm_url(cfg.lcm.url),
                 lo.pose_channel, lo.stats_channel,
                 publisher->state() == transport::PublisherState::degraded
                     ? " - not connected yet: " + publisher->last_error()
                     : "");
  }

  app::RunSummary summary;
  summary.window_us = cfg.window.length_us;
  summary.hop_us = cfg.window.hop_us;
  summary.out_of_order_dropped = cfg.source.drop_out_of_order;
  summary.denoise_filter = filter ? std::string(filter->name()) : "none";
  summary.denoise_latency_us = filter ? filter->latency_us() : 0;

  stages::PipelineOptions po;
  po.mode = live ? stages::Mode::live : stages::Mode::replay;
  po.window_us = cfg.window.length_us;
  po.hop_us = cfg.window.hop_us;
  po.max_empty_span_us = cfg.window.max_empty_span_us;
  po.batch_queue_capacity = static_cast<std::size_t>(cfg.pipeline.source_queue_packets);
  po.batch_queue_events = static_cast<std::size_t>(cfg.pipeline.source_queue_events);
  po.window_queue_capacity = static_cast<std::size_t>(cfg.pipeline.pose_queue_windows);
  po.pose_queue_capacity = static_cast<std::size_t>(cfg.pipeline.publish_queue);
  po.stats_period = std::chrono::milliseconds(cfg.lcm.stats_period_ms);
  po.denoise_threads = cfg.denoise.threads > 0
                           ? cfg.denoise.threads
                           : std::clamp(static_cast<int>(std::thread::hardware_concurrency()), 1, 4);
  spdlog::debug("denoise: {} thread(s)", po.denoise_threads);
  stages::LcmSink sink(publisher.get(), pose_stage.get(), live, !truth.empty());
  std::unique_ptr<app::PreviewWorker> preview;
  // The inputs and the outputs that exist now (the poses CSV, the LCM log): the video and the stills must not
  // overwrite any of them (a log that did not exist yet passed the first video check by name).
  std::vector<std::string> files = inputs;
  files.push_back(cfg.pose.poses_out);
  if (transport::LcmUrl u; publisher && publisher->writes_log() &&
                           !transport::check_lcm_url(transport::effective_lcm_url(cfg.lcm.url), true, &u))
    files.push_back(u.target);
  if (!cli.video.empty()) {
    try {
      check_output_file(cli.video, files);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "evpipe: configuration error: --video: %s\n", e.what());
      return 2;
    }
    files.push_back(cli.video);
  }
  if (cli.png_every > 0) {
    if (const auto clash = still_collision(cli.png_dir, files)) {
      std::fprintf(stderr, "evpipe: configuration error: --png-dir: %s: refusing to overwrite it\n", clash->c_str());
      return 2;
    }
  }
  if (preview_on) {
    app::PreviewOptions vo;
    vo.hz = cfg.lcm.preview_hz;
    vo.lcm = preview_lcm;
    vo.lcm_url = cfg.lcm.url;
    vo.lcm_channel = cfg.lcm.preview_channel;
    vo.video = cli.video;
    vo.video_fps = cli.video_fps;
    vo.png_every = cli.png_every;
    vo.png_dir = cli.png_dir;
    vo.protected_files = files;
    vo.lossless = !live && (!cli.video.empty() || cli.png_every > 0);  // a replay's video / stills: every window
    std::optional<camera::CameraModel> cam;
    std::optional<camera::LineModel> model;
    if (pose_stage) {  // loaded once more for the drawing (create() has checked them)
      cam = camera::load_camera(cfg.pose.camera);
      model = camera::load_line_model(cfg.pose.model);
    }
    try {
      preview = std::make_unique<app::PreviewWorker>(vo, source->info().geometry, cfg.window.hop_us, std::move(cam),
                                                     std::move(model), &sink);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "evpipe: preview: %s\n", e.what());
      return 1;
    }
    sink.set_observer(preview.get());
    if (pose_stage) pose_stage->set_observer(preview.get());
    if (preview_lcm) spdlog::info("LCM preview: {} Hz on {}", cfg.lcm.preview_hz, cfg.lcm.preview_channel);
  }
  stages::EventsOnlyProcessor no_pose(preview.get());
  stages::WindowProcessor& processor = pose_stage ? static_cast<stages::WindowProcessor&>(*pose_stage) : no_pose;
  stages::Pipeline pipe(std::move(source), std::move(filter), processor, sink, po);

  g_pipeline.store(&pipe);
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);
  std::signal(SIGHUP, on_signal);  // a closed terminal or session: stop cleanly like TERM
  std::signal(SIGUSR1, on_usr1);

  // systemd: READY once the threads run, STATUS= every second, WATCHDOG=1 only while every stage progresses.
  service::SupervisorOptions so;
  so.status = [&sink, &pose_stage]() {
    const auto st = sink.latest_stats();
    return st ? stages::status_line(*st, sink.latest_status(), pose_stage != nullptr) : std::string("starting");
  };
  service::Supervisor supervisor(so);
  for (std::size_t i = 0; i < 4; ++i) {
    supervisor.watch(std::string(kStageNames[i]), [&pipe, i]() {
      const auto st = pipe.stats();
      return service::HeartbeatSample{i < st.stages.size() ? st.stages[i].heartbeat : 0, false};
    });
  }

  app::ProgressBar progress(!cli.no_progress);
  const auto t_start = std::chrono::steady_clock::now();
  pipe.start();
  supervisor.start();
  service::ready(live ? "reading the camera" : "replaying " + cfg.source.replay);
  while (!pipe.wait_for(std::chrono::milliseconds(100))) {
    if (g_status_request.exchange(false)) {
      const auto st = sink.latest_stats();
      spdlog::info("status: {}", st ? stages::status_line(*st, sink.latest_status(), pose_stage != nullptr)
                                    : std::string("starting"));
    }
    if (progress.active()) {
      const auto st = pipe.stats();
      std::string extra =
          fmt::format("kept {:.1f} %", st.denoise_events_in ? 100.0 * static_cast<double>(st.denoise_events_kept) /
                                                                  static_cast<double>(st.denoise_events_in)
                                                            : 0.0);
      if (pose_stage) extra += fmt::format("  pose {}", pose::to_string(sink.latest_status()));
      progress.update(st.source.progress, st.source.counters.events, st.stream_time_us, extra);
    }
  }
  if (g_stop.load()) service::stopping();
  pipe.join();
  supervisor.stop();
  g_pipeline.store(nullptr);
  progress.finish();

  std::string preview_error;
  if (preview) {
    try {
      preview->finish();
    } catch (const std::exception& e) {
      preview_error = fmt::format("preview: {}", e.what());
    }
    const auto c = preview->counters();
    if (preview_lcm) {
      spdlog::info("LCM preview: {} published ({:.1f} kB each on average), {} dropped, {} failed", c.published,
                   c.published ? static_cast<double>(c.bytes) / static_cast<double>(c.published) / 1e3 : 0.0, c.dropped,
                   c.publish_failures);
    }
    if (!cli.video.empty())
      spdlog::info("video: {} frames of {}x{} ({}) written to {}", c.video_frames, c.video_width, c.video_height,
                   c.video_codec, c.video_path);
    if (cli.png_every > 0) spdlog::info("png: {} stills written to {}", c.pngs, cli.png_dir);
  }

  const auto stats = pipe.stats();
  summary.stream = &pipe.stream_stats();
  summary.interrupted = g_stop.load();
  summary.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  summary.info = pipe.source_info();
  summary.source = pipe.source_stats();
  summary.denoise_in = stats.denoise_events_in;
  summary.denoise_kept = stats.denoise_events_kept;
  for (const auto& item : stats.denoise_report) summary.denoise_report.emplace_back(item.key, item.value);
  summary.windows = stats.windows;
  for (const auto& s : stats.stages)
    if (s.name == "pose") summary.window_events = s.events_in;
  for (const auto& q : stats.queues) summary.queue_drops.emplace_back(q.name, q.dropped);
  summary.latency_event_ms_p50 = static_cast<double>(stats.latency_event_to_publish_ns.p50) / 1e6;
  summary.latency_event_ms_p99 = static_cast<double>(stats.latency_event_to_publish_ns.p99) / 1e6;
  summary.latency_window_ms_p50 = static_cast<double>(stats.latency_window_to_publish_ns.p50) / 1e6;
  summary.latency_window_ms_p99 = static_cast<double>(stats.latency_window_to_publish_ns.p99) / 1e6;
  summary.latency_window_ms_max = static_cast<double>(stats.latency_window_to_publish_ns.max) / 1e6;
  if (publisher) {
    const auto c = publisher->counters();
    summary.lcm_url = transport::effective_lcm_url(cfg.lcm.url);
    summary.lcm_poses = static_cast<std::uint64_t>(c.poses_published);
    summary.lcm_stats = static_cast<std::uint64_t>(c.stats_published);
    summary.lcm_failures = static_cast<std::uint64_t>(c.publish_failures);
    if (publisher->writes_log() && c.publish_failures > 0) {
      spdlog::warn("LCM log: {} of {} message(s) could not be written ({})", c.publish_failures,
                   c.publish_failures + c.poses_published + c.stats_published, publisher->last_error());
    }
  }
  if (pose_stage) summary.pose = pose_stage->summary();
  if (!truth.empty()) add_ate(summary, truth, sink.valid_poses());
  int status = 0;
  if (const auto err = pipe.error()) {
    summary.error = *err;
    spdlog::error("{}", *err);
    status = 1;
  } else if (!preview_error.empty()) {
    summary.error = preview_error;
    spdlog::error("{}", preview_error);
    status = 1;
  }
  if (status == 0 && publisher && publisher->writes_log() && summary.lcm_failures > 0 && summary.lcm_poses == 0 &&
      summary.lcm_stats == 0) {
    summary.error = fmt::format("LCM log {}: nothing could be written: {}", summary.lcm_url, publisher->last_error());
    status = 1;
  }
  std::cout << (cli.json ? app::format_json(summary) : app::format_text(summary)) << std::flush;
  if (!std::cout) {  // SIGPIPE is ignored: a closed stdout (`evpipe --json | true`) is a write error, said here
    std::fprintf(stderr, "evpipe: could not write the summary to standard output (closed pipe?)\n");
  }
  if (status != 0) std::fprintf(stderr, "evpipe: %s\n", summary.error.c_str());
  return status;
}

}  // namespace

int main(int argc, char** argv) {
  std::signal(SIGPIPE, SIG_IGN);  // a closed stdout/stderr is a write error, not death with rows unwritten
  spdlog::set_default_logger(evpipe::service::make_logger("evpipe"));

  Cli cli;
  evpipe::cli::App app{"evpipe: DAVIS346 event-camera pipeline (replay a recording, or read the camera over USB)"};
  // "evpipe <version>" and the libcaer it was built with ("libcaer: 3.3.15" or "libcaer: stub: no camera support").
  app.set_version_flag("--version", std::string("evpipe " EVPIPE_VERSION "\n") + evpipe::app::libcaer_version_line());
  app.add_option("--replay", cli.replay, "Replay a recording (AEDAT 2.0/3.1/4.0 or text) instead of the camera");
  app.add_option("--config", cli.config_path, "Run configuration (YAML); command-line options override it")
      ->check(evpipe::cli::existing_file());
  app.add_option("--speed", cli.speed, "Replay pace: 1 = real time (default), 2 = twice as fast, max = unpaced");
  app.add_option("--camera", cli.camera, "Camera calibration YAML (pose stage)");
  app.add_option("--model", cli.model, "Line model of the target, YAML or DXF (pose stage)");
  app.add_option("--prior", cli.prior, "Initial pose prior YAML (pose stage)");
  app.add_option("--poses-out", cli.poses_out, "Write every published pose to this trajectory CSV");
  app.add_option("--denoise", cli.denoise,
                 "Denoising filter or chain (evdenoise --list-filters), or none; overrides denoise.filter");
  app.add_option("--ground-truth", cli.ground_truth,
                 "Replay: trajectory CSV of the true pose; the summary then reports the ATE");
  app.add_option("--lcm-url", cli.lcm_url, "LCM provider URL (overrides lcm.url; default: LCM's default)");
  app.add_flag("--no-lcm", cli.no_lcm, "Do not publish on LCM");
  app.add_option("--log-level", cli.log_level, "trace, debug, info, warn, error, critical or off");
  app.add_flag("--json", cli.json, "Print the summary as one JSON object");
  app.add_flag("--no-progress", cli.no_progress, "No progress bar even on a terminal");
  app.add_flag("--print-config", cli.print_config, "Print the effective configuration as YAML and exit");
  app.footer(fmt::format(
      "Limits (docs/operations.md): a sensor of at most {0}x{0} pixels; each denoise filter's per-pixel state at most "
      "{1} bytes per pixel ({2} MiB at that size); --speed in [{3}, {4}] or max; the ranges of every configuration "
      "key are in config/evpipe.yaml.",
      evpipe::kMaxSensorSide, evpipe::denoise::kMaxFilterBytesPerPixel, evpipe::denoise::kMaxFilterStateBytes >> 20,
      evpipe::config::kMinSpeed, evpipe::config::kMaxSpeed));
  app.add_flag("--preview", cli.preview, "Publish a preview for evpipe-view on EVPIPE_PREVIEW (lcm.preview)");
  app.add_option("--preview-hz", cli.preview_hz, "Previews per second (implies --preview; lcm.preview_hz, default 10)")
      ->check(evpipe::cli::range(0.1, 30.0));
  app.add_option("--video", cli.video,
                 "Write the preview of every window to this video (.mp4: MPEG-4 via FFmpeg; .avi: Motion JPEG)");
  app.add_option("--video-fps", cli.video_fps,
                 "Video frame rate in [0.1, 1000] (default: sensor time, 1 / window.hop_us)")
      ->check(evpipe::cli::range(0.1, 1000.0));
  app.add_option("--png-every", cli.png_every, "Write every Nth window's preview as PNG (to --png-dir)")
      ->check(evpipe::cli::positive_number());
  app.add_option("--png-dir", cli.png_dir, "Folder for --png-every stills (default: .)");
  if (const auto status = app.parse(argc, argv)) return *status;
  return run(cli);
}
