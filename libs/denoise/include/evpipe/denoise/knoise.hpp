#pragma once
// KNoise (Khodamoradi & Kastner, "O(N)-space spatiotemporal filter for reducing noise in neuromorphic vision
// sensors", IEEE TETC 2018): O(W + H) memory. Each column x remembers its last event (t, y, p) and each row y its
// last event (t, x, p); an event is supported by the cells of columns x−1..x+1 whose row is within 1 of y, and
// by the cells of rows y−1..y+1 whose column is within 1 of x, when the polarity matches and t − c.t ≤ duration
// (inclusive). The event then overwrites its column and row cells, kept or not.
//
// variant dv (default) = dv-processing 2.0.4 dv::noise::KNoiseFilter, the paper's baseline (1 000 µs, one
// supporter): cells start at (t = 0, coordinate 0, OFF), so OFF events near row/column 0 with t ≤ duration are
// supported at the start of a stream (start-up artefact), and the own pixel's previous event counts (through
// col[x] with the same y, or row[y] with the same x).
// variant cuke = CUKE (cuke-emlb khodamoradi_noise.hpp): identical except that the own pixel never supports.
//
// `supporters` is the number of supporting cells needed (dv-processing: 1). Each of the six cells counts once,
// so one neighbour event can count twice (as its column's and its row's last event), as in CUKE.

#include <cstdint>
#include <vector>

#include "evpipe/core/event.hpp"
#include "evpipe/denoise/registry.hpp"

namespace evpipe::denoise {

struct KnoiseOptions {
  enum class Variant : std::uint8_t { dv, cuke };
  std::int64_t duration_us = 1000;
  int supporters = 1;
  Variant variant = Variant::dv;
};

class Knoise {
 public:
  Knoise(const SensorGeometry& geometry, KnoiseOptions options);
  [[nodiscard]] bool accept(const Event& e) noexcept;
  /// Number of supporting cells (0..6; higher = more signal-like).
  [[nodiscard]] float last_score() const noexcept { return score_; }
  void reset() noexcept;

 private:
  // Columns and rows in the same layout: index i + 1 holds column/row i, index 0 and the last two are padding
  // that never supports (t = "never"). (Loading the three cells as one SIMD vector was measured no faster: the
  // cells were usually just written by the previous events, and a wide load of a fresh narrow store stalls.) The last
  // event of a column is stored as key = 2·y + polarity, of a row as 2·x + polarity: "coordinate within 1 and same
  // polarity" is then key − our key ∈ {−2, 0, 2}.
  struct Lines {
    std::vector<std::int64_t> t_us;
    std::vector<std::int32_t> key;
  };
  /// Supporting cells among the three of `lines` starting at index `first` (our line − 1 + padding offset).
  [[nodiscard]] int count3(const Lines& lines, std::size_t first, std::int32_t key,
                           std::int64_t oldest_us) const noexcept;

  SensorGeometry geometry_;
  KnoiseOptions options_;
  Lines cols_;
  Lines rows_;
  float score_ = 0.0F;
};

FilterSpec knoise_spec();

}  // namespace evpipe::denoise
