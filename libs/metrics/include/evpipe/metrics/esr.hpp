#pragma once
// ESR, the event structural ratio of E-MLB (Ding et al., IEEE TMM 2023), exactly as the authors' CUKE code
// computes it (`EventStructuralRatio`, evalEventStorePerNumber; ../shared/reference/denoise.md §6):
//
//   the stream is cut into consecutive blocks of exactly N = 30 000 events (a remainder < N is dropped);
//   per block, with n_i the events at pixel i (polarity ignored) over all K = W·H pixels and M = floor(2N/3):
//     NTSS = Σ n_i (n_i − 1) / (N (N − 1))
//     L    = K − Σ (1 − M/N)^n_i                (= Σ over non-empty pixels of 1 − (1 − M/N)^n_i)
//     ESR  = sqrt(NTSS · L)
//   the result is the mean over blocks; with fewer than N events it is undefined ("n/a", never 0.5).
//
// Computed in double (the reference's float32 differs by < 4e-6). ESR is not bounded by 1 and grows with
// bursty (hot) pixels; it measures structure, not signal retention.
//
//   EsrAccumulator esr(kDavis346);
//   esr.add(batch.span());  // any number of pieces
//   if (auto m = esr.mean()) ...

#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "evpipe/core/event.hpp"

namespace evpipe::metrics {

/// E-MLB's block size (CUKE's `interval`); fixed for the paper metric.
inline constexpr std::size_t kEsrChunkEvents = 30'000;

/// ESR of one block from its per-pixel counts: `counts` holds n_i of the non-empty pixels only (empty pixels
/// add 0 to both sums), `events` = N = Σ n_i, `pixels` = K. Needs N ≥ 2.
[[nodiscard]] double esr_of_counts(std::span<const std::uint32_t> counts, std::size_t events, std::size_t pixels);

/// Streaming ESR: memory is one count per pixel plus one value per finished block.
class EsrAccumulator {
 public:
  /// `chunk_events` is N (E-MLB: 30 000; other values only for experiments). Throws std::invalid_argument for
  /// N < 3 or an empty geometry.
  explicit EsrAccumulator(const SensorGeometry& geometry, std::size_t chunk_events = kEsrChunkEvents);

  /// Adds time-ordered events. Events outside the geometry are not counted (counted in outside()).
  void add(EventSpan events);
  void add(const Event& e);

  /// Mean over the finished blocks; nullopt before the first block is complete.
  [[nodiscard]] std::optional<double> mean() const;
  /// ESR of each finished block, in stream order.
  [[nodiscard]] const std::vector<double>& chunk_values() const noexcept { return chunks_; }
  [[nodiscard]] std::size_t chunks() const noexcept { return chunks_.size(); }
  /// Events in the current, unfinished block (dropped if the stream ends here).
  [[nodiscard]] std::size_t remainder() const noexcept { return in_chunk_; }
  /// Events counted (in blocks or in the remainder) and events ignored for lying outside the sensor.
  [[nodiscard]] std::uint64_t events() const noexcept { return events_; }
  [[nodiscard]] std::uint64_t outside() const noexcept { return outside_; }
  [[nodiscard]] std::size_t chunk_events() const noexcept { return chunk_events_; }

  /// Starts afresh (no blocks, empty count map).
  void reset();

 private:
  void close_chunk();

  SensorGeometry geometry_;
  std::size_t chunk_events_;
  std::vector<std::uint32_t> count_;    // per pixel, row-major
  std::vector<std::uint32_t> touched_;  // pixels with count_ > 0 in the current block
  std::vector<std::uint32_t> scratch_;  // counts of touched_ at block end
  std::size_t in_chunk_ = 0;
  std::uint64_t events_ = 0;
  std::uint64_t outside_ = 0;
  std::vector<double> chunks_;
};

struct EsrResult {
  std::optional<double> mean;  ///< nullopt when fewer than N events
  std::vector<double> chunks;  ///< per block
};

/// One-shot ESR of a whole stream.
[[nodiscard]] EsrResult esr(EventSpan events, const SensorGeometry& geometry,
                            std::size_t chunk_events = kEsrChunkEvents);

}  // namespace evpipe::metrics
