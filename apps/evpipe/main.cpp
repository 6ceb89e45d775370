// evpipe: DAVIS346 event stream → denoise → (pose → LCM, in later stages). This version replays a recording
// or reads the live camera, denoises it with the configured filter (the paper's curvature filter by default),
// cuts the kept events into windows and prints a summary.
//
// Exit status: 0 success (also after SIGINT/SIGTERM), 1 runtime error (bad file, device), 2 usage or
// configuration error.

#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <CLI/CLI.hpp>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <thread>
#include <vector>

#include "evpipe/config/run_config.hpp"
#include "evpipe/core/error.hpp"
#include "evpipe/core/slicer.hpp"
#include "evpipe/core/stream_stats.hpp"
#include "evpipe/denoise/filtered_stream.hpp"
#include "evpipe/denoise/registry.hpp"
#include "evpipe/io/reader.hpp"
#include "evpipe/pipeline/paced_source.hpp"
#include "live.hpp"
#include "pose_stage.hpp"
#include "progress.hpp"
#include "summary.hpp"

namespace {

std::atomic<bool> g_stop{false};
// The paced replay source, so that a signal also ends its sleep (a silent stretch of a recording could
// otherwise keep it asleep for as long as the silence lasts). Lock-free atomic stores are signal-safe.
std::atomic<evpipe::pipeline::PacedSource*> g_paced{nullptr};
extern "C" void on_signal(int /*sig*/) {
  g_stop.store(true);
  if (auto* p = g_paced.load()) p->stop();
}

struct Cli {
  std::string config_path;
  std::string replay;
  std::string speed;
  std::string camera, model, prior, poses_out;
  std::string log_level;
  std::string denoise;
  bool json = false;
  bool no_progress = false;
  bool print_config = false;
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
    if (!cli.log_level.empty()) cfg.log.level = cli.log_level;
    if (!cli.denoise.empty()) cfg.denoise.filter = cli.denoise;
    cfg.validate();
  } catch (const config::ConfigError& e) {
    std::fprintf(stderr, "evpipe: configuration error: %s\n", e.what());
    return 2;
  }
  spdlog::set_level(spdlog::level::from_str(cfg.log.level));
  if (cli.print_config) {
    std::cout << cfg.to_yaml() << "\n";
    return 0;
  }
  spdlog::debug("effective configuration:\n{}", cfg.to_yaml());
  // The pose stage runs when a camera and a model are configured; a prior, an output CSV or ground truth
  // without them is a configuration error (create() says which is missing).
  std::unique_ptr<app::PoseStage> pose_stage;
  const auto& pc = cfg.pose;
  if (!pc.camera.empty() || !pc.model.empty() || !pc.prior.empty() || !pc.poses_out.empty() ||
      !pc.ground_truth.empty()) {
    try {
      pose_stage = app::PoseStage::create(cfg);
    } catch (const config::ConfigError& e) {
      std::fprintf(stderr, "evpipe: configuration error: %s\n", e.what());
      return 2;
    }
  }

  std::unique_ptr<EventSource> source;
  pipeline::PacedSource* paced = nullptr;
  try {
    if (!cfg.source.replay.empty()) {
      auto reader = io::open_reader(cfg.source.replay, reader_options(cfg.source));
      if (cfg.source.speed) {
        auto p = std::make_unique<pipeline::PacedSource>(std::move(reader), *cfg.source.speed);
        paced = p.get();
        source = std::move(p);
      } else {
        source = std::move(reader);
      }
    } else {
      source = app::open_live_source(cfg.device);
    }
  } catch (const SourceError& e) {
    std::fprintf(stderr, "evpipe: %s\n", e.what());
    return 1;
  }
  // Built once the source knows the sensor size; parameter errors are configuration errors.
  std::unique_ptr<denoise::Filter> filter;
  if (cfg.denoise.filter != "none") {
    try {
      filter = denoise::make_filter_chain(cfg.denoise.filter, cfg.denoise.params, source->info().geometry);
    } catch (const std::invalid_argument& e) {
      std::fprintf(stderr, "evpipe: configuration error: denoise: %s\n", e.what());
      return 2;
    }
  }
  const bool live = cfg.source.replay.empty();
  spdlog::info("{} {} ({}, {}x{})", live ? "reading" : "replaying", source->info().name, source->info().format,
               source->info().geometry.width, source->info().geometry.height);

  g_paced.store(paced);
  std::signal(SIGINT, on_signal);
  std::signal(SIGTERM, on_signal);

  StreamStats stream;
  app::RunSummary summary;
  summary.stream = &stream;
  summary.window_us = cfg.window.length_us;
  summary.hop_us = cfg.window.hop_us;
  summary.out_of_order_dropped = cfg.source.drop_out_of_order;
  summary.denoise_filter = filter ? std::string(filter->name()) : "none";
  summary.denoise_latency_us = filter ? filter->latency_us() : 0;
  // Denoise, then windows of the configured length and hop over the kept events (the pose stage plugs in here).
  std::optional<denoise::FilteredStream> denoised;
  if (filter) denoised.emplace(*filter);
  std::vector<EventBatch> kept;
  TimeSlicer slicer({cfg.window.length_us, cfg.window.hop_us, std::nullopt}, [&](const EventWindow& w) {
    ++summary.windows;
    summary.window_events += w.size();
    if (pose_stage) pose_stage->write(pose_stage->process(w));
  });
  app::ProgressBar progress(!cli.no_progress);
  const auto t_start = std::chrono::steady_clock::now();
  int status = 0;
  try {
    while (!g_stop.load()) {
      auto batch = source->next();
      if (!batch) {
        if (source->finished()) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(1));  // live: nothing new yet
        continue;
      }
      stream.add(batch->span());
      if (denoised) {
        kept.clear();
        denoised->push(batch, kept);
        for (auto& b : kept) slicer.accept(std::make_shared<const EventBatch>(std::move(b)));
      } else {
        slicer.accept(batch);
      }
      progress.update(source->progress(), stream.events(), stream.duration_us());
    }
    if (denoised) {
      kept.clear();
      denoised->finish(kept);
      for (auto& b : kept) slicer.accept(std::make_shared<const EventBatch>(std::move(b)));
    }
    slicer.flush();
  } catch (const SourceError& e) {
    progress.finish();
    summary.error = e.what();
    spdlog::error("{}", e.what());
    status = 1;
  }
  progress.finish();
  summary.interrupted = g_stop.load();
  summary.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  summary.info = source->info();
  summary.source = source->stats();
  if (pose_stage) summary.pose = pose_stage->summary();
  if (denoised) {
    summary.denoise_in = denoised->events_in();
    summary.denoise_kept = denoised->events_kept();
  }
  std::cout << (cli.json ? app::format_json(summary) : app::format_text(summary)) << std::flush;
  if (status != 0) std::fprintf(stderr, "evpipe: %s\n", summary.error.c_str());
  return status;
}

}  // namespace

int main(int argc, char** argv) {
  auto logger = spdlog::stderr_color_mt("evpipe");
  spdlog::set_default_logger(logger);
  spdlog::set_pattern("[%Y-%m-%d %H:%M:%S.%e] [%^%l%$] %v");

  Cli cli;
  CLI::App app{"evpipe: DAVIS346 event-camera pipeline (replay a recording, or read the camera over USB)"};
  app.set_version_flag("--version", "evpipe 0.1.0");
  app.add_option("--replay", cli.replay, "Replay a recording (AEDAT 2.0/3.1/4.0 or text) instead of the camera");
  app.add_option("--config", cli.config_path, "Run configuration (YAML); command-line options override it")
      ->check(CLI::ExistingFile);
  app.add_option("--speed", cli.speed, "Replay pace: 1 = real time (default), 2 = twice as fast, max = unpaced");
  app.add_option("--camera", cli.camera, "Camera calibration YAML (pose stage)");
  app.add_option("--model", cli.model, "Line model of the target, YAML or DXF (pose stage)");
  app.add_option("--prior", cli.prior, "Initial pose prior YAML (pose stage)");
  app.add_option("--poses-out", cli.poses_out, "Write every published pose to this trajectory CSV");
  app.add_option("--denoise", cli.denoise,
                 "Denoising filter or chain (evdenoise --list-filters), or none; overrides denoise.filter");
  app.add_option("--log-level", cli.log_level, "trace, debug, info, warn, error, critical or off");
  app.add_flag("--json", cli.json, "Print the summary as one JSON object");
  app.add_flag("--no-progress", cli.no_progress, "No progress bar even on a terminal");
  app.add_flag("--print-config", cli.print_config, "Print the effective configuration as YAML and exit");
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  return run(cli);
}
