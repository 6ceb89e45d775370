#pragma once
// Filters in series: an event is kept only if every stage keeps it; a stage sees only the events the stages
// before it kept (so a hot-pixel filter in front of a density filter removes hot pixels from its neighbourhoods).

#include <deque>
#include <memory>
#include <string>
#include <vector>

#include "evpipe/denoise/filter.hpp"

namespace evpipe::denoise {

class FilterChain final : public Filter {
 public:
  explicit FilterChain(std::vector<std::unique_ptr<Filter>> stages);

  [[nodiscard]] std::string_view name() const noexcept override { return name_; }
  void push(EventSpan events, Decisions& out) override;
  void finish(Decisions& out) override;
  void reset() override;
  [[nodiscard]] std::size_t pending() const noexcept override { return entries_.size(); }
  [[nodiscard]] std::int64_t latency_us() const noexcept override;
  /// The last stage's score for events that reached it; events an earlier stage dropped score lowest.
  [[nodiscard]] bool has_score() const noexcept override;
  /// Every stage's items, prefixed "<stage>.".
  [[nodiscard]] std::vector<ReportItem> report() const override;
  /// Passed on to every stage.
  void set_parallelism(int tasks, TaskRunner runner) override;

  [[nodiscard]] const std::vector<std::unique_ptr<Filter>>& stages() const noexcept { return stages_; }

 private:
  // One entry per input event not yet decided: the stage it waits at (stages_.size() = kept by all) or dropped.
  struct Entry {
    Event event;
    std::uint32_t stage = 0;
    bool dropped = false;
    float score = 0.0F;
  };
  void feed(std::size_t stage, EventSpan events);
  void collect(std::size_t stage, const Decisions& d);
  void emit(Decisions& out);

  std::vector<std::unique_ptr<Filter>> stages_;
  std::string name_;
  std::deque<Entry> entries_;
  // Per stage: indices (into entries_, offset by popped_) of events pushed to that stage and not yet decided.
  std::vector<std::deque<std::uint64_t>> waiting_;
  std::uint64_t popped_ = 0;  // entries removed from the front of entries_ so far
  Decisions scratch_;
  std::vector<Event> batch_;
};

}  // namespace evpipe::denoise
