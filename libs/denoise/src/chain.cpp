#include "evpipe/denoise/chain.hpp"

#include <fmt/format.h>

#include <limits>
#include <stdexcept>

namespace evpipe::denoise {

namespace {
// Score of an event an earlier stage dropped: below anything the last stage can give.
constexpr float kDroppedEarlier = -std::numeric_limits<float>::max();
}  // namespace

FilterChain::FilterChain(std::vector<std::unique_ptr<Filter>> stages) : stages_(std::move(stages)) {
  if (stages_.empty()) {
    throw std::invalid_argument("a filter chain needs at least one filter");
  }
  std::vector<std::string_view> names;
  for (const auto& s : stages_) {
    names.push_back(s->name());
  }
  name_ = fmt::format("{}", fmt::join(names, ","));
  waiting_.resize(stages_.size());
}

bool FilterChain::has_score() const noexcept {
  return stages_.back()->has_score();
}

std::int64_t FilterChain::latency_us() const noexcept {
  std::int64_t total = 0;
  for (const auto& s : stages_) {
    total += s->latency_us();
  }
  return total;
}

void FilterChain::feed(std::size_t stage, EventSpan events) {
  if (events.empty()) {
    return;
  }
  Decisions d;
  stages_[stage]->push(events, d);
  collect(stage, d);
}

// Applies the decisions `d` of `stage` to its oldest waiting events and feeds the kept ones to the next stage.
void FilterChain::collect(std::size_t stage, const Decisions& d) {
  const bool last = stage + 1 == stages_.size();
  std::vector<Event> next;
  for (std::size_t k = 0; k < d.size(); ++k) {
    const std::uint64_t index = waiting_[stage].front();
    waiting_[stage].pop_front();
    Entry& entry = entries_[static_cast<std::size_t>(index - popped_)];
    if (last && !d.score.empty()) {
      entry.score = d.score[k];
    }
    if (d.keep[k] == 0) {
      entry.dropped = true;
      continue;
    }
    entry.stage = static_cast<std::uint32_t>(stage + 1);
    if (!last) {
      waiting_[stage + 1].push_back(index);
      next.push_back(entry.event);
    }
  }
  if (!last) {
    feed(stage + 1, next);
  }
}

void FilterChain::emit(Decisions& out) {
  const bool scored = has_score();
  while (!entries_.empty()) {
    const Entry& e = entries_.front();
    const bool done = e.dropped || e.stage == stages_.size();
    if (!done) {
      break;
    }
    out.keep.push_back(e.dropped ? 0 : 1);
    if (scored) {
      out.score.push_back(e.score);
    }
    entries_.pop_front();
    ++popped_;
  }
}

void FilterChain::push(EventSpan events, Decisions& out) {
  const std::uint64_t first = popped_ + entries_.size();
  for (std::size_t i = 0; i < events.size(); ++i) {
    entries_.push_back({events[i], 0, false, kDroppedEarlier});
    waiting_[0].push_back(first + i);
  }
  feed(0, events);
  emit(out);
}

void FilterChain::finish(Decisions& out) {
  for (std::size_t s = 0; s < stages_.size(); ++s) {
    Decisions d;
    stages_[s]->finish(d);
    collect(s, d);
  }
  emit(out);
}

void FilterChain::reset() {
  for (auto& s : stages_) {
    s->reset();
  }
  entries_.clear();
  for (auto& w : waiting_) {
    w.clear();
  }
}

void FilterChain::set_parallelism(int tasks, TaskRunner runner) {
  for (auto& s : stages_) s->set_parallelism(tasks, runner);
}

std::vector<ReportItem> FilterChain::report() const {
  std::vector<ReportItem> all;
  for (const auto& s : stages_) {
    for (auto item : s->report()) {
      item.key = fmt::format("{}.{}", s->name(), item.key);
      all.push_back(std::move(item));
    }
  }
  return all;
}

}  // namespace evpipe::denoise
