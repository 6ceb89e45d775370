#pragma once
// The evpipe processing graph: four stages, run either with one thread per stage joined by named SPSC queues
// (start/join: the product) or all on the calling thread, in order (run_sequential: deterministic, for tests and
// batch evaluation). The stage objects are the same in both; only their outlets differ (runtime::Outlet).
// docs/architecture.md, "Threads and queues":
//
//   source ──[batches]──▶ denoise + windows ──[windows]──▶ pose ──[poses]──▶ publish
//   EventSource::next()   FilteredStream + TimeSlicer      WindowProcessor    PoseSink (+ stats every second)
//                         (+ denoise_threads − 1 TaskPool workers for one block's row bands)
//
// Policies: replay is lossless (every queue blocks its producer, the reader waits); live never blocks the reader
// (batches: drop_newest, windows: latest_wins, poses: drop_newest), every drop is counted.
//
//   stages::Pipeline p(std::move(source), std::move(filter), processor, sink, options);
//   p.start();
//   ... p.request_stop();       // from a signal handler (lock-free), or p.stop() from a thread
//   p.join();                   // threads end in pipeline order
//   if (p.error()) ...          // a stage threw: the pipeline stopped, the reason is here
//
// Shutdown order: stop flag -> the source stops reading and closes its queue -> each stage drains its input, flushes
// and closes its output -> threads are joined in order. A drain that is not done `drain_timeout` after the stop
// request is cut short (remaining items dropped and counted), so a stop always ends within about that time plus one
// step. The end of a replayed file drains everything (no deadline): every window is processed.

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "evpipe/core/slicer.hpp"
#include "evpipe/core/source.hpp"
#include "evpipe/core/stream_stats.hpp"
#include "evpipe/denoise/filter.hpp"
#include "evpipe/pose/estimator.hpp"
#include "evpipe/runtime/histogram.hpp"
#include "evpipe/runtime/queue.hpp"
#include "evpipe/runtime/stage.hpp"

namespace evpipe::stages {

using runtime::Clock;
using runtime::HistogramSummary;
using runtime::QueueStats;
using runtime::StageStats;

/// The pose stage's work, behind an interface so that the pipeline does not depend on how poses are estimated.
/// Called from the pose thread only.
class WindowProcessor {
 public:
  WindowProcessor() = default;
  virtual ~WindowProcessor() = default;
  WindowProcessor(const WindowProcessor&) = delete;
  WindowProcessor& operator=(const WindowProcessor&) = delete;

  /// One window of denoised events [t0_us, t1_us). May throw: the pipeline stops with the error.
  virtual pose::PoseEstimate process(const EventWindow& window) = 0;
};

/// One estimate with the times that make its latency.
struct PoseSample {
  pose::PoseEstimate estimate;
  std::uint64_t window_index = 0;  ///< windows emitted before this one (gaps = windows dropped in live mode)
  std::int64_t window_t0_us = 0;
  std::int64_t window_t1_us = 0;  ///< window end, sensor time
  std::size_t window_events = 0;
  bool starts_segment = false;            ///< first window after a clock discontinuity (or of the stream)
  Clock::time_point newest_event_read{};  ///< host time the source read the batch holding the window's newest event
  Clock::time_point window_ready{};       ///< host time the window was complete (emitted by the slicer)
  Clock::time_point pose_done{};          ///< host time the processor returned
};

enum class SourceState : std::uint8_t {
  starting,  ///< not started yet
  running,   ///< reading (live: camera connected)
  lost,      ///< live camera disconnected; the source retries (publish status LOST)
  ended,     ///< end of the recording / device closed for good
  stopped,   ///< stopped on request
  failed,    ///< next() threw (see PipelineStats::error)
};
[[nodiscard]] std::string_view state_name(SourceState state) noexcept;

struct SourceHealth {
  SourceState state = SourceState::starting;
  std::uint64_t lost_count = 0;  ///< times the camera was lost
  std::uint64_t reconnects = 0;  ///< times it came back
  SourceStats counters;          ///< the source's own counters (copied on the source thread)
  std::optional<double> progress;
};

/// Everything the statistics message needs; PoseSink::publish_stats gets one at least every stats_period.
struct PipelineStats {
  double elapsed_s = 0.0;  ///< since start()
  SourceHealth source;
  std::vector<StageStats> stages;   ///< source, denoise, pose, publish
  std::vector<QueueStats> queues;   ///< batches, windows, poses
  std::int64_t stream_time_us = 0;  ///< sensor time from the first to the newest event read
  std::uint64_t windows = 0;        ///< windows emitted by the slicer
  std::uint64_t denoise_events_in = 0;
  std::uint64_t denoise_events_kept = 0;
  /// The filter's own figures (denoise::Filter::report(); curvature: noise_rate_hz, density_threshold_used, ...),
  /// copied by the denoise thread every 500 ms and at its end; empty without a filter.
  std::vector<denoise::ReportItem> denoise_report;
  std::uint64_t poses_published = 0;
  /// Newest event of a window read -> publish_pose() returned (includes the wait for the window to complete and
  /// the denoiser's look-ahead).
  HistogramSummary latency_event_to_publish_ns;
  /// Window complete (emitted) -> publish_pose() returned: the processing latency of the pose and publish stages.
  HistogramSummary latency_window_to_publish_ns;
  bool running = false;  ///< some thread is still running
  std::string error;     ///< first stage error ("stage: what"), empty if none
};

/// Where poses and statistics go (LCM in the application, a recorder in tests). Called from the publish thread
/// only, so implementations need no locking.
class PoseSink {
 public:
  PoseSink() = default;
  virtual ~PoseSink() = default;
  PoseSink(const PoseSink&) = delete;
  PoseSink& operator=(const PoseSink&) = delete;

  virtual void publish_pose(const PoseSample& sample) = 0;
  /// At least every PipelineOptions::stats_period while running, and once more at the end.
  virtual void publish_stats(const PipelineStats& stats) = 0;
};

enum class Mode : std::uint8_t { replay, live };

struct PipelineOptions {
  Mode mode = Mode::replay;
  std::int64_t window_us = 30'000;  ///< window length (config window.length_us)
  std::int64_t hop_us = 30'000;     ///< hop between window starts (config window.hop_us)
  /// Empty windows (the filter kept nothing) are cut up to this long after the newest kept event, on the time the
  /// filter has decided (config window.max_empty_span_us; 0 = only windows holding events).
  std::int64_t max_empty_span_us = 0;
  std::size_t batch_queue_capacity = 64;  ///< source -> denoise (libcaer's default ring size)
  /// source -> denoise: also at most this many events queued (0 = no bound). A live packet's size follows the
  /// event rate, so the packet count alone does not bound the queue's memory (NamedQueue::set_weight_budget).
  std::size_t batch_queue_events = 0;
  std::size_t window_queue_capacity = 4;  ///< denoise -> pose in replay (live: latest_wins, one window)
  std::size_t pose_queue_capacity = 16;   ///< pose -> publish
  std::chrono::milliseconds stats_period{1000};
  /// Longest sleep of an idle stage before it re-checks cancellation and timers.
  std::chrono::milliseconds idle_wait{20};
  /// Live: pause after next() returned nothing (DavisSource never blocks; libcaer containers come every 5 ms).
  std::chrono::microseconds source_poll{1000};
  /// After a stop request, stages drain their queues for at most this long; then what is left is dropped.
  std::chrono::milliseconds drain_timeout{800};
  /// Threads the denoise stage spreads the filter's work over (its own thread + denoise_threads − 1 pool workers,
  /// denoise::Filter::set_parallelism); 1 = the stage's thread only. Decisions do not depend on it.
  int denoise_threads = 1;
};

class Pipeline {
 public:
  /// `filter` may be null (no denoising). `processor` and `sink` must outlive the pipeline. Throws
  /// std::invalid_argument for bad options (window/hop <= 0, zero capacities).
  Pipeline(std::unique_ptr<EventSource> source, std::unique_ptr<denoise::Filter> filter, WindowProcessor& processor,
           PoseSink& sink, PipelineOptions options = {});
  /// Stops at once (no drain) and joins.
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  /// Starts the four threads (once; not after run_sequential()).
  void start();
  /// Asks for the shutdown described above. Only atomic stores: safe from a signal handler; sleeping threads
  /// notice within idle_wait.
  void request_stop() noexcept;
  /// request_stop() and wakes the threads at once.
  void stop();
  /// True once every thread has ended (end of file, stop, or error), waiting at most `timeout`.
  bool wait_for(std::chrono::nanoseconds timeout);
  /// Waits for the end and joins the threads in pipeline order.
  void join();
  /// start() + join(); returns error().
  std::optional<std::string> run();
  /// Instead of start(): runs the same stages on the calling thread until the source ends, a stage throws or
  /// request_stop(): each batch goes through denoise, each window it completes through pose and publish at once
  /// (no queue, nothing dropped, whatever the mode); statistics after a pose at most every stats_period (as the
  /// publish thread's tick) and once at the end. The poses are those of a replay through start()/join(),
  /// deterministically unless the processor itself runs threads (PoseProcessor's init_worker). A step's time in the
  /// stage statistics includes the steps after it (nested). Returns error().
  std::optional<std::string> run_sequential();

  /// Any thread, any time.
  [[nodiscard]] PipelineStats stats() const;
  /// The first stage error ("stage: what"), if any.
  [[nodiscard]] std::optional<std::string> error() const;
  [[nodiscard]] const PipelineOptions& options() const noexcept;
  [[nodiscard]] const SourceInfo& source_info() const noexcept;
  /// Rates, time span and ON share of everything the source delivered. Only after join().
  [[nodiscard]] const StreamStats& stream_stats() const noexcept;
  /// The source's own counters. Only after join().
  [[nodiscard]] const SourceStats& source_stats() const noexcept;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

}  // namespace evpipe::stages
