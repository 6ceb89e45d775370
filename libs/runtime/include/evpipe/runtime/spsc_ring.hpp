#pragma once
// A bounded lock-free single-producer / single-consumer ring (docs/architecture.md, "Queues": why our own).
//
// The ideas of libcaer's ring and rigtorp's SPSCQueue: power-of-two capacity (index & mask), the producer's and the
// consumer's index on separate cache lines, and each side keeping a private copy of the other side's index so that
// it reads the shared one only when the ring looks full (producer) or empty (consumer). Indices count up without
// wrapping (64 bits), so all `capacity()` slots are usable and full/empty need no spare slot.
//
//   SpscRing<EventBatchPtr> ring(64);
//   producer: if (!ring.try_push(std::move(b))) { /* full: b is untouched */ }
//   consumer: EventBatchPtr b; if (ring.try_pop(b)) { ... }
//
// Exactly one thread may push and exactly one (other or same) thread may pop. size() / empty() may be called from
// any thread and are exact when both sides are quiet.

#include <atomic>
#include <concepts>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <type_traits>

namespace evpipe::runtime {

/// Cache line size assumed for padding (x86-64 and most ARM cores); a constant rather than
/// std::hardware_destructive_interference_size, whose value GCC warns may change between compiler versions.
inline constexpr std::size_t kCacheLineBytes = 64;

/// Smallest power of two >= n (n >= 1).
[[nodiscard]] constexpr std::size_t next_power_of_two(std::size_t n) noexcept {
  std::size_t p = 1;
  while (p < n) p <<= 1;
  return p;
}

template <class T>
requires std::default_initializable<T> && std::is_nothrow_move_assignable_v<T>
class SpscRing {
 public:
  /// Capacity is rounded up to a power of two. Throws std::invalid_argument when min_capacity is 0 or above 2^30.
  explicit SpscRing(std::size_t min_capacity)
      : capacity_(checked_capacity(min_capacity)), mask_(capacity_ - 1), slots_(std::make_unique<T[]>(capacity_)) {}

  SpscRing(const SpscRing&) = delete;
  SpscRing& operator=(const SpscRing&) = delete;

  /// Producer: moves `value` in and returns true, or returns false (value untouched) when the ring is full.
  bool try_push(T&& value) noexcept {
    const std::uint64_t tail = tail_.load(std::memory_order_relaxed);  // only this thread writes tail_
    if (tail - cached_head_ >= capacity_) {
      cached_head_ = head_.load(std::memory_order_acquire);  // slots freed by the consumer are now ours
      if (tail - cached_head_ >= capacity_) return false;
    }
    slots_[tail & mask_] = std::move(value);
    tail_.store(tail + 1, std::memory_order_release);  // publishes the slot to the consumer
    return true;
  }

  /// Consumer: moves the oldest item into `out` and returns true, or returns false when the ring is empty.
  /// The slot is reset to T{} so that it does not keep a shared batch alive.
  bool try_pop(T& out) noexcept {
    const std::uint64_t head = head_.load(std::memory_order_relaxed);  // only this thread writes head_
    if (head == cached_tail_) {
      cached_tail_ = tail_.load(std::memory_order_acquire);
      if (head == cached_tail_) return false;
    }
    T& slot = slots_[head & mask_];
    out = std::move(slot);
    slot = T{};
    head_.store(head + 1, std::memory_order_release);  // hands the slot back to the producer
    return true;
  }

  /// Items in the ring (any thread; a snapshot, exact when both sides are quiet).
  [[nodiscard]] std::size_t size() const noexcept {
    // head first: tail read later is >= the head read (items are pushed before they are popped).
    const std::uint64_t head = head_.load(std::memory_order_acquire);
    const std::uint64_t tail = tail_.load(std::memory_order_acquire);
    const std::uint64_t n = tail - head;
    return static_cast<std::size_t>(n > capacity_ ? capacity_ : n);
  }
  [[nodiscard]] bool empty() const noexcept { return size() == 0; }
  [[nodiscard]] std::size_t capacity() const noexcept { return capacity_; }
  /// Items ever pushed / popped (any thread).
  [[nodiscard]] std::uint64_t pushed() const noexcept { return tail_.load(std::memory_order_acquire); }
  [[nodiscard]] std::uint64_t popped() const noexcept { return head_.load(std::memory_order_acquire); }

 private:
  static std::size_t checked_capacity(std::size_t n) {
    if (n == 0 || n > (std::size_t{1} << 30)) throw std::invalid_argument("SpscRing: capacity must be in [1, 2^30]");
    return next_power_of_two(n);
  }

  const std::size_t capacity_;
  const std::size_t mask_;
  std::unique_ptr<T[]> slots_;
  // Producer line: its index and its copy of the consumer's index.
  alignas(kCacheLineBytes) std::atomic<std::uint64_t> tail_{0};
  std::uint64_t cached_head_ = 0;
  // Consumer line.
  alignas(kCacheLineBytes) std::atomic<std::uint64_t> head_{0};
  std::uint64_t cached_tail_ = 0;
  // Keeps the consumer line from sharing a cache line with whatever follows this object.
  [[maybe_unused]] char pad_[kCacheLineBytes - sizeof(std::atomic<std::uint64_t>) - sizeof(std::uint64_t)]{};
};

}  // namespace evpipe::runtime
