#pragma once
// Shared body of the reader fuzz targets: feed the input to one reader through memory_source and drain
// it. A FormatError / SourceError is the expected answer to bad input; anything else escaping, a crash,
// a leak, UB, or a broken reader invariant (checked below, trapping) is a finding.

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <span>

#include "evpipe/io/reader.hpp"

namespace evpipe::fuzz {

[[noreturn]] inline void invariant_broken() {
  __builtin_trap();
}

template <typename Make>
int run_reader(Make make, const std::uint8_t* data, std::size_t size) {
  io::ReaderOptions options;
  // Small batches exercise batch splitting and discontinuity carry-over even on small inputs; the other
  // options vary with the input length so that each policy gets covered.
  options.batch_events = 1 + size % 61;
  options.out_of_order = (size & 1) != 0 ? io::OutOfOrderPolicy::keep : io::OutOfOrderPolicy::drop;
  options.aedat2_flip_x = (size & 2) != 0;
  options.aedat2_flip_y = (size & 4) == 0;
  options.discontinuity_us = (size & 8) != 0 ? 1'000 : 1'000'000;
  try {
    auto reader =
        make(io::memory_source(std::span(reinterpret_cast<const std::byte*>(data), size), "fuzz-input"), options);
    const SensorGeometry g = reader->info().geometry;
    std::uint64_t events = 0;
    std::optional<std::int64_t> last_t;
    while (auto batch = reader->next()) {
      if (batch->empty()) invariant_broken();  // next() returns nullptr rather than an empty batch
      if (batch->labelled() && batch->labels.size() != batch->events.size()) invariant_broken();
      if (batch->labelled() != reader->info().labelled) invariant_broken();
      if (batch->discontinuity_before) last_t.reset();
      for (const Event& e : batch->events) {
        if (!g.contains(e.x, e.y)) invariant_broken();
        // With the drop policy, time never goes back inside a segment.
        if (options.out_of_order == io::OutOfOrderPolicy::drop && last_t && e.t_us < *last_t) invariant_broken();
        last_t = e.t_us;
      }
      events += batch->size();
    }
    if (events != reader->stats().events) invariant_broken();
    if (!reader->finished()) invariant_broken();
    if (reader->next() != nullptr) invariant_broken();
  } catch (const SourceError&) {
    // FormatError and I/O errors: the documented outcome for bad input.
  }
  return 0;
}

}  // namespace evpipe::fuzz
