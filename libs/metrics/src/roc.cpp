#include "evpipe/metrics/roc.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace evpipe::metrics {

namespace {
constexpr std::size_t kMinBuffer = 1 << 16;

float canonical(float score) noexcept {
  if (std::isnan(score)) {
    return -std::numeric_limits<float>::infinity();
  }
  return score == 0.0F ? 0.0F : score;  // -0 → +0, so that equal scores share one bin
}

// 128-bit unsigned integer for the exact rank sum (P·N can exceed 2^64 / 2 for long recordings).
__extension__ using U128 = unsigned __int128;
}  // namespace

void AucAccumulator::add(float score, Label label) {
  buffer_.emplace_back(canonical(score), label);
  if (label == Label::signal) {
    ++signal_;
  } else {
    ++noise_;
  }
  // Merging when the buffer outgrows the table keeps the work amortised O(log) per event and memory
  // O(distinct scores + buffer).
  if (buffer_.size() >= std::max(kMinBuffer, bins_.size())) {
    merge_buffer();
  }
}

void AucAccumulator::add(std::span<const float> scores, std::span<const Label> labels) {
  if (scores.size() != labels.size()) {
    throw std::invalid_argument("ROC AUC: " + std::to_string(scores.size()) + " scores for " +
                                std::to_string(labels.size()) + " labels");
  }
  for (std::size_t i = 0; i < scores.size(); ++i) {
    add(scores[i], labels[i]);
  }
}

void AucAccumulator::merge_buffer() {
  if (buffer_.empty()) {
    return;
  }
  std::sort(buffer_.begin(), buffer_.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  scratch_.clear();
  scratch_.reserve(bins_.size() + buffer_.size());
  auto old = bins_.begin();
  auto append = [this](const Bin& b) {
    if (!scratch_.empty() && scratch_.back().score == b.score) {
      scratch_.back().signal += b.signal;
      scratch_.back().noise += b.noise;
    } else {
      scratch_.push_back(b);
    }
  };
  for (const auto& [score, label] : buffer_) {
    while (old != bins_.end() && old->score < score) {
      append(*old++);
    }
    append({score, label == Label::signal ? 1U : 0U, label == Label::signal ? 0U : 1U});
  }
  while (old != bins_.end()) {
    append(*old++);
  }
  bins_.swap(scratch_);
  buffer_.clear();
}

std::optional<double> AucAccumulator::auc() {
  if (signal_ == 0 || noise_ == 0) {
    return std::nullopt;
  }
  merge_buffer();
  // 2·U = Σ over signal events of (2·noise below + noise tied), in ascending score order.
  U128 twice_u = 0;
  std::uint64_t noise_below = 0;
  for (const Bin& b : bins_) {
    twice_u += U128{b.signal} * (U128{2} * noise_below + b.noise);
    noise_below += b.noise;
  }
  const U128 twice_pairs = U128{2} * signal_ * noise_;
  return static_cast<double>(static_cast<long double>(twice_u) / static_cast<long double>(twice_pairs));
}

std::size_t AucAccumulator::distinct_scores() {
  merge_buffer();
  return bins_.size();
}

void AucAccumulator::reset() {
  bins_.clear();
  buffer_.clear();
  signal_ = 0;
  noise_ = 0;
}

std::optional<double> roc_auc(std::span<const float> scores, std::span<const Label> labels) {
  AucAccumulator acc;
  acc.add(scores, labels);
  return acc.auc();
}

}  // namespace evpipe::metrics
