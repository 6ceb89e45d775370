#pragma once
// The generic stage loop (Kimera-VIO's PipelineModule idea): a stage writes one step, StageRunner runs it on its
// own thread — pull from the input queue, time the step, count, beat the heartbeat — until the input is closed
// and drained (then Stage::finish flushes), the run is cancelled, or a step throws (the error is reported through
// a callback, never std::terminate).
//
// Waiting: an empty input queue puts the thread to sleep on the queue's condition variable with a timeout
// (idle_wait, default 20 ms): no CPU is burnt while idle, a push wakes it at once, and the timeout lets the loop
// notice cancellation and run Stage::tick (timers such as the one-second statistics) without any other thread.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
#include <string_view>
#include <thread>
#include <utility>

#include "evpipe/runtime/histogram.hpp"
#include "evpipe/runtime/queue.hpp"

namespace evpipe::runtime {

using Clock = std::chrono::steady_clock;

enum class StageState : std::uint8_t { idle, running, finished, cancelled, failed };
[[nodiscard]] std::string_view state_name(StageState state) noexcept;

/// A copy of a stage's counters.
struct StageStats {
  std::string name;
  StageState state = StageState::idle;
  std::uint64_t items_in = 0;        ///< input items taken (batches, windows, poses)
  std::uint64_t items_out = 0;       ///< output items accepted by the next queue / the sink
  std::uint64_t events_in = 0;       ///< events in the input items
  std::uint64_t events_out = 0;      ///< events passed on (source: pushed; denoise: kept; pose: in processed windows)
  std::uint64_t items_dropped = 0;   ///< outputs refused by the next queue (its policy) or replaced there
  std::uint64_t events_dropped = 0;  ///< events in the refused outputs (source)
  std::uint64_t heartbeat = 0;       ///< loop rounds: grows at least every idle wait while the thread is healthy
  HistogramSummary step_ns;          ///< processing time per step, back-pressure waits excluded
};

/// Counters of one stage: written by its thread only, read by any (single-writer atomics).
class StageMetrics {
 public:
  explicit StageMetrics(std::string name) : name_(std::move(name)) {}
  [[nodiscard]] const std::string& name() const noexcept { return name_; }

  std::atomic<std::uint64_t> items_in{0};
  std::atomic<std::uint64_t> items_out{0};
  std::atomic<std::uint64_t> events_in{0};
  std::atomic<std::uint64_t> events_out{0};
  std::atomic<std::uint64_t> items_dropped{0};
  std::atomic<std::uint64_t> events_dropped{0};
  std::atomic<std::uint64_t> heartbeat{0};
  std::atomic<StageState> state{StageState::idle};
  Histogram step_ns;
  /// Blocking pushes of the current step report their waits here (see WaitObserver).
  WaitObserver wait{&heartbeat, {}};

  [[nodiscard]] StageStats snapshot() const;

 private:
  std::string name_;
};

/// One stage: consumes items of type In.
template <class In>
class Stage {
 public:
  Stage() = default;
  virtual ~Stage() = default;
  Stage(const Stage&) = delete;
  Stage& operator=(const Stage&) = delete;

  /// Processes one input item (pushes its outputs to its Outlet). May throw: the pipeline stops with the error.
  virtual void step(In&& item) = 0;
  /// The input was closed and every item was processed: flush what is held back.
  virtual void finish() {}
  /// Called every loop round (after each step and each idle wake-up): timers.
  virtual void tick(Clock::time_point /*now*/) {}
};

/// Where a stage's step puts its outputs: the next stage's queue when each stage has its thread (QueueOutlet), or
/// the next stage itself when one thread drives them all (InlineOutlet, the sequential runner). A stage is written
/// once against this and runs either way.
template <class T>
class Outlet {
 public:
  Outlet() = default;
  virtual ~Outlet() = default;
  Outlet(const Outlet&) = delete;
  Outlet& operator=(const Outlet&) = delete;
  virtual PushResult push(T&& item) = 0;
};

/// Pushes into a queue (its policy decides: wait, drop or replace); a blocking wait is reported to `wait`.
template <class T>
class QueueOutlet final : public Outlet<T> {
 public:
  /// wait_step: a blocked push re-checks for an interrupt at least this often.
  QueueOutlet(NamedQueue<T>& queue, WaitObserver* wait,
              std::chrono::nanoseconds wait_step = std::chrono::milliseconds(20))
      : queue_(queue), wait_(wait), wait_step_(wait_step) {}
  PushResult push(T&& item) override { return queue_.push(std::move(item), wait_, wait_step_); }

 private:
  NamedQueue<T>& queue_;
  WaitObserver* wait_;
  std::chrono::nanoseconds wait_step_;
};

/// What an InlineOutlet throws when the next stage's step throws: the stage's name and the reason, passed through
/// unchanged by the outlets of the stages before it (so that the driver reports the stage that failed).
class StageFailure : public std::runtime_error {
 public:
  StageFailure(std::string stage, const std::string& what) : std::runtime_error(what), stage_(std::move(stage)) {}
  [[nodiscard]] const std::string& stage() const noexcept { return stage_; }

 private:
  std::string stage_;
};

/// Runs the next stage's step at once on the calling thread, counted and timed in its metrics as its runner would
/// (items_in, step_ns, heartbeat), then its tick(). Never drops. The time of a step includes the steps it pushed
/// to (nested). Throws StageFailure naming the next stage when its step or tick throws (as StageRunner reports
/// both as that stage's error).
template <class T>
class InlineOutlet final : public Outlet<T> {
 public:
  InlineOutlet(StageMetrics& next_metrics, Stage<T>& next) : metrics_(next_metrics), next_(next) {}
  PushResult push(T&& item) override {
    detail::bump(metrics_.heartbeat);
    detail::bump(metrics_.items_in);
    try {
      const auto t0 = Clock::now();
      next_.step(std::move(item));
      const auto now = Clock::now();
      metrics_.step_ns.record(static_cast<std::uint64_t>(std::max<std::int64_t>(0, (now - t0).count())));
      next_.tick(now);
    } catch (const StageFailure&) {
      throw;
    } catch (const std::exception& e) {
      throw StageFailure(metrics_.name(), e.what());
    } catch (...) {
      throw StageFailure(metrics_.name(), "unknown exception");
    }
    return PushResult::pushed;
  }

 private:
  StageMetrics& metrics_;
  Stage<T>& next_;
};

/// Cancellation shared by the runners of one pipeline: a deadline on the steady clock (nanoseconds since its
/// epoch; max = none). Lock-free: request_at() may be called from a signal handler.
class CancelDeadline {
 public:
  void request_at(Clock::time_point t) noexcept {
    const auto ns = t.time_since_epoch().count();
    auto cur = ns_.load(std::memory_order_relaxed);
    while (ns < cur && !ns_.compare_exchange_weak(cur, ns, std::memory_order_release)) {
    }
  }
  void request_now() noexcept { request_at(Clock::now()); }
  [[nodiscard]] bool due(Clock::time_point now) const noexcept {
    return now.time_since_epoch().count() >= ns_.load(std::memory_order_acquire);
  }

 private:
  std::atomic<Clock::rep> ns_{std::numeric_limits<Clock::rep>::max()};
};

template <class In>
class StageRunner {
 public:
  struct Hooks {
    /// Called once on the stage's thread when the loop ends for any reason (close the output queues here).
    std::function<void()> on_exit;
    /// Called on the stage's thread when a step / finish throws: (stage name, what()).
    std::function<void(const std::string&, const std::string&)> on_error;
  };

  StageRunner(StageMetrics& metrics, NamedQueue<In>& input, Stage<In>& stage, const CancelDeadline& cancel, Hooks hooks,
              std::chrono::nanoseconds idle_wait = std::chrono::milliseconds(20))
      : metrics_(metrics),
        input_(input),
        stage_(stage),
        cancel_(cancel),
        hooks_(std::move(hooks)),
        idle_wait_(idle_wait) {}
  ~StageRunner() { join(); }
  StageRunner(const StageRunner&) = delete;
  StageRunner& operator=(const StageRunner&) = delete;

  void start() {
    thread_ = std::thread([this] { loop(); });
  }
  void join() {
    if (thread_.joinable()) thread_.join();
  }
  /// Runs the loop on the calling thread (tests, sequential use).
  void run_here() { loop(); }

 private:
  void loop() {
    metrics_.state.store(StageState::running, std::memory_order_release);
    StageState end = StageState::finished;
    try {
      for (;;) {
        detail::bump(metrics_.heartbeat);
        if (cancel_.due(Clock::now())) {
          input_.abandon();  // the producer stops waiting for us; what is left is dropped
          end = StageState::cancelled;
          break;
        }
        In item;
        const PopResult r = input_.pop(item, idle_wait_);
        if (r == PopResult::item) {
          detail::bump(metrics_.items_in);
          metrics_.wait.waited = std::chrono::nanoseconds{0};
          const auto t0 = Clock::now();
          stage_.step(std::move(item));
          const auto busy = Clock::now() - t0 - metrics_.wait.waited;
          metrics_.step_ns.record(static_cast<std::uint64_t>(std::max<std::int64_t>(0, busy.count())));
        } else if (r == PopResult::closed) {
          stage_.finish();
          break;
        }
        stage_.tick(Clock::now());
      }
    } catch (const std::exception& e) {
      end = StageState::failed;
      input_.abandon();
      if (hooks_.on_error) hooks_.on_error(metrics_.name(), e.what());
    } catch (...) {
      end = StageState::failed;
      input_.abandon();
      if (hooks_.on_error) hooks_.on_error(metrics_.name(), "unknown exception");
    }
    metrics_.state.store(end, std::memory_order_release);
    if (hooks_.on_exit) hooks_.on_exit();
  }

  StageMetrics& metrics_;
  NamedQueue<In>& input_;
  Stage<In>& stage_;
  const CancelDeadline& cancel_;
  Hooks hooks_;
  std::chrono::nanoseconds idle_wait_;
  std::thread thread_;
};

}  // namespace evpipe::runtime
