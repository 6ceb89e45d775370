#pragma once
// An EventSource over batches already in memory (pipeline and pacing tests).

#include <utility>
#include <vector>

#include "evpipe/core/source.hpp"

namespace evpipe::testing {

class VectorSource final : public EventSource {
 public:
  explicit VectorSource(std::vector<EventBatchPtr> batches) : batches_(std::move(batches)) {
    info_.name = "vector";
    info_.geometry = kDavis346;
  }
  EventBatchPtr next() override {
    if (i_ >= batches_.size()) return nullptr;
    stats_.events += batches_[i_]->size();
    ++stats_.batches;
    return batches_[i_++];
  }
  [[nodiscard]] bool finished() const override { return i_ >= batches_.size(); }
  [[nodiscard]] const SourceInfo& info() const override { return info_; }
  [[nodiscard]] const SourceStats& stats() const override { return stats_; }

 private:
  std::vector<EventBatchPtr> batches_;
  std::size_t i_ = 0;
  SourceInfo info_;
  SourceStats stats_;
};

}  // namespace evpipe::testing
