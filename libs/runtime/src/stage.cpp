#include "evpipe/runtime/stage.hpp"

namespace evpipe::runtime {

std::string_view policy_name(QueuePolicy policy) noexcept {
  switch (policy) {
    case QueuePolicy::block:
      return "block";
    case QueuePolicy::drop_newest:
      return "drop_newest";
    case QueuePolicy::latest_wins:
      return "latest_wins";
  }
  return "?";
}

std::string_view state_name(StageState state) noexcept {
  switch (state) {
    case StageState::idle:
      return "idle";
    case StageState::running:
      return "running";
    case StageState::finished:
      return "finished";
    case StageState::cancelled:
      return "cancelled";
    case StageState::failed:
      return "failed";
  }
  return "?";
}

StageStats StageMetrics::snapshot() const {
  StageStats s;
  s.name = name_;
  s.state = state.load(std::memory_order_acquire);
  s.items_in = items_in.load(std::memory_order_relaxed);
  s.items_out = items_out.load(std::memory_order_relaxed);
  s.events_in = events_in.load(std::memory_order_relaxed);
  s.events_out = events_out.load(std::memory_order_relaxed);
  s.items_dropped = items_dropped.load(std::memory_order_relaxed);
  s.events_dropped = events_dropped.load(std::memory_order_relaxed);
  s.heartbeat = heartbeat.load(std::memory_order_relaxed);
  s.step_ns = step_ns.summary();
  return s;
}

}  // namespace evpipe::runtime
