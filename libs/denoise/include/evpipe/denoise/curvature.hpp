#pragma once
// The paper's filter (Yang et al. 2025, sections 3.1–3.2): spherical spatio-temporal density, then the
// curvature consistency of a local quadric fit. Registered as `curvature`; every interpretation of the
// paper is documented in docs/algorithms.md ("Denoising: the paper's curvature filter").
//
// Per event: ρ = 1 + number of other events in the ball (sphere.hpp). ρ < ρ_TH → noise. Otherwise fit the
// quadric over the ball (quadric.hpp): a rank-deficient fit has no curvature (dropped, or kept with
// singular=keep); the others form the population of their block (absolute blocks of window_us), and the
// keep_fraction of it with the most consistent curvature 4ab − c² is kept (selection.hpp).
//
//   CurvatureFilter f(CurvatureOptions{}, kDavis346);   // stream mode, grid index, paper parameters
//   Decisions d = run_filter(f, events);

#include <cstdint>
#include <memory>
#include <vector>

#include "evpipe/core/event.hpp"
#include "evpipe/denoise/curvature_options.hpp"
#include "evpipe/denoise/filter.hpp"
#include "evpipe/denoise/registry.hpp"
#include "evpipe/denoise/sphere.hpp"

namespace evpipe::denoise {

/// What happened to an event (in CurvatureTrace).
enum class CurvatureStatus : std::uint8_t {
  outside,       ///< outside the sensor: dropped
  density_fail,  ///< ρ < ρ_TH: dropped
  density_only,  ///< passed density, curvature stage off: kept
  undefined,     ///< passed density, singular fit: dropped (reject) or kept (keep)
  selected,      ///< curvature consistent: kept
  not_selected,  ///< curvature outside the kept share: dropped
};

/// Per-event diagnostics in decision order (tests, evdenoise diagnostics). Optional per-site statistics.
struct CurvatureTrace {
  bool with_sites = false;  ///< set before the run to also record counts/sums
  std::vector<std::int32_t> rho;
  std::vector<CurvatureStatus> status;
  std::vector<double> curvature;     ///< 4ab − c² (0 when not fitted)
  std::vector<std::int32_t> counts;  ///< with_sites: sphere.size() per event
  std::vector<std::int64_t> sums_dt;
  void clear() {
    rho.clear();
    status.clear();
    curvature.clear();
    counts.clear();
    sums_dt.clear();
  }
};

class CurvatureFilter final : public Filter {
 public:
  /// Throws std::invalid_argument for invalid options (validate()).
  CurvatureFilter(const CurvatureOptions& options, const SensorGeometry& geometry);
  ~CurvatureFilter() override;

  [[nodiscard]] std::string_view name() const noexcept override { return "curvature"; }
  void push(EventSpan events, Decisions& out) override;
  void finish(Decisions& out) override;
  void reset() override;
  [[nodiscard]] std::size_t pending() const noexcept override;
  /// frames: window_us; stream: window_us + reach; causal: 0.
  [[nodiscard]] std::int64_t latency_us() const noexcept override;
  [[nodiscard]] bool has_score() const noexcept override { return true; }
  /// density_passed, curvature_undefined, curvature_dropped, blocks, noise_rate_hz, density_threshold_used,
  /// latency_us.
  [[nodiscard]] std::vector<ReportItem> report() const override;
  /// Grid backend, frames / stream: each block is cut into `tasks` row bands of about equal event counts, indexed
  /// and fitted as separate tasks (the selection stays one step per block). Decisions are identical for any
  /// count. Call between pushes. The other modes and the FLANN backend stay in one task.
  void set_parallelism(int tasks, TaskRunner runner) override;

  /// Records per-event diagnostics into `trace` (nullptr = off). The trace is appended in decision order.
  void set_trace(CurvatureTrace* trace) noexcept;
  [[nodiscard]] const Sphere& sphere() const noexcept;
  [[nodiscard]] const CurvatureOptions& options() const noexcept;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The reference: ONE FLANN index over the whole recording, every event decided with the options' mode
/// semantics (stream: the full ball, whatever the block borders). Equals CurvatureFilter's decisions for any
/// backend and any cutting of the input into pushes.
Decisions curvature_batch(EventSpan all_events, const CurvatureOptions& options, const SensorGeometry& geometry,
                          CurvatureTrace* trace = nullptr);

/// Reads the options from KEY=VALUE parameters (throws std::invalid_argument naming the key).
CurvatureOptions curvature_options_from(Params& params);
FilterSpec curvature_spec();

}  // namespace evpipe::denoise
