// The whole pipeline graph: a threaded replay equals Pipeline::run_sequential (the same stages on one thread) window
// by window and count by count, and both equal FilteredStream + TimeSlicer run directly (an independent reference),
// overload with the live policies, stage errors, shutdown within 1 s (also with full queues and from a signal
// handler), and a fake camera unplugged and replugged under a running pipeline (libcaer stub).

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "evpipe/core/slicer.hpp"
#include "evpipe/denoise/filtered_stream.hpp"
#include "evpipe/denoise/registry.hpp"
#include "evpipe/io/reader.hpp"
#include "evpipe/runtime/paced_source.hpp"
#include "evpipe/stages/pipeline.hpp"
#include "evpipe_test_data.hpp"

#if EVPIPE_TEST_FAKE_DEVICE
#include <libcaer_stub/fake_device.h>

#include "evpipe/device/davis_source.hpp"
#include "vector_source.hpp"
#endif

using namespace evpipe;
using namespace evpipe::stages;
using namespace evpipe::runtime;
using namespace std::chrono_literals;

namespace {

// Shutdown bound of the issue (1 s); ThreadSanitizer slows everything ~10x, so its builds only check the order.
#if defined(__SANITIZE_THREAD__)
constexpr auto kShutdownBound = 10s;
#else
constexpr auto kShutdownBound = 1s;
#endif

constexpr const char* kRecording = "davis346-faery-trimmed/sample.aedat4";
constexpr const char* kLongRecording = "davis346-faery/davis346.aedat4";  // several seconds

using evpipe::testing::VectorSource;

/// Random events, `segments` clock segments (each restarting near t = 0 with a discontinuity flag).
std::vector<EventBatchPtr> synthetic(std::uint32_t seed, std::size_t batches, std::size_t per_batch, int segments = 1,
                                     std::int64_t step_max_us = 20) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> dx(0, 345);
  std::uniform_int_distribution<int> dy(0, 259);
  std::uniform_int_distribution<std::int64_t> step(0, step_max_us);
  std::vector<EventBatchPtr> out;
  std::int64_t t = 1000;
  const std::size_t per_segment =
      (batches + static_cast<std::size_t>(segments) - 1) / static_cast<std::size_t>(segments);
  for (std::size_t b = 0; b < batches; ++b) {
    auto batch = std::make_shared<EventBatch>();
    if (b > 0 && b % per_segment == 0) {
      batch->discontinuity_before = true;
      t = 500;
    }
    for (std::size_t i = 0; i < per_batch; ++i) {
      t += step(rng);
      batch->events.push_back(
          {t, static_cast<std::uint16_t>(dx(rng)), static_cast<std::uint16_t>(dy(rng)), (rng() & 1) != 0});
    }
    out.push_back(std::move(batch));
  }
  return out;
}

struct WindowRecord {
  std::int64_t t0_us;
  std::int64_t t1_us;
  bool starts_segment;
  std::vector<Event> events;
  friend bool operator==(const WindowRecord&, const WindowRecord&) = default;
};

/// Records every window; optionally slow, optionally throwing at one window.
class RecordingProcessor final : public WindowProcessor {
 public:
  pose::PoseEstimate process(const EventWindow& w) override {
    if (calls_++ == throw_at) throw std::runtime_error("estimator exploded at window " + std::to_string(throw_at));
    if (delay.count() > 0) std::this_thread::sleep_for(delay);
    if (record) windows.push_back({w.t0_us, w.t1_us, w.starts_segment, w.contiguous()});
    pose::PoseEstimate e;
    e.t_us = w.t1_us;
    e.window_events = w.size();
    return e;
  }
  std::vector<WindowRecord> windows;  // pose thread only; read after join
  std::chrono::microseconds delay{0};
  bool record = true;
  std::int64_t throw_at = -1;

 private:
  std::int64_t calls_ = 0;
};

class RecordingSink final : public PoseSink {
 public:
  void publish_pose(const PoseSample& s) override {
    samples.push_back(s);
    published.store(published.load() + 1);
  }
  void publish_stats(const PipelineStats& s) override {
    stats.push_back(s);
    stats_calls.store(stats_calls.load() + 1);
  }
  std::vector<PoseSample> samples;  // publish thread only; read after join
  std::vector<PipelineStats> stats;
  std::atomic<std::uint64_t> published{0};
  std::atomic<std::uint64_t> stats_calls{0};
};

std::unique_ptr<denoise::Filter> filter_for(const std::string& name, const SensorGeometry& g) {
  return name == "none" ? nullptr : denoise::make_filter_chain(name, {}, g);
}

/// The reference: the same stages driven on the calling thread (Pipeline::run_sequential), the windows they cut.
/// `final_stats`: the statistics it ends with.
std::vector<WindowRecord> sequential_windows(std::unique_ptr<EventSource> source, const std::string& filter_name,
                                             PipelineOptions o, PipelineStats* final_stats = nullptr) {
  RecordingProcessor processor;
  RecordingSink sink;
  o.mode = Mode::replay;
  const auto geometry = source->info().geometry;
  Pipeline p(std::move(source), filter_for(filter_name, geometry), processor, sink, o);
  const auto error = p.run_sequential();
  EXPECT_FALSE(error) << *error;
  // Every window reached publish, once, in order.
  EXPECT_EQ(sink.samples.size(), processor.windows.size());
  for (std::size_t i = 0; i < sink.samples.size(); ++i) EXPECT_EQ(sink.samples[i].window_index, i);
  EXPECT_FALSE(p.stats().running);
  if (final_stats) *final_stats = p.stats();
  return processor.windows;
}

/// The independent reference: the filter and the slicer alone, without the pipeline's stages.
std::vector<WindowRecord> direct_windows(EventSource& source, const std::string& filter_name,
                                         const PipelineOptions& o) {
  std::vector<WindowRecord> out;
  auto filter = filter_for(filter_name, source.info().geometry);
  std::optional<denoise::FilteredStream> stream;
  if (filter) stream.emplace(*filter);
  TimeSlicer slicer({o.window_us, o.hop_us, std::nullopt}, [&](EventWindow&& w) {
    out.push_back({w.t0_us, w.t1_us, w.starts_segment, w.contiguous()});
  });
  std::vector<EventBatch> kept;
  while (auto b = source.next()) {
    if (!stream) {
      slicer.accept(b);
      continue;
    }
    kept.clear();
    stream->push(b, kept);
    for (auto& k : kept) slicer.accept(std::make_shared<const EventBatch>(std::move(k)));
  }
  if (stream) {
    kept.clear();
    stream->finish(kept);
    for (auto& k : kept) slicer.accept(std::make_shared<const EventBatch>(std::move(k)));
  }
  slicer.flush();
  return out;
}

// After the end every queue is empty and each item offered was either taken or dropped (counted).
void expect_queue_accounting(const PipelineStats& s) {
  for (const auto& q : s.queues) {
    SCOPED_TRACE("queue " + q.name);
    EXPECT_EQ(q.fill, 0u);
    EXPECT_EQ(q.pushed, q.popped + q.dropped);
    EXPECT_LE(q.high_water, q.capacity);
  }
}

std::string first_window_difference(const std::vector<WindowRecord>& got, const std::vector<WindowRecord>& want) {
  if (got.size() != want.size()) return "windows " + std::to_string(got.size()) + " != " + std::to_string(want.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    if (!(got[i] == want[i])) {
      return "window " + std::to_string(i) + " [" + std::to_string(got[i].t0_us) + ", " + std::to_string(got[i].t1_us) +
             ") events " + std::to_string(got[i].events.size()) + " vs [" + std::to_string(want[i].t0_us) + ", " +
             std::to_string(want[i].t1_us) + ") events " + std::to_string(want[i].events.size());
    }
  }
  return {};
}

bool wait_until(const std::function<bool()>& pred, std::chrono::milliseconds timeout = 10s) {
  const auto end = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < end) {
    if (pred()) return true;
    std::this_thread::sleep_for(2ms);
  }
  return pred();
}

// ---- replay: lossless and equal to the sequential run ----

void replay_equals_sequential(const std::string& path, const std::string& filter, PipelineOptions o) {
  SCOPED_TRACE(path + " filter " + filter);
  PipelineStats want_stats;
  const auto want = sequential_windows(io::open_reader(path), filter, o, &want_stats);
  ASSERT_GT(want.size(), 10u);
  EXPECT_EQ(first_window_difference(want, direct_windows(*io::open_reader(path), filter, o)), "");

  auto source = io::open_reader(path);
  const auto geometry = source->info().geometry;
  RecordingProcessor processor;
  RecordingSink sink;
  o.mode = Mode::replay;
  Pipeline p(std::move(source), filter_for(filter, geometry), processor, sink, o);
  const auto error = p.run();
  ASSERT_FALSE(error) << *error;

  EXPECT_EQ(first_window_difference(processor.windows, want), "");
  const auto s = p.stats();
  EXPECT_FALSE(s.running);
  EXPECT_EQ(s.source.state, SourceState::ended);
  EXPECT_EQ(s.windows, want.size());
  EXPECT_EQ(s.poses_published, want.size());
  ASSERT_EQ(sink.samples.size(), want.size());
  for (std::size_t i = 0; i < want.size(); ++i) {  // in order, none missing
    EXPECT_EQ(sink.samples[i].window_index, i);
    EXPECT_EQ(sink.samples[i].window_t1_us, want[i].t1_us);
    EXPECT_EQ(sink.samples[i].estimate.t_us, want[i].t1_us);
    EXPECT_EQ(sink.samples[i].window_events, want[i].events.size());
    EXPECT_LE(sink.samples[i].newest_event_read, sink.samples[i].window_ready);
    EXPECT_LE(sink.samples[i].window_ready, sink.samples[i].pose_done);
  }
  expect_queue_accounting(s);
  for (const auto& q : s.queues) EXPECT_EQ(q.dropped, 0u) << q.name;  // replay is lossless
  // The sequential runner counts as the threads do (a lossless replay: the same items and events at every stage).
  EXPECT_EQ(s.source.state, want_stats.source.state);
  EXPECT_EQ(s.windows, want_stats.windows);
  EXPECT_EQ(s.denoise_events_kept, want_stats.denoise_events_kept);
  EXPECT_EQ(s.poses_published, want_stats.poses_published);
  ASSERT_EQ(s.stages.size(), want_stats.stages.size());
  for (std::size_t k = 0; k < s.stages.size(); ++k) {
    const auto& a = s.stages[k];
    const auto& b = want_stats.stages[k];
    SCOPED_TRACE("stage " + a.name);
    EXPECT_EQ(a.state, b.state);
    EXPECT_EQ(a.items_in, b.items_in);
    EXPECT_EQ(a.items_out, b.items_out);
    EXPECT_EQ(a.events_in, b.events_in);
    EXPECT_EQ(a.events_out, b.events_out);
    EXPECT_EQ(a.items_dropped, b.items_dropped);
  }
  for (const auto& st : s.stages) {
    EXPECT_EQ(st.state, StageState::finished) << st.name;
    EXPECT_EQ(st.items_dropped, 0u) << st.name;
  }
  EXPECT_EQ(s.stages[0].events_in, s.source.counters.events);
  EXPECT_EQ(s.stages[0].events_out, s.source.counters.events);
  EXPECT_EQ(s.denoise_events_in, s.source.counters.events);
  EXPECT_EQ(s.latency_event_to_publish_ns.count, want.size());
  EXPECT_EQ(s.latency_window_to_publish_ns.count, want.size());
  EXPECT_GE(s.latency_event_to_publish_ns.p99, s.latency_event_to_publish_ns.p50);
  ASSERT_FALSE(sink.stats.empty());  // the final statistics come after the end
  EXPECT_FALSE(sink.stats.back().running);
  EXPECT_EQ(sink.stats.back().poses_published, want.size());
  // The filter's own figures at the end are those of one direct run over the whole recording.
  if (filter == "none") {
    EXPECT_TRUE(s.denoise_report.empty());
  } else {
    auto direct = filter_for(filter, geometry);
    denoise::Decisions d;
    const auto all = io::read_all(path);
    direct->push(all.events, d);
    direct->finish(d);
    const auto want_report = direct->report();
    ASSERT_EQ(s.denoise_report.size(), want_report.size()) << filter;
    for (std::size_t i = 0; i < want_report.size(); ++i) {
      EXPECT_EQ(s.denoise_report[i].key, want_report[i].key);
      EXPECT_EQ(s.denoise_report[i].value, want_report[i].value) << filter << " " << want_report[i].key;
    }
    const auto& published = sink.stats.back().denoise_report;
    ASSERT_EQ(published.size(), want_report.size()) << filter;
    for (std::size_t i = 0; i < want_report.size(); ++i) EXPECT_EQ(published[i].value, want_report[i].value);
  }
}

TEST(PipelineGraph, ReplayOfARealRecordingEqualsTheSequentialWindows) {
  EVPIPE_REQUIRE_REAL(path, kRecording);
  PipelineOptions o;
  o.window_us = 30'000;
  o.hop_us = 10'000;           // sliding windows
  o.batch_queue_capacity = 4;  // small queues: the source really waits
  o.window_queue_capacity = 2;
  o.pose_queue_capacity = 2;
  replay_equals_sequential(path, "baf", o);
  replay_equals_sequential(path, "none", o);
}

TEST(PipelineGraph, ReplayWithTheCurvatureFilterEqualsTheSequentialWindows) {
  EVPIPE_REQUIRE_REAL(path, kRecording);
  PipelineOptions o;  // the look-ahead filter: decisions arrive late, windows must still match
  o.window_us = 10'000;
  o.hop_us = 5'000;
  replay_equals_sequential(path, "curvature", o);
  // Each block spread over the stage's thread and pool workers (row bands): the same windows.
  o.denoise_threads = 3;
  replay_equals_sequential(path, "curvature", o);
  replay_equals_sequential(path, "hotpixel,curvature", o);
}

// Behind a filter each window also carries its unfiltered events (EventWindow::raw_parts: the hold's standstill test
// counts them): exactly the recording's events in [t0, t1), threaded and sequential alike; none without a filter.
TEST(PipelineGraph, WindowsBehindAFilterCarryTheirRawEvents) {
  EVPIPE_REQUIRE_REAL(path, kRecording);
  std::vector<Event> all;
  {
    auto reader = io::open_reader(path);
    while (auto b = reader->next()) all.insert(all.end(), b->events.begin(), b->events.end());
  }
  ASSERT_FALSE(all.empty());
  class RawChecker final : public WindowProcessor {
   public:
    explicit RawChecker(const std::vector<Event>& all) : all_(all) {}
    pose::PoseEstimate process(const EventWindow& w) override {
      std::vector<Event> raw;
      for (const EventSpan& part : w.raw_parts) raw.insert(raw.end(), part.begin(), part.end());
      const auto before = [](const Event& e, std::int64_t t) { return e.t_us < t; };
      const auto lo = std::lower_bound(all_.begin(), all_.end(), w.t0_us, before);
      const auto hi = std::lower_bound(lo, all_.end(), w.t1_us, before);
      if (!w.raw_parts.empty()) ++with_raw;
      if (std::vector<Event>(lo, hi) != raw) ++mismatches;
      if (w.raw_owners.size() != w.raw_parts.size()) ++mismatches;
      return {};
    }
    int with_raw = 0, mismatches = 0;

   private:
    const std::vector<Event>& all_;
  };
  for (const bool threaded : {false, true}) {
    SCOPED_TRACE(threaded ? "threaded" : "sequential");
    PipelineOptions o;
    o.mode = Mode::replay;
    o.window_us = 30'000;
    o.hop_us = 10'000;  // sliding windows: the raw batches serve several windows
    auto source = io::open_reader(path);
    const auto geometry = source->info().geometry;
    RawChecker checker(all);
    RecordingSink sink;
    Pipeline p(std::move(source), filter_for("significance", geometry), checker, sink, o);
    const auto error = threaded ? p.run() : p.run_sequential();
    ASSERT_FALSE(error) << *error;
    EXPECT_GT(checker.with_raw, 10);
    EXPECT_EQ(checker.mismatches, 0);
  }
  // No filter: the window's events are the raw ones; nothing attached.
  PipelineOptions o;
  o.mode = Mode::replay;
  auto source = io::open_reader(path);
  RawChecker checker(all);
  RecordingSink sink;
  Pipeline p(std::move(source), nullptr, checker, sink, o);
  ASSERT_FALSE(p.run_sequential());
  EXPECT_EQ(checker.with_raw, 0);
}

TEST(PipelineGraph, StatisticsCarryTheFiltersFiguresWhileRunning) {
  // The denoise thread copies the filter's report out as it goes (not only at the end): a statistics message taken
  // while the run is still going has it. The slow pose stage keeps the run going for ~0.4 s.
  const auto batches = synthetic(21, 40, 2000);
  RecordingProcessor processor;
  processor.delay = std::chrono::microseconds(5000);
  RecordingSink sink;
  PipelineOptions o;
  o.window_us = 10'000;
  o.hop_us = 10'000;
  o.stats_period = std::chrono::milliseconds(20);
  // Density stage alone at threshold 1: every event kept, so that every window reaches the slow stage.
  auto filter =
      denoise::make_filter_chain("curvature", {{"density_threshold", "1"}, {"curvature", "false"}}, kDavis346);
  Pipeline p(std::make_unique<VectorSource>(batches), std::move(filter), processor, sink, o);
  ASSERT_FALSE(p.run());
  EXPECT_GE(processor.windows.size(), 50u);
  const auto during = std::find_if(sink.stats.begin(), sink.stats.end(), [](const PipelineStats& s) {
    return s.running && s.denoise_events_in > 0 && !s.denoise_report.empty();
  });
  ASSERT_NE(during, sink.stats.end()) << sink.stats.size() << " statistics, none with the figures while running";
  EXPECT_TRUE(std::any_of(during->denoise_report.begin(), during->denoise_report.end(),
                          [](const denoise::ReportItem& i) { return i.key == "density_threshold_used"; }));
  EXPECT_FALSE(sink.stats.back().denoise_report.empty());
}

TEST(PipelineGraph, ClockSegmentsAreWindowedAsSequentially) {
  const std::uint32_t seed = 7;
  SCOPED_TRACE("seed " + std::to_string(seed));
  // Each batch stamped with its own read time (its index + 1 ms on the steady clock's epoch).
  std::vector<EventBatchPtr> batches;
  for (const auto& b : synthetic(seed, 300, 500, 3)) {
    auto stamped = std::make_shared<EventBatch>(*b);
    stamped->read_at = Clock::time_point(std::chrono::milliseconds(batches.size() + 1));
    batches.push_back(std::move(stamped));
  }
  PipelineOptions o;
  o.window_us = 5'000;
  o.hop_us = 2'500;
  const auto want = sequential_windows(std::make_unique<VectorSource>(batches), "baf", o);
  VectorSource reference(batches);
  EXPECT_EQ(first_window_difference(want, direct_windows(reference, "baf", o)), "");
  RecordingProcessor processor;
  RecordingSink sink;
  Pipeline p(std::make_unique<VectorSource>(batches), filter_for("baf", kDavis346), processor, sink, o);
  ASSERT_FALSE(p.run());
  EXPECT_EQ(first_window_difference(processor.windows, want), "");
  int segments = 0;
  for (const auto& w : processor.windows) segments += w.starts_segment ? 1 : 0;
  EXPECT_EQ(segments, 3);
  // A window's read time is that of the input batch holding its newest (kept) event, in the window's own clock
  // segment (times repeat across segments: 100 batches each).
  ASSERT_EQ(sink.samples.size(), processor.windows.size());
  int segment = -1;
  for (std::size_t i = 0; i < processor.windows.size(); ++i) {
    const auto& w = processor.windows[i];
    if (w.starts_segment) ++segment;
    ASSERT_FALSE(w.events.empty());
    const Event& newest = w.events.back();
    std::optional<Clock::time_point> read_at;
    for (std::size_t b = 100 * static_cast<std::size_t>(segment); b < 100 * static_cast<std::size_t>(segment + 1);
         ++b) {
      const auto& ev = batches[b]->events;
      if (std::find(ev.begin(), ev.end(), newest) != ev.end()) read_at = batches[b]->read_at;
    }
    ASSERT_TRUE(read_at) << "window " << i;
    EXPECT_EQ(sink.samples[i].newest_event_read, *read_at) << "window " << i;
    EXPECT_LE(sink.samples[i].newest_event_read, sink.samples[i].window_ready);
  }
}

// ---- errors ----

TEST(PipelineGraph, AStageErrorStopsThePipelineWithTheReason) {
  const auto batches = synthetic(11, 400, 500);
  RecordingProcessor processor;
  processor.throw_at = 5;
  RecordingSink sink;
  PipelineOptions o;
  o.batch_queue_capacity = 2;
  o.window_queue_capacity = 1;
  Pipeline p(std::make_unique<VectorSource>(batches), nullptr, processor, sink, o);
  const auto error = p.run();  // returns: no std::terminate, no hang
  ASSERT_TRUE(error);
  EXPECT_EQ(*error, "pose: estimator exploded at window 5");
  const auto s = p.stats();
  EXPECT_EQ(s.error, *error);
  EXPECT_EQ(s.stages[2].state, StageState::failed);
  EXPECT_EQ(s.source.state, SourceState::stopped);
  EXPECT_EQ(sink.samples.size(), 5u);  // the windows before the failing one were published
  ASSERT_FALSE(sink.stats.empty());
  EXPECT_EQ(sink.stats.back().error, *error);
}

// The sequential runner reports the stage that threw as the threads do (the reference of the graph tests must fail
// the same way), and the pipeline can still be joined and destroyed after it.
TEST(PipelineGraph, RunSequentialNamesTheStageThatFailed) {
  const auto batches = synthetic(11, 400, 500);
  RecordingProcessor processor;
  processor.throw_at = 5;
  RecordingSink sink;
  Pipeline p(std::make_unique<VectorSource>(batches), nullptr, processor, sink);
  const auto error = p.run_sequential();
  ASSERT_TRUE(error);
  EXPECT_EQ(*error, "pose: estimator exploded at window 5");
  const auto s = p.stats();
  EXPECT_EQ(s.stages[1].state, StageState::finished);
  EXPECT_EQ(s.stages[2].state, StageState::failed);
  EXPECT_EQ(s.source.state, SourceState::stopped);
  EXPECT_FALSE(s.running);
  EXPECT_EQ(sink.samples.size(), 5u);
  ASSERT_FALSE(sink.stats.empty());
  EXPECT_EQ(sink.stats.back().error, *error);
  EXPECT_TRUE(p.wait_for(0ns));
  p.join();  // nothing to join; the destructor after it neither hangs nor throws
}

/// A publish stage whose statistics cannot go out (the first periodic publish_stats throws).
class StatsFailingSink final : public PoseSink {
 public:
  void publish_pose(const PoseSample& /*s*/) override {}
  void publish_stats(const PipelineStats& /*s*/) override {
    if (calls_++ == 0) throw std::runtime_error("stats link down");
  }

 private:
  int calls_ = 0;
};

TEST(PipelineGraph, AFailingStatisticsPublishIsThePublishStagesErrorThreadedOrSequential) {
  for (const bool sequential : {false, true}) {
    SCOPED_TRACE(sequential ? "sequential" : "threaded");
    RecordingProcessor processor;
    StatsFailingSink sink;
    Pipeline p(std::make_unique<VectorSource>(synthetic(12, 40, 500)), nullptr, processor, sink);
    const auto error = sequential ? p.run_sequential() : p.run();
    ASSERT_TRUE(error);
    EXPECT_EQ(*error, "publish: stats link down");
    EXPECT_EQ(p.stats().stages[3].state, StageState::failed);
  }
}

// A sink that throws something that is not a std::exception from every statistics publish, the final one included
// (the publish thread's exit hook): the run reports it; before, the hook let it escape and std::terminate ended the
// program.
class NonStandardThrowingSink final : public PoseSink {
 public:
  void publish_pose(const PoseSample& /*s*/) override {}
  void publish_stats(const PipelineStats& /*s*/) override { throw 42; }  // NOLINT(hicpp-exception-baseclass)
};

TEST(PipelineGraph, ANonStandardExceptionFromTheStatisticsIsReportedNotFatal) {
  for (const bool sequential : {false, true}) {
    SCOPED_TRACE(sequential ? "sequential" : "threaded");
    RecordingProcessor processor;
    NonStandardThrowingSink sink;
    Pipeline p(std::make_unique<VectorSource>(synthetic(13, 40, 500)), nullptr, processor, sink);
    const auto error = sequential ? p.run_sequential() : p.run();
    ASSERT_TRUE(error);
    EXPECT_EQ(*error, "publish: unknown exception");
  }
}

class ThrowingSource final : public EventSource {
 public:
  EventBatchPtr next() override {
    if (n_++ < 3) return synthetic(1, 1, 100)[0];
    throw SourceError("rec.aedat4: byte 1234: packet header is corrupt");
  }
  [[nodiscard]] bool finished() const override { return false; }
  [[nodiscard]] const SourceInfo& info() const override { return info_; }
  [[nodiscard]] const SourceStats& stats() const override { return stats_; }

 private:
  int n_ = 0;
  SourceInfo info_;
  SourceStats stats_;
};

TEST(PipelineGraph, ASourceErrorIsReported) {
  RecordingProcessor processor;
  RecordingSink sink;
  Pipeline p(std::make_unique<ThrowingSource>(), nullptr, processor, sink);
  const auto error = p.run();
  ASSERT_TRUE(error);
  EXPECT_EQ(*error, "source: rec.aedat4: byte 1234: packet header is corrupt");
  EXPECT_EQ(p.stats().source.state, SourceState::failed);
  EXPECT_EQ(p.stats().stages[0].items_in, 3u);
}

TEST(PipelineGraph, BadOptionsAreRejected) {
  RecordingProcessor processor;
  RecordingSink sink;
  PipelineOptions o;
  o.hop_us = 0;
  EXPECT_THROW(Pipeline(std::make_unique<VectorSource>(std::vector<EventBatchPtr>{}), nullptr, processor, sink, o),
               std::invalid_argument);
  o = {};
  o.pose_queue_capacity = 0;
  EXPECT_THROW(Pipeline(std::make_unique<VectorSource>(std::vector<EventBatchPtr>{}), nullptr, processor, sink, o),
               std::invalid_argument);
}

// ---- overload: live policies ----

TEST(PipelineGraph, LiveOverloadDropsAndCountsButStaysBounded) {
  const std::uint32_t seed = 3;
  SCOPED_TRACE("seed " + std::to_string(seed));
  const auto batches = synthetic(seed, 1500, 1000, 1, 5);  // 1.5 Mev, ~3.8 s of sensor time, read unpaced
  std::uint64_t total = 0;
  for (const auto& b : batches) total += b->size();
  RecordingProcessor processor;
  processor.delay = 3ms;  // far slower than the 1 ms hop asks for
  processor.record = false;
  RecordingSink sink;
  PipelineOptions o;
  o.mode = Mode::live;
  o.window_us = 2'000;
  o.hop_us = 1'000;
  o.batch_queue_capacity = 8;
  o.batch_queue_events = 3'000;  // three of these 1000-event packets: the event bound binds before the count
  o.pose_queue_capacity = 4;
  Pipeline p(std::make_unique<VectorSource>(batches), filter_for("baf", kDavis346), processor, sink, o);
  ASSERT_FALSE(p.run());
  const auto s = p.stats();
  expect_queue_accounting(s);  // drops == pushed - popped on every queue
  const auto& batches_q = s.queues[0];
  const auto& windows_q = s.queues[1];
  EXPECT_EQ(batches_q.policy, QueuePolicy::drop_newest);
  EXPECT_EQ(batches_q.weight_budget, 3'000u);
  EXPECT_LE(batches_q.weight_high_water, 3'000u);
  EXPECT_LE(batches_q.high_water, 3u);
  EXPECT_GT(batches_q.dropped, 0u);
  EXPECT_EQ(windows_q.policy, QueuePolicy::latest_wins);
  EXPECT_EQ(windows_q.capacity, 1u);
  EXPECT_GT(windows_q.dropped, 0u);  // stale windows were replaced by fresher ones
  // The source counts what it could not hand on, event-exact.
  EXPECT_EQ(s.stages[0].events_in, total);
  EXPECT_EQ(s.stages[0].events_out + s.stages[0].events_dropped, total);
  EXPECT_EQ(s.stages[0].items_dropped, batches_q.dropped);
  EXPECT_EQ(s.stages[1].events_in, s.stages[0].events_out);
  // Every window that reached the pose stage was published, in order, with gaps where windows were dropped.
  EXPECT_EQ(sink.samples.size(), windows_q.popped - s.queues[2].dropped);
  for (std::size_t i = 1; i < sink.samples.size(); ++i) {
    ASSERT_LT(sink.samples[i - 1].window_index, sink.samples[i].window_index);
  }
  EXPECT_EQ(s.windows, s.stages[1].items_out + s.stages[1].items_dropped);
}

// ---- shutdown ----

TEST(PipelineGraph, StopWithFullQueuesEndsWithinTheBound) {
  // Replay, lossless queues, a processor far too slow: every queue fills and the reader waits.
  const auto batches = synthetic(5, 1500, 1000);
  RecordingProcessor processor;
  processor.delay = 20ms;
  processor.record = false;
  RecordingSink sink;
  PipelineOptions o;
  o.window_us = 2'000;
  o.hop_us = 1'000;
  o.batch_queue_capacity = 16;
  o.window_queue_capacity = 4;
  o.pose_queue_capacity = 4;
  o.drain_timeout = 500ms;  // the drain would take seconds: it is cut short (bound = drain_timeout + one step)
  Pipeline p(std::make_unique<VectorSource>(batches), nullptr, processor, sink, o);
  p.start();
  ASSERT_TRUE(wait_until([&] {
    const auto s = p.stats();
    return s.queues[0].fill == s.queues[0].capacity && s.queues[1].fill == s.queues[1].capacity;
  }));
  const auto t0 = std::chrono::steady_clock::now();
  p.stop();
  ASSERT_TRUE(p.wait_for(5s));
  const auto took = std::chrono::steady_clock::now() - t0;
  p.join();
  EXPECT_LT(took, kShutdownBound) << std::chrono::duration<double>(took).count() << " s";
  const auto s = p.stats();
  EXPECT_FALSE(s.running);
  EXPECT_TRUE(s.error.empty()) << s.error;
  EXPECT_EQ(s.source.state, SourceState::stopped);
  expect_queue_accounting(s);
  EXPECT_LT(s.stages[0].items_in, batches.size());  // it really stopped early
}

Pipeline* g_signal_pipeline = nullptr;
extern "C" void on_sigterm(int) {
  if (g_signal_pipeline) g_signal_pipeline->request_stop();  // lock-free: allowed in a handler
}

TEST(PipelineGraph, SigtermDuringARealTimeReplayDrainsAndEndsWithinTheBound) {
  EVPIPE_REQUIRE_REAL(path, kLongRecording);
  RecordingProcessor processor;
  RecordingSink sink;
  auto paced = std::make_unique<PacedSource>(io::open_reader(path), 1.0);
  Pipeline p(std::move(paced), filter_for("baf", kDavis346), processor, sink, PipelineOptions{});
  g_signal_pipeline = &p;
  auto* previous = std::signal(SIGTERM, on_sigterm);
  p.start();
  ASSERT_TRUE(wait_until([&] { return sink.published.load() >= 10; }));  // ~300 ms into the recording
  const auto t0 = std::chrono::steady_clock::now();
  std::raise(SIGTERM);
  const bool ended = p.wait_for(5s);
  const auto took = std::chrono::steady_clock::now() - t0;
  std::signal(SIGTERM, previous);
  ASSERT_TRUE(ended);
  p.join();
  g_signal_pipeline = nullptr;
  EXPECT_LT(took, kShutdownBound) << std::chrono::duration<double>(took).count() << " s";
  const auto s = p.stats();
  EXPECT_EQ(s.source.state, SourceState::stopped);
  EXPECT_TRUE(s.error.empty()) << s.error;
  // Drained: whatever the source handed on was windowed, and every window was published. A paced source is live:
  // on a machine that falls behind real time for a moment (sanitiser builds on a loaded 2-core runner) it drops whole
  // batches, counted, rather than wait; what it handed on is what must drain.
  expect_queue_accounting(s);
  for (const auto& q : s.queues) {
    if (q.name == "batches") {
      EXPECT_LE(q.dropped, s.stages[0].items_dropped);  // counted by the source too (with pushes cut by the stop)
    } else {
      EXPECT_EQ(q.dropped, 0u) << q.name;
    }
  }
  EXPECT_EQ(s.stages[1].events_in, s.stages[0].events_out);
  EXPECT_EQ(s.poses_published, s.windows);
  for (const auto& st : s.stages) EXPECT_EQ(st.state, StageState::finished) << st.name;
}

#if EVPIPE_TEST_FAKE_DEVICE
// ---- live camera: unplug and replug under a running pipeline ----

std::vector<caer_stub::FakeEvent> fake_events(std::size_t n, std::int64_t t0_us, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<caer_stub::FakeEvent> out;
  std::int64_t t = t0_us;
  for (std::size_t i = 0; i < n; ++i) {
    t += static_cast<std::int64_t>(rng() % 20);
    out.push_back(
        {t, static_cast<std::uint16_t>(rng() % 346), static_cast<std::uint16_t>(rng() % 260), (rng() & 1) != 0, true});
  }
  return out;
}

TEST(PipelineGraph, CameraUnplugAndReplugAreVisibleAndThePipelineKeepsRunning) {
  auto& fake = caer_stub::FakeDevice::instance();
  fake.reset();
  device::DavisOptions dopt;
  dopt.reconnect_interval_ms = 10;
  dopt.statistics_interval_ms = 0;
  auto camera = std::make_unique<device::DavisSource>(dopt);
  RecordingProcessor processor;
  RecordingSink sink;
  PipelineOptions o;
  o.mode = Mode::live;
  o.stats_period = 50ms;
  Pipeline p(std::move(camera), nullptr, processor, sink, o);
  p.start();

  fake.queue_events(fake_events(20'000, 0, 1));  // ~190 ms of device time
  ASSERT_TRUE(wait_until([&] { return p.stats().source.counters.events == 20'000; }));
  EXPECT_EQ(p.stats().source.state, SourceState::running);

  fake.unplug();
  ASSERT_TRUE(wait_until([&] { return p.stats().source.state == SourceState::lost; }));
  EXPECT_EQ(p.stats().source.lost_count, 1u);
  const auto beat = p.stats().stages[0].heartbeat;
  ASSERT_TRUE(wait_until([&] { return p.stats().stages[0].heartbeat > beat + 5; }));  // alive while lost
  const auto calls = sink.stats_calls.load();
  ASSERT_TRUE(wait_until([&] { return sink.stats_calls.load() >= calls + 2; }));  // published while lost

  fake.replug();
  fake.queue_events(fake_events(20'000, 0, 2));  // device time restarts
  ASSERT_TRUE(wait_until([&] {
    const auto s = p.stats();
    return s.source.state == SourceState::running && s.source.counters.events == 40'000;
  }));
  const auto s_after = p.stats();
  EXPECT_EQ(s_after.source.reconnects, 1u);
  EXPECT_EQ(s_after.source.lost_count, 1u);
  EXPECT_EQ(s_after.source.counters.discontinuities, 1u);
  EXPECT_TRUE(s_after.running);
  const auto calls_after = sink.stats_calls.load();
  ASSERT_TRUE(wait_until([&] { return sink.stats_calls.load() >= calls_after + 2; }));  // published while running

  p.stop();
  ASSERT_TRUE(p.wait_for(5s));
  p.join();
  const auto s = p.stats();
  EXPECT_TRUE(s.error.empty()) << s.error;
  EXPECT_EQ(s.source.state, SourceState::stopped);
  EXPECT_GT(s.poses_published, 0u);
  // The published statistics saw the LOST state (what the application turns into status LOST).
  bool saw_lost = false;
  bool saw_running_after_lost = false;
  for (const auto& st : sink.stats) {
    if (st.source.state == SourceState::lost) saw_lost = true;
    if (saw_lost && st.source.state == SourceState::running) saw_running_after_lost = true;
  }
  EXPECT_TRUE(saw_lost);
  EXPECT_TRUE(saw_running_after_lost);
  // Live: windows may be replaced before the pose stage takes them, but those it takes are in order.
  for (std::size_t i = 1; i < sink.samples.size(); ++i) {
    EXPECT_LT(sink.samples[i - 1].window_index, sink.samples[i].window_index);
  }
  fake.reset();
}

// A source wrapping the camera (as PacedSource does): forwarding EventSource::connection() and reconnects(), the
// camera's state still shows without the pipeline knowing the camera's type.
class PassThrough final : public EventSource {
 public:
  explicit PassThrough(std::unique_ptr<EventSource> inner) : inner_(std::move(inner)) {}
  EventBatchPtr next() override { return inner_->next(); }
  [[nodiscard]] bool finished() const override { return inner_->finished(); }
  [[nodiscard]] const SourceInfo& info() const override { return inner_->info(); }
  [[nodiscard]] const SourceStats& stats() const override { return inner_->stats(); }
  [[nodiscard]] SourceConnection connection() const noexcept override { return inner_->connection(); }
  [[nodiscard]] std::uint64_t reconnects() const noexcept override { return inner_->reconnects(); }
  void stop() noexcept override { inner_->stop(); }

 private:
  std::unique_ptr<EventSource> inner_;
};

TEST(PipelineGraph, AWrappedCameraStillReportsItsUnplug) {
  auto& fake = caer_stub::FakeDevice::instance();
  fake.reset();
  device::DavisOptions dopt;
  dopt.reconnect_interval_ms = 10;
  dopt.statistics_interval_ms = 0;
  auto camera = std::make_unique<device::DavisSource>(dopt);
  RecordingProcessor processor;
  RecordingSink sink;
  PipelineOptions o;
  o.mode = Mode::live;
  o.stats_period = 50ms;
  Pipeline p(std::make_unique<PassThrough>(std::move(camera)), nullptr, processor, sink, o);
  p.start();
  fake.queue_events(fake_events(20'000, 0, 1));
  ASSERT_TRUE(wait_until([&] { return p.stats().source.counters.events == 20'000; }));
  fake.unplug();
  ASSERT_TRUE(wait_until([&] { return p.stats().source.state == SourceState::lost; }));
  EXPECT_EQ(p.stats().source.lost_count, 1u);
  p.stop();
  ASSERT_TRUE(p.wait_for(5s));
  p.join();
  fake.reset();
}
#endif

}  // namespace
