#include "evpipe/metrics/esr.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>
#include <string>

namespace evpipe::metrics {

double esr_of_counts(std::span<const std::uint32_t> counts, std::size_t events, std::size_t pixels) {
  if (events < 2) {
    throw std::invalid_argument("esr_of_counts: a block needs at least 2 events, got " + std::to_string(events));
  }
  const std::size_t thinned = events * 2 / 3;  // M = floor(2N/3)
  // 1 − M/N as the reference forms it in double (0.33333333333333337 for N = 30 000).
  const double q = 1.0 - static_cast<double>(thinned) / static_cast<double>(events);
  // q^n for the small counts that make up nearly every pixel of a block, computed once with the same pow.
  constexpr std::size_t kTable = 64;
  std::array<double, kTable> q_pow{};
  for (std::size_t n = 0; n < kTable; ++n) {
    q_pow[n] = std::pow(q, static_cast<double>(n));
  }
  std::uint64_t pairs = 0;  // Σ n(n − 1): exact in 64 bits for any block that fits in memory
  double occupied = 0.0;    // Σ over non-empty pixels of 1 − q^n  (= K − Σ over all pixels of q^n)
  std::size_t total = 0;
  for (const std::uint32_t n : counts) {
    pairs += std::uint64_t{n} * (std::uint64_t{n} - (n > 0 ? 1 : 0));
    occupied += 1.0 - (n < kTable ? q_pow[n] : std::pow(q, static_cast<double>(n)));
    total += n;
  }
  if (total != events || counts.size() > pixels) {
    throw std::invalid_argument("esr_of_counts: counts sum to " + std::to_string(total) + " over " +
                                std::to_string(counts.size()) + " pixels, expected " + std::to_string(events) +
                                " events over at most " + std::to_string(pixels));
  }
  const double n = static_cast<double>(events);
  const double ntss = static_cast<double>(pairs) / (n * (n - 1.0));
  return std::sqrt(ntss * occupied);
}

EsrAccumulator::EsrAccumulator(const SensorGeometry& geometry, std::size_t chunk_events)
    : geometry_(geometry), chunk_events_(chunk_events) {
  if (chunk_events_ < 3) {
    throw std::invalid_argument("ESR: a block needs at least 3 events, got " + std::to_string(chunk_events_));
  }
  if (geometry_.width <= 0 || geometry_.height <= 0) {
    throw std::invalid_argument("ESR: empty sensor geometry " + std::to_string(geometry_.width) + "x" +
                                std::to_string(geometry_.height));
  }
  count_.assign(geometry_.pixels(), 0);
  touched_.reserve(std::min(chunk_events_, geometry_.pixels()));
}

void EsrAccumulator::add(const Event& e) {
  if (!geometry_.contains(e.x, e.y)) {
    ++outside_;
    return;
  }
  const std::uint32_t pixel = static_cast<std::uint32_t>(e.y) * static_cast<std::uint32_t>(geometry_.width) + e.x;
  if (count_[pixel]++ == 0) {
    touched_.push_back(pixel);
  }
  ++events_;
  if (++in_chunk_ == chunk_events_) {
    close_chunk();
  }
}

void EsrAccumulator::add(EventSpan events) {
  for (const Event& e : events) {
    add(e);
  }
}

void EsrAccumulator::close_chunk() {
  scratch_.clear();
  for (const std::uint32_t pixel : touched_) {
    scratch_.push_back(count_[pixel]);
    count_[pixel] = 0;  // clearing only the touched pixels keeps a block O(N), not O(K)
  }
  touched_.clear();
  chunks_.push_back(esr_of_counts(scratch_, in_chunk_, geometry_.pixels()));
  in_chunk_ = 0;
}

std::optional<double> EsrAccumulator::mean() const {
  if (chunks_.empty()) {
    return std::nullopt;
  }
  double sum = 0.0;
  for (const double v : chunks_) {
    sum += v;
  }
  return sum / static_cast<double>(chunks_.size());
}

void EsrAccumulator::reset() {
  for (const std::uint32_t pixel : touched_) {
    count_[pixel] = 0;
  }
  touched_.clear();
  in_chunk_ = 0;
  events_ = 0;
  outside_ = 0;
  chunks_.clear();
}

EsrResult esr(EventSpan events, const SensorGeometry& geometry, std::size_t chunk_events) {
  EsrAccumulator acc(geometry, chunk_events);
  acc.add(events);
  return {acc.mean(), acc.chunk_values()};
}

}  // namespace evpipe::metrics
