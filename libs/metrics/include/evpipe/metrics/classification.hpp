#pragma once
// A denoiser's keep/drop decisions scored against labels (signal = positive, "keep" = predicted signal):
//
//   TP = signal kept      FN = signal removed      TN = noise removed      FP = noise kept
//   SR  = TP / (TP + FN)          signal retention = TPR (denoise.md §7.2)
//   NR  = TN / (TN + FP)          noise removed among the noise = TNR (§7.3)
//   precision = TP / (TP + FP),   F1 = 2 TP / (2 TP + FP + FN)
//   NRR = removed / input         the paper's noise-reduction rate (§4.1; on pure noise it equals NR)
//
// Ratios with a zero denominator are nullopt ("n/a"), never 0 or 1.

#include <cstdint>
#include <optional>
#include <span>

#include "evpipe/core/event.hpp"

namespace evpipe::metrics {

struct Confusion {
  std::uint64_t tp = 0;
  std::uint64_t fp = 0;
  std::uint64_t tn = 0;
  std::uint64_t fn = 0;

  [[nodiscard]] std::uint64_t signal() const noexcept { return tp + fn; }
  [[nodiscard]] std::uint64_t noise() const noexcept { return tn + fp; }
  friend bool operator==(const Confusion&, const Confusion&) = default;
};

[[nodiscard]] std::optional<double> signal_retention(const Confusion& c) noexcept;  ///< SR = TPR
[[nodiscard]] std::optional<double> noise_removal(const Confusion& c) noexcept;     ///< NR = TNR
[[nodiscard]] std::optional<double> precision(const Confusion& c) noexcept;
[[nodiscard]] std::optional<double> f1(const Confusion& c) noexcept;

/// Counts of a run, labelled or not.
struct Classification {
  std::uint64_t events_in = 0;
  std::uint64_t events_kept = 0;
  /// Present when every event added carried a label.
  std::optional<Confusion> confusion;

  [[nodiscard]] std::uint64_t events_removed() const noexcept { return events_in - events_kept; }
  /// NRR = removed / input; nullopt for an empty input.
  [[nodiscard]] std::optional<double> nrr() const noexcept;
  [[nodiscard]] std::optional<double> kept_fraction() const noexcept;
};

/// Streaming counter over decisions (1 = keep) and, optionally, their events' labels.
class ClassificationCounter {
 public:
  /// `labels` is empty (unlabelled: the result then has no confusion matrix) or one per decision; throws
  /// std::invalid_argument otherwise.
  void add(std::span<const std::uint8_t> keep, std::span<const Label> labels = {});
  [[nodiscard]] const Classification& result() const noexcept { return result_; }
  void reset() noexcept { *this = ClassificationCounter{}; }

 private:
  Classification result_{0, 0, Confusion{}};
};

/// One-shot version.
[[nodiscard]] Classification classify(std::span<const std::uint8_t> keep, std::span<const Label> labels = {});

}  // namespace evpipe::metrics
