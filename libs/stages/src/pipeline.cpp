#include "evpipe/stages/pipeline.hpp"

#include <algorithm>
#include <condition_variable>
#include <deque>
#include <mutex>
#include <stdexcept>
#include <thread>

#include "evpipe/denoise/filtered_stream.hpp"
#include "evpipe/runtime/task_pool.hpp"

namespace evpipe::stages {

using runtime::CancelDeadline;
using runtime::Histogram;
using runtime::InlineOutlet;
using runtime::NamedQueue;
using runtime::Outlet;
using runtime::PushResult;
using runtime::QueueOutlet;
using runtime::QueuePolicy;
using runtime::Stage;
using runtime::StageFailure;
using runtime::StageMetrics;
using runtime::StageRunner;
using runtime::StageState;
using runtime::TaskPool;

std::string_view state_name(SourceState state) noexcept {
  switch (state) {
    case SourceState::starting:
      return "starting";
    case SourceState::running:
      return "running";
    case SourceState::lost:
      return "lost";
    case SourceState::ended:
      return "ended";
    case SourceState::stopped:
      return "stopped";
    case SourceState::failed:
      return "failed";
  }
  return "?";
}

namespace {

using runtime::detail::bump;

/// What the denoise thread hands on.
struct WindowItem {
  EventWindow window;
  std::uint64_t index = 0;
  Clock::time_point newest_event_read{};
  Clock::time_point ready{};
};

std::uint64_t to_ns(Clock::duration d) {
  return static_cast<std::uint64_t>(
      std::max<std::int64_t>(0, std::chrono::duration_cast<std::chrono::nanoseconds>(d).count()));
}

/// Denoises each batch and cuts the kept events into windows. The read time of each window's newest event comes
/// with its batch (EventBatch::read_at, carried through the filter).
class DenoiseStage final : public Stage<EventBatchPtr> {
 public:
  DenoiseStage(denoise::Filter* filter, const PipelineOptions& o, StageMetrics& m)
      : filter_(filter),
        m_(m),
        slicer_({o.window_us, o.hop_us, std::nullopt, o.max_empty_span_us},
                [this](EventWindow&& w) { emit(std::move(w)); }),
        window_us_(o.window_us),
        hop_us_(o.hop_us) {
    if (filter) stream_.emplace(*filter);
  }

  void connect(Outlet<WindowItem>& out) noexcept { out_ = &out; }

  void step(EventBatchPtr&& batch) override {
    bump(m_.events_in, batch->size());
    input_read_at_ = batch->read_at;
    // FilteredStream flags its next kept batch after a discontinuity within the stream (not before the first event).
    if (batch->discontinuity_before && stream_ && stream_->events_in() > 0) new_segment_pending_ = true;
    if (stream_) {
      // The unfiltered batches stay shared (not copied) until the windows over them are cut: each window carries its
      // raw events too (EventWindow::raw_parts; the hold's standstill test counts them). Times restart after a
      // discontinuity: the old segment's windows still to come get none.
      if (batch->discontinuity_before) raw_.clear();
      if (!batch->empty()) raw_.push_back(batch);
      kept_.clear();
      stream_->push(std::move(batch), kept_);
      for (auto& b : kept_) accept(std::make_shared<const EventBatch>(std::move(b)));
      // Time passes although nothing may have been kept (a still target): the windows it completes are cut (not
      // across a clock discontinuity whose first kept event has not reached the slicer yet).
      if (const auto until = stream_->decided_until_us(); until && !new_segment_pending_) slicer_.advance(*until);
      // A window still to be cut ends after the decided time (else it would have been), so it starts after that
      // minus its length: older raw batches are not needed (a still scene cuts no window for minutes).
      if (const auto until = stream_->decided_until_us()) {
        while (!raw_.empty() && raw_.front()->events.back().t_us < *until - window_us_) raw_.pop_front();
      }
      // The filter belongs to this thread: its figures are copied out for stats() now and then (a few short
      // strings twice a second), not read by the statistics thread.
      if (const auto now = Clock::now(); now - last_report_ >= kReportPeriod) {
        last_report_ = now;
        take_report();
      }
    } else {
      accept(std::move(batch));
    }
  }

  void finish() override {
    if (stream_) {
      kept_.clear();
      stream_->finish(kept_);
      for (auto& b : kept_) accept(std::make_shared<const EventBatch>(std::move(b)));
      if (const auto until = stream_->decided_until_us()) slicer_.advance(*until);
      take_report();
    }
    slicer_.flush();
  }

  [[nodiscard]] std::uint64_t windows() const noexcept { return windows_.load(std::memory_order_relaxed); }
  /// The filter's figures (denoise::Filter::report) as last copied: at most kReportPeriod old, final after finish().
  [[nodiscard]] std::vector<denoise::ReportItem> report() const {
    std::lock_guard lock(report_mu_);
    return report_;
  }

 private:
  void accept(EventBatchPtr b) {
    if (b->discontinuity_before) new_segment_pending_ = false;
    bump(m_.events_out, b->size());
    slicer_.accept(b);
  }

  /// The raw events of [w.t0_us, w.t1_us) into w; drops the raw batches no later window needs.
  void attach_raw(EventWindow& w) {
    const auto before = [](const Event& e, std::int64_t t) { return e.t_us < t; };
    for (const EventBatchPtr& b : raw_) {
      const EventSpan all = b->span();
      if (all.back().t_us < w.t0_us) continue;
      if (all.front().t_us >= w.t1_us) break;
      const auto lo = std::lower_bound(all.begin(), all.end(), w.t0_us, before);
      const auto hi = std::lower_bound(lo, all.end(), w.t1_us, before);
      if (lo == hi) continue;
      w.raw_parts.emplace_back(lo, hi);
      w.raw_owners.push_back(b);
    }
    while (!raw_.empty() && raw_.front()->events.back().t_us < w.t0_us + hop_us_) raw_.pop_front();
  }

  void emit(EventWindow&& w) {
    if (stream_) attach_raw(w);
    const auto now = Clock::now();
    // The newest event's batch; an empty window (nothing kept) was completed by time: the input batch being
    // processed when it was cut (with a look-ahead filter, later than the one that brought its end). A source that
    // does not stamp its batches: the window's completion.
    auto read_at = w.owners.empty() ? input_read_at_ : w.owners.back()->read_at;
    if (read_at == Clock::time_point{}) read_at = now;
    const std::size_t n = w.size();
    WindowItem item{std::move(w), index_, read_at, now};
    ++index_;
    bump(windows_);
    switch (out_->push(std::move(item))) {
      case PushResult::pushed:
      case PushResult::replaced:  // accepted; the queue counts the window it displaced
        bump(m_.items_out);
        break;
      case PushResult::dropped:
      case PushResult::stopped:
        bump(m_.items_dropped);
        bump(m_.events_dropped, n);
        break;
    }
  }

  void take_report() {
    auto r = filter_->report();
    std::lock_guard lock(report_mu_);
    report_ = std::move(r);
  }

  static constexpr std::chrono::milliseconds kReportPeriod{500};
  denoise::Filter* filter_;
  Outlet<WindowItem>* out_ = nullptr;
  StageMetrics& m_;
  std::optional<denoise::FilteredStream> stream_;
  Clock::time_point last_report_{};
  mutable std::mutex report_mu_;
  std::vector<denoise::ReportItem> report_;
  TimeSlicer slicer_;
  std::int64_t window_us_;
  std::int64_t hop_us_;
  std::deque<EventBatchPtr> raw_;  // the unfiltered batches the windows still to be cut may need
  std::vector<EventBatch> kept_;
  Clock::time_point input_read_at_{};
  bool new_segment_pending_ = false;
  std::uint64_t index_ = 0;
  std::atomic<std::uint64_t> windows_{0};
};

/// Runs the processor on each window and hands the estimate on with the window's times.
class PoseStage final : public Stage<WindowItem> {
 public:
  PoseStage(WindowProcessor& processor, StageMetrics& m) : processor_(processor), m_(m) {}

  void connect(Outlet<PoseSample>& out) noexcept { out_ = &out; }

  void step(WindowItem&& w) override {
    const std::size_t n = w.window.size();
    bump(m_.events_in, n);
    PoseSample s;
    s.estimate = processor_.process(w.window);
    s.pose_done = Clock::now();
    s.window_index = w.index;
    s.window_t0_us = w.window.t0_us;
    s.window_t1_us = w.window.t1_us;
    s.window_events = n;
    s.starts_segment = w.window.starts_segment;
    s.newest_event_read = w.newest_event_read;
    s.window_ready = w.ready;
    bump(m_.events_out, n);
    switch (out_->push(std::move(s))) {
      case PushResult::pushed:
      case PushResult::replaced:
        bump(m_.items_out);
        break;
      case PushResult::dropped:
      case PushResult::stopped:
        bump(m_.items_dropped);
        break;
    }
  }

 private:
  WindowProcessor& processor_;
  Outlet<PoseSample>* out_ = nullptr;
  StageMetrics& m_;
};

}  // namespace

struct Pipeline::Impl {
  Impl(std::unique_ptr<EventSource> src, std::unique_ptr<denoise::Filter> flt, WindowProcessor& processor,
       PoseSink& snk, PipelineOptions o)
      : options(validated(o)),
        source(std::move(src)),
        filter(std::move(flt)),
        sink(snk),
        batches("batches", options.batch_queue_capacity,
                options.mode == Mode::live ? QueuePolicy::drop_newest : QueuePolicy::block),
        windows_q("windows", options.mode == Mode::live ? 1 : options.window_queue_capacity,
                  options.mode == Mode::live ? QueuePolicy::latest_wins : QueuePolicy::block),
        poses("poses", options.pose_queue_capacity,
              options.mode == Mode::live ? QueuePolicy::drop_newest : QueuePolicy::block),
        m_source("source"),
        m_denoise("denoise"),
        m_pose("pose"),
        m_publish("publish"),
        denoise_stage(filter.get(), options, m_denoise),
        pose_stage(processor, m_pose),
        publish_stage(*this),
        to_batches(batches, &m_source.wait, options.idle_wait),
        to_windows(windows_q, &m_denoise.wait),
        to_poses(poses, &m_pose.wait) {
    if (!source) throw std::invalid_argument("Pipeline: source is null");
    batches.set_weight_budget(options.batch_queue_events,
                              [](const EventBatchPtr& b) -> std::uint64_t { return b ? b->size() : 0; });
    if (filter && options.denoise_threads > 1) {
      denoise_pool = std::make_unique<TaskPool>(options.denoise_threads - 1, "denoise-");
      filter->set_parallelism(options.denoise_threads, denoise_pool->runner());
    }
    source_snapshot.counters = source->stats();
    source_snapshot.progress = source->progress();
  }

  static PipelineOptions validated(PipelineOptions o) {
    if (o.window_us <= 0) throw std::invalid_argument("Pipeline: window_us must be > 0");
    if (o.hop_us <= 0) throw std::invalid_argument("Pipeline: hop_us must be > 0");
    if (o.batch_queue_capacity == 0 || o.window_queue_capacity == 0 || o.pose_queue_capacity == 0) {
      throw std::invalid_argument("Pipeline: queue capacities must be > 0");
    }
    if (o.idle_wait.count() <= 0) throw std::invalid_argument("Pipeline: idle_wait must be > 0");
    if (o.denoise_threads < 1 || o.denoise_threads > 64) {
      throw std::invalid_argument("Pipeline: denoise_threads must be in [1, 64]");
    }
    return o;
  }

  class PublishStage final : public Stage<PoseSample> {
   public:
    explicit PublishStage(Impl& impl) : impl_(impl) {}
    void step(PoseSample&& s) override {
      bump(impl_.m_publish.events_in, s.window_events);
      impl_.sink.publish_pose(s);
      const auto now = Clock::now();  // publication = publish_pose() returned
      impl_.latency_event.record(to_ns(now - s.newest_event_read));
      impl_.latency_window.record(to_ns(now - s.window_ready));
      bump(impl_.m_publish.items_out);
      bump(impl_.m_publish.events_out, s.window_events);
    }
    void tick(Clock::time_point now) override {
      if (now < next_stats_) return;
      next_stats_ = now + impl_.options.stats_period;
      impl_.sink.publish_stats(impl_.stats());
    }

   private:
    Impl& impl_;
    Clock::time_point next_stats_{};
  };

  void fail(const std::string& stage, const std::string& what) {
    {
      std::lock_guard lock(error_mu);
      if (error.empty()) error = stage + ": " + what;
    }
    request_stop();  // upstream stops; downstream drains what it has (the failed stage closed its output)
  }

  void request_stop() noexcept {
    if (!stop_requested.exchange(true)) cancel.request_at(Clock::now() + options.drain_timeout);
    source->stop();  // a paced replay's sleep ends at once
    batches.interrupt_producer_async();
  }

  void set_source_state(SourceState s) {
    std::lock_guard lock(source_mu);
    if (s == SourceState::lost && source_snapshot.state != SourceState::lost) ++source_snapshot.lost_count;
    source_snapshot.state = s;
  }

  void snapshot_source() {
    const auto connection = source->connection();
    const SourceState s = connection == SourceConnection::connected      ? SourceState::running
                          : connection == SourceConnection::disconnected ? SourceState::lost
                                                                         : SourceState::ended;
    const std::uint64_t reconnects = source->reconnects();
    const auto& counters = source->stats();
    const auto progress = source->progress();
    std::lock_guard lock(source_mu);
    if (s == SourceState::lost && source_snapshot.state != SourceState::lost) ++source_snapshot.lost_count;
    source_snapshot.state = s;
    source_snapshot.reconnects = reconnects;
    source_snapshot.counters = counters;
    source_snapshot.progress = progress;
  }

  /// Reads the source until it ends, a stop, or an error, handing each batch to `out` (the batches queue, or the
  /// denoise stage in line). Closes nothing: the caller does.
  void source_loop(Outlet<EventBatchPtr>& out) {
    StageMetrics& m = m_source;
    m.state.store(StageState::running, std::memory_order_release);
    StageState end = StageState::finished;
    SourceState final_state = SourceState::ended;
    try {
      for (;;) {
        bump(m.heartbeat);
        if (stop_requested.load(std::memory_order_acquire)) {
          final_state = SourceState::stopped;
          break;
        }
        const auto t0 = Clock::now();
        EventBatchPtr b = source->next();
        const auto t1 = Clock::now();  // the batch itself carries when it was delivered (read_at)
        snapshot_source();
        if (!b) {
          if (source->finished()) break;
          std::this_thread::sleep_for(options.source_poll);  // live: nothing new yet
          continue;
        }
        stream.add(b->span());
        if (stream.first_t_us()) stream_time_us.store(stream.duration_us(), std::memory_order_relaxed);
        if (b->empty()) continue;
        const std::size_t n = b->size();
        bump(m.items_in);
        bump(m.events_in, n);
        m.step_ns.record(to_ns(t1 - t0));
        switch (out.push(std::move(b))) {
          case PushResult::pushed:
          case PushResult::replaced:
            bump(m.items_out);
            bump(m.events_out, n);
            break;
          case PushResult::dropped:
          case PushResult::stopped:
            bump(m.items_dropped);
            bump(m.events_dropped, n);
            break;
        }
      }
      if (stop_requested.load(std::memory_order_acquire)) final_state = SourceState::stopped;
    } catch (const StageFailure& e) {  // run_sequential: a stage after the source threw in line
      final_state = SourceState::stopped;
      fail_in_line(e);
    } catch (const std::exception& e) {
      end = StageState::failed;
      final_state = SourceState::failed;
      fail("source", e.what());
    } catch (...) {
      end = StageState::failed;
      final_state = SourceState::failed;
      fail("source", "unknown exception");
    }
    set_source_state(final_state);
    m.state.store(end, std::memory_order_release);
  }

  /// run_sequential: the stage named in `e` failed (the error is recorded, the run stops).
  void fail_in_line(const StageFailure& e) {
    for (StageMetrics* m : {&m_denoise, &m_pose, &m_publish}) {
      if (m->name() == e.stage()) m->state.store(StageState::failed, std::memory_order_release);
    }
    fail(e.stage(), e.what());
  }

  void thread_done() {
    {
      std::lock_guard lock(done_mu);
      ++threads_done;
    }
    done_cv.notify_all();
  }

  /// Waits until `n` threads have ended (bounded: a stage stuck in a step must not hang the shutdown); false on
  /// the timeout.
  bool wait_for_threads(int n, std::chrono::nanoseconds timeout) {
    std::unique_lock lock(done_mu);
    return done_cv.wait_for(lock, timeout, [this, n] { return threads_done >= n; });
  }

  /// Once the producers have ended: what is still queued (an item pushed after its consumer abandoned the queue)
  /// is discarded and counted as dropped, so that pushed == popped + dropped holds at the end.
  void discard_leftovers() {
    batches.discard_queued();
    windows_q.discard_queued();
    poses.discard_queued();
  }

  PipelineStats stats() const {
    PipelineStats s;
    const auto t0 = t_start_ns.load(std::memory_order_acquire);
    s.elapsed_s =
        t0 == 0 ? 0.0 : std::chrono::duration<double>(Clock::now() - Clock::time_point(Clock::duration(t0))).count();
    {
      std::lock_guard lock(source_mu);
      s.source = source_snapshot;
    }
    s.stream_time_us = stream_time_us.load(std::memory_order_relaxed);
    for (const StageMetrics* m : {&m_source, &m_denoise, &m_pose, &m_publish}) s.stages.push_back(m->snapshot());
    s.queues = {batches.stats(), windows_q.stats(), poses.stats()};
    s.windows = denoise_stage.windows();
    s.denoise_events_in = s.stages[1].events_in;
    s.denoise_events_kept = s.stages[1].events_out;
    s.denoise_report = denoise_stage.report();
    s.poses_published = s.stages[3].items_out;
    s.latency_event_to_publish_ns = latency_event.summary();
    s.latency_window_to_publish_ns = latency_window.summary();
    {
      std::lock_guard lock(done_mu);
      s.running = started.load() && threads_done < 4;
    }
    {
      std::lock_guard lock(error_mu);
      s.error = error;
    }
    return s;
  }

  const PipelineOptions options;
  std::unique_ptr<EventSource> source;
  std::unique_ptr<TaskPool> denoise_pool;  // before the filter: it outlives the filter's use of its runner
  std::unique_ptr<denoise::Filter> filter;
  PoseSink& sink;
  NamedQueue<EventBatchPtr> batches;
  NamedQueue<WindowItem> windows_q;
  NamedQueue<PoseSample> poses;
  StageMetrics m_source;
  StageMetrics m_denoise;
  StageMetrics m_pose;
  StageMetrics m_publish;
  DenoiseStage denoise_stage;
  PoseStage pose_stage;
  PublishStage publish_stage;
  QueueOutlet<EventBatchPtr> to_batches;  // the threaded graph's outlets (run_sequential uses InlineOutlets)
  QueueOutlet<WindowItem> to_windows;
  QueueOutlet<PoseSample> to_poses;
  Histogram latency_event;   // written by the publish thread
  Histogram latency_window;  // written by the publish thread

  CancelDeadline cancel;
  std::atomic<bool> stop_requested{false};
  std::atomic<bool> started{false};
  std::atomic<Clock::rep> t_start_ns{0};  // 0 = not started

  mutable std::mutex source_mu;
  SourceHealth source_snapshot;
  StreamStats stream;                           // source thread only; read after join
  std::atomic<std::int64_t> stream_time_us{0};  // its duration so far, for progress displays
  mutable std::mutex error_mu;
  std::string error;
  mutable std::mutex done_mu;
  std::condition_variable done_cv;
  int threads_done = 0;

  std::thread source_thread;
  std::unique_ptr<StageRunner<EventBatchPtr>> denoise_runner;
  std::unique_ptr<StageRunner<WindowItem>> pose_runner;
  std::unique_ptr<StageRunner<PoseSample>> publish_runner;
};

Pipeline::Pipeline(std::unique_ptr<EventSource> source, std::unique_ptr<denoise::Filter> filter,
                   WindowProcessor& processor, PoseSink& sink, PipelineOptions options)
    : impl_(std::make_unique<Impl>(std::move(source), std::move(filter), processor, sink, options)) {}

Pipeline::~Pipeline() {
  if (impl_->started.load()) {
    impl_->cancel.request_now();
    stop();
    join();
  }
}

void Pipeline::start() {
  Impl& s = *impl_;
  if (s.started.exchange(true)) throw std::logic_error("Pipeline::start called twice");
  s.t_start_ns.store(Clock::now().time_since_epoch().count(), std::memory_order_release);
  auto on_error = [&s](const std::string& stage, const std::string& what) { s.fail(stage, what); };
  s.denoise_stage.connect(s.to_windows);
  s.pose_stage.connect(s.to_poses);
  s.denoise_runner =
      std::make_unique<StageRunner<EventBatchPtr>>(s.m_denoise, s.batches, s.denoise_stage, s.cancel,
                                                   StageRunner<EventBatchPtr>::Hooks{[&s] {
                                                                                       s.windows_q.close();
                                                                                       s.thread_done();
                                                                                     },
                                                                                     on_error},
                                                   s.options.idle_wait);
  s.pose_runner = std::make_unique<StageRunner<WindowItem>>(s.m_pose, s.windows_q, s.pose_stage, s.cancel,
                                                            StageRunner<WindowItem>::Hooks{[&s] {
                                                                                             s.poses.close();
                                                                                             s.thread_done();
                                                                                           },
                                                                                           on_error},
                                                            s.options.idle_wait);
  s.publish_runner = std::make_unique<StageRunner<PoseSample>>(
      s.m_publish, s.poses, s.publish_stage, s.cancel,
      StageRunner<PoseSample>::Hooks{[&s] {
                                       // Final statistics once every other stage has ended (on a cancel the
                                       // pose thread may still finish its step and push after this thread
                                       // abandoned its input): then nothing moves and the counts are exact.
                                       // (Not when a stage is stuck: its queues still have a live side.)
                                       if (s.wait_for_threads(3, s.options.drain_timeout + std::chrono::seconds(5))) {
                                         s.discard_leftovers();
                                       }
                                       try {
                                         auto final_stats = s.stats();
                                         final_stats.running = false;  // every other thread has ended
                                         s.sink.publish_stats(final_stats);
                                       } catch (const std::exception& e) {
                                         s.fail("publish", e.what());
                                       } catch (...) {  // a hook must not throw: std::terminate otherwise
                                         s.fail("publish", "unknown exception");
                                       }
                                       s.thread_done();
                                     },
                                     on_error},
      s.options.idle_wait);
  s.set_source_state(SourceState::running);
  // Consumers first, so that nothing waits on a queue without a reader.
  s.publish_runner->start();
  s.pose_runner->start();
  s.denoise_runner->start();
  s.source_thread = std::thread([&s] {
    s.source_loop(s.to_batches);
    s.batches.close();
    s.thread_done();
  });
}

std::optional<std::string> Pipeline::run_sequential() {
  Impl& s = *impl_;
  if (s.started.exchange(true)) throw std::logic_error("Pipeline::run_sequential: the pipeline was already started");
  s.t_start_ns.store(Clock::now().time_since_epoch().count(), std::memory_order_release);
  // The same stage objects as start()'s, each pushing straight into the next one's step.
  InlineOutlet<PoseSample> to_publish(s.m_publish, s.publish_stage);
  InlineOutlet<WindowItem> to_pose(s.m_pose, s.pose_stage);
  InlineOutlet<EventBatchPtr> to_denoise(s.m_denoise, s.denoise_stage);
  s.denoise_stage.connect(to_pose);
  s.pose_stage.connect(to_publish);
  for (StageMetrics* m : {&s.m_denoise, &s.m_pose, &s.m_publish}) {
    m->state.store(StageState::running, std::memory_order_release);
  }
  s.set_source_state(SourceState::running);
  s.source_loop(to_denoise);
  // The end of the stream (or a stop): the denoise stage flushes (its last windows go through pose and publish);
  // the pose and publish stages hold nothing back. Not after a failure: the run ends there.
  if (!error()) {
    try {
      s.denoise_stage.finish();
    } catch (const StageFailure& e) {
      s.fail_in_line(e);
    } catch (const std::exception& e) {
      s.fail_in_line(StageFailure(s.m_denoise.name(), e.what()));
    } catch (...) {
      s.fail_in_line(StageFailure(s.m_denoise.name(), "unknown exception"));
    }
  }
  for (StageMetrics* m : {&s.m_denoise, &s.m_pose, &s.m_publish}) {
    if (m->state.load(std::memory_order_acquire) == StageState::running) {
      m->state.store(StageState::finished, std::memory_order_release);
    }
  }
  {
    std::lock_guard lock(s.done_mu);
    s.threads_done = 4;
  }
  s.done_cv.notify_all();
  try {
    auto final_stats = s.stats();
    final_stats.running = false;
    s.sink.publish_stats(final_stats);
  } catch (const std::exception& e) {
    s.fail("publish", e.what());
  } catch (...) {
    s.fail("publish", "unknown exception");
  }
  return error();
}

void Pipeline::request_stop() noexcept {
  impl_->request_stop();
}

void Pipeline::stop() {
  impl_->request_stop();
  impl_->batches.interrupt_producer();
}

bool Pipeline::wait_for(std::chrono::nanoseconds timeout) {
  Impl& s = *impl_;
  if (!s.started.load()) return true;
  std::unique_lock lock(s.done_mu);
  return s.done_cv.wait_for(lock, timeout, [&s] { return s.threads_done >= 4; });
}

void Pipeline::join() {
  Impl& s = *impl_;
  if (!s.started.load()) return;
  // Pipeline order: each thread ends after its upstream closed its input.
  if (s.source_thread.joinable()) s.source_thread.join();
  if (s.denoise_runner) s.denoise_runner->join();  // null after run_sequential()
  if (s.pose_runner) s.pose_runner->join();
  if (s.publish_runner) s.publish_runner->join();
  s.discard_leftovers();  // every thread has ended: safe from here
}

std::optional<std::string> Pipeline::run() {
  start();
  join();
  return error();
}

PipelineStats Pipeline::stats() const {
  return impl_->stats();
}

std::optional<std::string> Pipeline::error() const {
  std::lock_guard lock(impl_->error_mu);
  if (impl_->error.empty()) return std::nullopt;
  return impl_->error;
}

const PipelineOptions& Pipeline::options() const noexcept {
  return impl_->options;
}
const SourceInfo& Pipeline::source_info() const noexcept {
  return impl_->source->info();
}

const StreamStats& Pipeline::stream_stats() const noexcept {
  return impl_->stream;
}

const SourceStats& Pipeline::source_stats() const noexcept {
  return impl_->source->stats();
}

}  // namespace evpipe::stages
