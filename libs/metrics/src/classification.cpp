#include "evpipe/metrics/classification.hpp"

#include <stdexcept>
#include <string>

namespace evpipe::metrics {

namespace {
std::optional<double> ratio(std::uint64_t num, std::uint64_t den) noexcept {
  if (den == 0) {
    return std::nullopt;
  }
  return static_cast<double>(num) / static_cast<double>(den);
}
}  // namespace

std::optional<double> signal_retention(const Confusion& c) noexcept {
  return ratio(c.tp, c.tp + c.fn);
}
std::optional<double> noise_removal(const Confusion& c) noexcept {
  return ratio(c.tn, c.tn + c.fp);
}
std::optional<double> precision(const Confusion& c) noexcept {
  return ratio(c.tp, c.tp + c.fp);
}
std::optional<double> f1(const Confusion& c) noexcept {
  return ratio(2 * c.tp, 2 * c.tp + c.fp + c.fn);
}

std::optional<double> Classification::nrr() const noexcept {
  return ratio(events_removed(), events_in);
}
std::optional<double> Classification::kept_fraction() const noexcept {
  return ratio(events_kept, events_in);
}

void ClassificationCounter::add(std::span<const std::uint8_t> keep, std::span<const Label> labels) {
  if (!labels.empty() && labels.size() != keep.size()) {
    throw std::invalid_argument("classification: " + std::to_string(labels.size()) + " labels for " +
                                std::to_string(keep.size()) + " decisions");
  }
  std::uint64_t kept = 0;
  for (const std::uint8_t k : keep) {
    kept += k != 0 ? 1 : 0;
  }
  result_.events_in += keep.size();
  result_.events_kept += kept;
  if (!result_.confusion || keep.empty()) {
    return;
  }
  if (labels.empty()) {
    result_.confusion.reset();  // part of the stream is unlabelled: no confusion matrix for the whole
    return;
  }
  Confusion& c = *result_.confusion;
  for (std::size_t i = 0; i < keep.size(); ++i) {
    const bool signal = labels[i] == Label::signal;
    const bool kept_i = keep[i] != 0;
    c.tp += signal && kept_i ? 1 : 0;
    c.fn += signal && !kept_i ? 1 : 0;
    c.fp += !signal && kept_i ? 1 : 0;
    c.tn += !signal && !kept_i ? 1 : 0;
  }
}

Classification classify(std::span<const std::uint8_t> keep, std::span<const Label> labels) {
  ClassificationCounter counter;
  counter.add(keep, labels);
  return counter.result();
}

}  // namespace evpipe::metrics
