// Pipeline speed: queue throughput between two threads (our SPSC ring and NamedQueue vs a mutex + deque queue, in
// one run so the ratio is measured on the same machine state), and whole-pipeline events/s on an in-memory replay
// with a no-op pose processor (no denoising, and with BAF).
//
//   build-rel/tests/bench/bench_pipeline --benchmark_filter=Queue      (items_per_second)
//   build-rel/tests/bench/bench_pipeline --benchmark_filter=Pipeline   (events_per_second)

#include <benchmark/benchmark.h>

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <random>
#include <thread>
#include <vector>

#include "evpipe/denoise/registry.hpp"
#include "evpipe/runtime/queue.hpp"
#include "evpipe/runtime/spsc_ring.hpp"
#include "evpipe/stages/pipeline.hpp"

using namespace evpipe;
using namespace evpipe::stages;
using namespace evpipe::runtime;

namespace {

constexpr std::uint64_t kItems = 1 << 20;
constexpr std::size_t kCapacity = 1024;

// The baseline: a bounded queue guarded by one mutex, spinning on full/empty exactly like the ring below.
class MutexDequeQueue {
 public:
  bool try_push(std::uint64_t v) {
    std::lock_guard lock(mu_);
    if (q_.size() >= kCapacity) return false;
    q_.push_back(v);
    return true;
  }
  bool try_pop(std::uint64_t& v) {
    std::lock_guard lock(mu_);
    if (q_.empty()) return false;
    v = q_.front();
    q_.pop_front();
    return true;
  }

 private:
  std::mutex mu_;
  std::deque<std::uint64_t> q_;
};

template <class Q>
void transfer(Q& q, benchmark::State& state) {
  std::thread producer([&] {
    for (std::uint64_t i = 0; i < kItems; ++i) {
      while (!q.try_push(std::uint64_t{i})) std::this_thread::yield();
    }
  });
  std::uint64_t v = 0;
  std::uint64_t sum = 0;
  for (std::uint64_t n = 0; n < kItems;) {
    if (q.try_pop(v)) {
      sum += v;
      ++n;
    } else {
      std::this_thread::yield();
    }
  }
  producer.join();
  if (sum != kItems * (kItems - 1) / 2) state.SkipWithError("lost or duplicated items");
  benchmark::DoNotOptimize(sum);
}

void BM_Queue_SpscRing(benchmark::State& state) {
  for (auto _ : state) {
    SpscRing<std::uint64_t> ring(kCapacity);
    transfer(ring, state);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kItems));
}
BENCHMARK(BM_Queue_SpscRing)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_Queue_MutexDeque(benchmark::State& state) {
  for (auto _ : state) {
    MutexDequeQueue q;
    transfer(q, state);
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kItems));
}
BENCHMARK(BM_Queue_MutexDeque)->Unit(benchmark::kMillisecond)->UseRealTime();

// NamedQueue in `block` mode: the producer and consumer sleep on the queue's condition variables instead of
// spinning (what the pipeline stages do), with the statistics counters on.
void BM_Queue_NamedQueueBlocking(benchmark::State& state) {
  for (auto _ : state) {
    NamedQueue<std::uint64_t> q("bench", kCapacity, QueuePolicy::block);
    std::thread producer([&] {
      for (std::uint64_t i = 0; i < kItems; ++i) q.push(std::uint64_t{i});
      q.close();
    });
    std::uint64_t v = 0;
    std::uint64_t sum = 0;
    while (q.pop(v, std::chrono::milliseconds(20)) != PopResult::closed) sum += v;
    producer.join();
    if (sum != kItems * (kItems - 1) / 2) state.SkipWithError("lost or duplicated items");
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * kItems));
}
BENCHMARK(BM_Queue_NamedQueueBlocking)->Unit(benchmark::kMillisecond)->UseRealTime();

// ---- whole pipeline ----

class MemorySource final : public EventSource {
 public:
  explicit MemorySource(const std::vector<EventBatchPtr>& batches) : batches_(batches) {}
  EventBatchPtr next() override { return i_ < batches_.size() ? batches_[i_++] : nullptr; }
  [[nodiscard]] bool finished() const override { return i_ >= batches_.size(); }
  [[nodiscard]] const SourceInfo& info() const override { return info_; }
  [[nodiscard]] const SourceStats& stats() const override { return stats_; }

 private:
  const std::vector<EventBatchPtr>& batches_;
  std::size_t i_ = 0;
  SourceInfo info_;
  SourceStats stats_;
};

class NoOpProcessor final : public WindowProcessor {
 public:
  pose::PoseEstimate process(const EventWindow& w) override {
    pose::PoseEstimate e;
    e.t_us = w.t1_us;
    e.window_events = w.size();
    return e;
  }
};

class NullSink final : public PoseSink {
 public:
  void publish_pose(const PoseSample& s) override { benchmark::DoNotOptimize(s.window_events); }
  void publish_stats(const PipelineStats& s) override { benchmark::DoNotOptimize(s.windows); }
};

// 4 M events at 10 Mev/s (0.4 s of sensor time) in 5 ms batches, uniform over the DAVIS346 array.
const std::vector<EventBatchPtr>& recording() {
  static const std::vector<EventBatchPtr> batches = [] {
    std::mt19937 rng(1);
    std::vector<EventBatchPtr> out;
    std::int64_t t = 0;
    constexpr std::size_t kEvents = 4'000'000;
    constexpr std::size_t kPerBatch = 50'000;  // 5 ms at 10 Mev/s
    for (std::size_t done = 0; done < kEvents; done += kPerBatch) {
      auto b = std::make_shared<EventBatch>();
      b->events.reserve(kPerBatch);
      for (std::size_t i = 0; i < kPerBatch; ++i) {
        if (i % 10 == 0) ++t;
        b->events.push_back(
            {t, static_cast<std::uint16_t>(rng() % 346), static_cast<std::uint16_t>(rng() % 260), (rng() & 1) != 0});
      }
      out.push_back(std::move(b));
    }
    return out;
  }();
  return batches;
}

void run_pipeline(benchmark::State& state, const char* filter) {
  const auto& batches = recording();
  std::uint64_t events = 0;
  for (const auto& b : batches) events += b->size();
  double p99_window_us = 0.0;
  for (auto _ : state) {
    NoOpProcessor processor;
    NullSink sink;
    PipelineOptions o;
    o.window_us = 30'000;
    o.hop_us = 10'000;
    auto f = filter ? denoise::make_filter_chain(filter, {}, kDavis346) : nullptr;
    Pipeline p(std::make_unique<MemorySource>(batches), std::move(f), processor, sink, o);
    if (auto err = p.run()) state.SkipWithError(err->c_str());
    p99_window_us = static_cast<double>(p.stats().latency_window_to_publish_ns.p99) / 1000.0;
  }
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * events));
  state.counters["events_per_second"] =
      benchmark::Counter(static_cast<double>(events), benchmark::Counter::kIsIterationInvariantRate);
  state.counters["p99_window_to_publish_us"] = p99_window_us;
}

void BM_Pipeline_Replay_NoDenoise(benchmark::State& state) {
  run_pipeline(state, nullptr);
}
BENCHMARK(BM_Pipeline_Replay_NoDenoise)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

void BM_Pipeline_Replay_Baf(benchmark::State& state) {
  run_pipeline(state, "baf");
}
BENCHMARK(BM_Pipeline_Replay_Baf)->Unit(benchmark::kMillisecond)->UseRealTime()->Iterations(3);

}  // namespace

BENCHMARK_MAIN();
