#pragma once
// ROC AUC of per-event scores (higher = more signal-like) against labels: the probability that a random signal
// event scores above a random noise event, ties counting one half (the Mann–Whitney U statistic / (P·N), which
// equals the trapezoidal area under the ROC curve through every threshold). Exact: counts are integers and the
// final ratio is the only rounding.
//
//   AucAccumulator auc;
//   auc.add(decisions.score, batch.labels);
//   if (auto a = auc.auc()) ...
//
// Memory is O(distinct scores): scores are binned exactly (one bin per distinct value, counts per class) in a
// sorted table, merged from a bounded buffer.

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "evpipe/core/event.hpp"

namespace evpipe::metrics {

class AucAccumulator {
 public:
  /// `scores` and `labels` have the same length (else std::invalid_argument). A NaN score counts as the lowest
  /// possible score (-infinity); -0 equals +0.
  void add(std::span<const float> scores, std::span<const Label> labels);
  void add(float score, Label label);

  /// Nullopt when one class is absent (AUC undefined).
  [[nodiscard]] std::optional<double> auc();
  [[nodiscard]] std::uint64_t signal() const noexcept { return signal_; }
  [[nodiscard]] std::uint64_t noise() const noexcept { return noise_; }
  /// Distinct scores seen (after merging the buffer).
  [[nodiscard]] std::size_t distinct_scores();
  void reset();

 private:
  struct Bin {
    float score;
    std::uint64_t signal;
    std::uint64_t noise;
  };
  void merge_buffer();

  std::vector<Bin> bins_;  // sorted by score, one per distinct score
  std::vector<std::pair<float, Label>> buffer_;
  std::vector<Bin> scratch_;
  std::uint64_t signal_ = 0;
  std::uint64_t noise_ = 0;
};

/// One-shot AUC.
[[nodiscard]] std::optional<double> roc_auc(std::span<const float> scores, std::span<const Label> labels);

}  // namespace evpipe::metrics
