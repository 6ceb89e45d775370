#pragma once
// A named single-producer / single-consumer queue with a back-pressure policy and statistics
// (docs/architecture.md, "Queues"):
//
//   block        replay: lossless; a push waits while the queue is full. The wait ends when space frees, when
//                interrupt_producer() is called (the pipeline is stopping) or when the consumer abandoned the queue
//                (it failed): the item is then dropped and counted.
//   drop_newest  live: a push never waits; when the queue is full the pushed item is dropped and counted
//                (libcaer's own policy for its container ring).
//   latest_wins  hand-off of the freshest item (capacity 1): a push replaces an item the consumer has not taken yet
//                and counts the replaced one as dropped. The pose stage only wants the newest window.
//
// The fast paths are lock-free (SpscRing, or one atomic pointer exchange for latest_wins). A mutex and condition
// variable are touched only when a side has to sleep: a consumer on an empty queue, a `block` producer on a full
// one. Every wait has a timeout, so a missed wake-up costs at most that timeout, never a hang.
//
// An optional weight budget bounds what the items hold, not only their number (set_weight_budget): the source queue
// weighs a packet by its events, because a live packet's size follows the event rate (libcaer hands over a container
// every few ms, up to ~60 000 events at the DAVIS346's peak), so a packet count alone bounds nothing in bytes. An
// item that would take the queued weight over the budget counts as not fitting, exactly like a full ring (the policy
// decides: wait or drop), except into an empty queue: a single item larger than the budget still passes.
//
// Counters: pushed = every push() call (items offered), popped = items the consumer took, dropped = items that
// never reach the consumer (the policy, or discarded by an abandoning consumer). pushed == popped + dropped + fill
// whenever both sides are quiet.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>

#include "evpipe/runtime/spsc_ring.hpp"

namespace evpipe::runtime {

enum class QueuePolicy : std::uint8_t { block, drop_newest, latest_wins };
[[nodiscard]] std::string_view policy_name(QueuePolicy policy) noexcept;

enum class PushResult : std::uint8_t {
  pushed,    ///< the item is in the queue
  replaced,  ///< latest_wins: the item is in the queue and displaced an older one (counted as dropped)
  dropped,   ///< drop_newest on a full queue, or a push after close() / abandon(): the item was discarded
  stopped,   ///< block: the wait was interrupted (interrupt_producer or abandoned consumer); the item was discarded
};
enum class PopResult : std::uint8_t {
  item,     ///< `out` holds the next item
  timeout,  ///< nothing arrived within the timeout
  closed,   ///< the producer closed the queue and every item was taken
};

/// Counters of one queue, readable from any thread (each field exact; the set not one instant).
struct QueueStats {
  std::string name;
  QueuePolicy policy = QueuePolicy::block;
  std::size_t capacity = 0;
  std::uint64_t pushed = 0;
  std::uint64_t popped = 0;
  std::uint64_t dropped = 0;
  std::size_t fill = 0;
  std::size_t high_water = 0;           ///< largest fill seen right after a push
  std::uint64_t weight_budget = 0;      ///< 0 = none
  std::uint64_t weight_fill = 0;        ///< queued weight (e.g. events)
  std::uint64_t weight_high_water = 0;  ///< largest queued weight seen right after a push
};

/// Optional observer of a blocking push: bumps a stage heartbeat on every wake-up (a stage waiting on a full
/// queue is alive) and accumulates the time spent waiting (so that stage timings can exclude back-pressure).
struct WaitObserver {
  std::atomic<std::uint64_t>* heartbeat = nullptr;
  std::chrono::nanoseconds waited{0};
};

namespace detail {

/// Sleep/wake-up for one waiting side. wait() announces the sleeper, then re-checks readiness, so that a ring()
/// that follows a state change cannot be missed. Both sides pass through a read-modify-write of `order_` between
/// their store and their load (announce -> re-check; state change -> look for a sleeper): RMWs on one atomic are
/// totally ordered and the later one synchronises with the earlier, so at least one side sees the other's store.
/// (The same as a pair of seq_cst fences, but visible to ThreadSanitizer, which does not model fences.)
class Doorbell {
 public:
  template <class Ready>
  void wait(Ready&& ready, std::chrono::nanoseconds timeout) {
    waiting_.store(true, std::memory_order_relaxed);
    order_.fetch_add(1, std::memory_order_acq_rel);
    if (!ready()) {
      std::unique_lock lock(mu_);
      cv_.wait_for(lock, timeout, ready);
    }
    waiting_.store(false, std::memory_order_relaxed);
  }
  /// After a state change: wakes the other side if it sleeps (no mutex when it does not).
  void ring() {
    order_.fetch_add(1, std::memory_order_acq_rel);
    if (waiting_.load(std::memory_order_relaxed)) ring_always();
  }
  void ring_always() {
    { std::lock_guard lock(mu_); }  // the sleeper is either before its predicate check or inside wait_for
    cv_.notify_all();
  }

 private:
  std::atomic<bool> waiting_{false};
  std::atomic<std::uint32_t> order_{0};
  std::mutex mu_;
  std::condition_variable cv_;
};

inline void bump(std::atomic<std::uint64_t>& counter, std::uint64_t n = 1,
                 std::memory_order order = std::memory_order_relaxed) noexcept {
  // Single writer per counter: no locked read-modify-write needed.
  counter.store(counter.load(std::memory_order_relaxed) + n, order);
}

}  // namespace detail

template <class T>
class NamedQueue {
 public:
  /// capacity: rounded up to a power of two for block / drop_newest; latest_wins always holds one item.
  /// Throws std::invalid_argument for a zero capacity.
  NamedQueue(std::string name, std::size_t capacity, QueuePolicy policy)
      : name_(std::move(name)), policy_(policy), ring_(policy == QueuePolicy::latest_wins ? std::size_t{1} : capacity) {
    if (capacity == 0) throw std::invalid_argument("NamedQueue " + name_ + ": capacity must be > 0");
  }
  ~NamedQueue() { delete slot_.exchange(nullptr); }
  NamedQueue(const NamedQueue&) = delete;
  NamedQueue& operator=(const NamedQueue&) = delete;

  [[nodiscard]] const std::string& name() const noexcept { return name_; }
  [[nodiscard]] QueuePolicy policy() const noexcept { return policy_; }
  [[nodiscard]] std::size_t capacity() const noexcept {
    return policy_ == QueuePolicy::latest_wins ? 1 : ring_.capacity();
  }

  /// Bounds the queued weight (Σ weigh(item)) to `budget` (0 = no bound) as well as the item count. block /
  /// drop_newest only; call before the producer and consumer start.
  void set_weight_budget(std::uint64_t budget, std::uint64_t (*weigh)(const T&)) {
    if (policy_ == QueuePolicy::latest_wins && budget > 0) {
      throw std::invalid_argument("NamedQueue " + name_ + ": a weight budget needs the block or drop_newest policy");
    }
    weight_budget_ = weigh != nullptr ? budget : 0;
    weigh_ = weigh;
  }

  // ---- producer thread ----

  /// Pushes per the policy. `value` is moved from unless the result is dropped / stopped on a full queue.
  PushResult push(T&& value, WaitObserver* observer = nullptr,
                  std::chrono::nanoseconds wait_step = std::chrono::milliseconds(20)) {
    detail::bump(pushed_);
    if (closed_.load(std::memory_order_relaxed) || abandoned_.load(std::memory_order_acquire)) {
      detail::bump(dropped_);
      return PushResult::dropped;
    }
    if (policy_ == QueuePolicy::latest_wins) return push_latest(std::move(value));
    const std::uint64_t w = weight_budget_ > 0 ? weigh_(value) : 0;
    if (fits(w) && try_push_weighed(value, w)) return pushed_ok();
    if (policy_ == QueuePolicy::drop_newest) {
      detail::bump(dropped_);
      return PushResult::dropped;
    }
    // block: wait for space, an interrupt, or an abandoned consumer.
    const auto t_start = std::chrono::steady_clock::now();
    for (;;) {
      if (interrupted_.load(std::memory_order_acquire) || abandoned_.load(std::memory_order_acquire)) {
        detail::bump(dropped_);
        if (observer) observer->waited += std::chrono::steady_clock::now() - t_start;
        return PushResult::stopped;
      }
      if (fits(w) && try_push_weighed(value, w)) {
        if (observer) observer->waited += std::chrono::steady_clock::now() - t_start;
        return pushed_ok();
      }
      if (observer && observer->heartbeat) detail::bump(*observer->heartbeat);
      producer_bell_.wait(
          [this, w] {
            return (ring_.size() < ring_.capacity() && fits(w)) || interrupted_.load(std::memory_order_acquire) ||
                   abandoned_.load(std::memory_order_acquire);
          },
          wait_step);
    }
  }

  /// No more items: the consumer gets PopResult::closed once it has taken the rest.
  void close() {
    closed_.store(true, std::memory_order_release);
    consumer_bell_.ring_always();
  }

  // ---- consumer thread ----

  /// Takes the next item, waiting up to `timeout` for one.
  PopResult pop(T& out, std::chrono::nanoseconds timeout) {
    if (try_pop(out)) return PopResult::item;
    if (closed_.load(std::memory_order_acquire)) return try_pop(out) ? PopResult::item : PopResult::closed;
    consumer_bell_.wait([this] { return has_item() || closed_.load(std::memory_order_acquire); }, timeout);
    if (try_pop(out)) return PopResult::item;
    if (closed_.load(std::memory_order_acquire)) return try_pop(out) ? PopResult::item : PopResult::closed;
    return PopResult::timeout;
  }

  bool try_pop(T& out) {
    bool got = false;
    if (policy_ == QueuePolicy::latest_wins) {
      std::unique_ptr<T> item(slot_.exchange(nullptr, std::memory_order_acq_rel));
      if (item) {
        out = std::move(*item);
        got = true;
      }
    } else {
      got = ring_.try_pop(out);
      if (got && weight_budget_ > 0) detail::bump(weight_out_, weigh_(out), std::memory_order_release);
    }
    if (got) {
      detail::bump(popped_);
      if (policy_ == QueuePolicy::block) producer_bell_.ring();
    }
    return got;
  }

  /// The consumer is gone (it failed or was cancelled): pushes drop from now on, a waiting producer wakes, and
  /// the items still queued are discarded and counted as dropped. Consumer thread only.
  /// A push already past its abandoned check may still land one item after this; once the producer has ended,
  /// discard_queued() (by whoever then owns the queue) accounts for it — the pipeline does so at shutdown.
  void abandon() {
    abandoned_.store(true, std::memory_order_release);
    producer_bell_.ring_always();
    discard_queued();
  }

  // ---- any thread ----

  /// Makes a waiting (and any later) `block` push give up with PushResult::stopped. Lock-free and safe to call
  /// from a signal handler (the waiting producer then notices within its wait step).
  void interrupt_producer_async() noexcept { interrupted_.store(true, std::memory_order_release); }
  /// The same, and wakes the producer at once.
  void interrupt_producer() {
    interrupt_producer_async();
    producer_bell_.ring_always();
  }

  /// Consumer thread: discards what is queued (counted as dropped).
  void discard_queued() {
    T item;
    for (;;) {
      bool got = false;
      if (policy_ == QueuePolicy::latest_wins) {
        std::unique_ptr<T> p(slot_.exchange(nullptr, std::memory_order_acq_rel));
        got = p != nullptr;
      } else {
        got = ring_.try_pop(item);
        if (got && weight_budget_ > 0) detail::bump(weight_out_, weigh_(item), std::memory_order_release);
      }
      if (!got) break;
      detail::bump(discarded_);
    }
    producer_bell_.ring_always();
  }

  [[nodiscard]] std::size_t fill() const noexcept {
    if (policy_ == QueuePolicy::latest_wins) return slot_.load(std::memory_order_acquire) != nullptr ? 1 : 0;
    return ring_.size();
  }

  [[nodiscard]] QueueStats stats() const {
    QueueStats s;
    s.name = name_;
    s.policy = policy_;
    s.capacity = capacity();
    // popped before pushed: a concurrent snapshot then never shows more popped than pushed.
    s.popped = popped_.load(std::memory_order_acquire);
    s.dropped = dropped_.load(std::memory_order_acquire) + discarded_.load(std::memory_order_acquire);
    s.pushed = pushed_.load(std::memory_order_acquire);
    s.fill = fill();
    s.high_water = static_cast<std::size_t>(high_water_.load(std::memory_order_relaxed));
    s.weight_budget = weight_budget_;
    s.weight_fill = queued_weight();
    s.weight_high_water = weight_high_water_.load(std::memory_order_relaxed);
    return s;
  }

 private:
  /// Producer side: whether an item of weight w may join the queue now. The consumer only lowers the queued weight,
  /// so a yes stays true until the push. "Empty" is judged by the weight too, not by the ring: the consumer takes
  /// an item before it accounts for its weight, and the budget must hold for the counters as well.
  [[nodiscard]] bool fits(std::uint64_t w) const noexcept {
    if (weight_budget_ == 0) return true;
    const std::uint64_t queued = queued_weight();
    return queued + w <= weight_budget_ || queued == 0;
  }
  [[nodiscard]] std::uint64_t queued_weight() const noexcept {
    // out is read first: a snapshot never shows more taken out than put in. A third thread (stats()) reads out
    // again: while it read `in` the consumer may have taken items and the producer pushed more in their place, and
    // that mix would be more than was ever queued. out only grows, so two equal reads bracket a true state.
    for (;;) {
      const std::uint64_t out = weight_out_.load(std::memory_order_acquire);
      const std::uint64_t in = weight_in_.load(std::memory_order_acquire);
      if (weight_out_.load(std::memory_order_acquire) == out) return in - out;
    }
  }

  /// The weight is counted in before the item becomes visible, so that the consumer, which counts it out after
  /// taking it, never makes the queued weight negative; taken back if the ring is full (the value is then intact).
  bool try_push_weighed(T& value, std::uint64_t w) {
    if (w > 0) detail::bump(weight_in_, w, std::memory_order_release);
    if (ring_.try_push(std::move(value))) return true;
    if (w > 0) weight_in_.store(weight_in_.load(std::memory_order_relaxed) - w, std::memory_order_release);
    return false;
  }

  PushResult pushed_ok() {
    const std::uint64_t f = ring_.size();
    if (f > high_water_.load(std::memory_order_relaxed)) high_water_.store(f, std::memory_order_relaxed);
    if (weight_budget_ > 0) {
      const std::uint64_t q = queued_weight();
      if (q > weight_high_water_.load(std::memory_order_relaxed))
        weight_high_water_.store(q, std::memory_order_relaxed);
    }
    consumer_bell_.ring();
    return PushResult::pushed;
  }

  PushResult push_latest(T&& value) {
    std::unique_ptr<T> fresh = std::make_unique<T>(std::move(value));
    std::unique_ptr<T> old(slot_.exchange(fresh.release(), std::memory_order_acq_rel));
    high_water_.store(1, std::memory_order_relaxed);
    consumer_bell_.ring();
    if (old) {
      detail::bump(dropped_);
      return PushResult::replaced;
    }
    return PushResult::pushed;
  }

  [[nodiscard]] bool has_item() const noexcept {
    return policy_ == QueuePolicy::latest_wins ? slot_.load(std::memory_order_acquire) != nullptr : !ring_.empty();
  }

  const std::string name_;
  const QueuePolicy policy_;
  SpscRing<T> ring_;                       // block / drop_newest
  std::atomic<T*> slot_{nullptr};          // latest_wins: owned item or null
  std::atomic<std::uint64_t> pushed_{0};   // producer
  std::atomic<std::uint64_t> dropped_{0};  // producer
  std::atomic<std::uint64_t> high_water_{0};
  std::uint64_t weight_budget_ = 0;  // fixed before the threads start
  std::uint64_t (*weigh_)(const T&) = nullptr;
  std::atomic<std::uint64_t> weight_in_{0};  // producer: Σ weight pushed
  std::atomic<std::uint64_t> weight_high_water_{0};
  alignas(kCacheLineBytes) std::atomic<std::uint64_t> popped_{0};  // consumer
  std::atomic<std::uint64_t> discarded_{0};                        // consumer: dropped by abandon()
  std::atomic<std::uint64_t> weight_out_{0};                       // consumer: Σ weight taken or discarded
  std::atomic<bool> closed_{false};
  std::atomic<bool> abandoned_{false};
  std::atomic<bool> interrupted_{false};
  detail::Doorbell consumer_bell_;
  detail::Doorbell producer_bell_;
};

}  // namespace evpipe::runtime
