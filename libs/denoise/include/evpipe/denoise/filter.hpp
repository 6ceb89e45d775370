#pragma once
// The denoising filter interface shared by evdenoise, the benchmarks and the live pipeline.
//
// A filter sees time-ordered events in pushes of any size and returns one keep/drop decision per event, in
// input order. Causal filters (BAF, KNoise, ...) decide each event on arrival through one noexcept per-event
// function (PerEventFilter below); filters that look ahead in time (curvature in `stream` mode) decide later
// and say so through pending() and latency_us(). Decisions never depend on how the stream was cut into pushes.
//
//   auto f = evpipe::denoise::make_filter("baf", {}, evpipe::kDavis346);
//   Decisions d;
//   f->push(batch.span(), d);   // d.keep[i] decides the i-th event not decided before
//   f->finish(d);               // end of stream: everything pending is decided

#include <concepts>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "evpipe/core/event.hpp"

namespace evpipe::denoise {

/// Decisions for consecutive events, in input order. `score` is empty when the filter exposes no score, else it
/// holds one value per decision: higher means more signal-like (ROC analysis sweeps a threshold over it).
struct Decisions {
  std::vector<std::uint8_t> keep;  ///< 1 = keep (signal), 0 = drop (noise)
  std::vector<float> score;

  [[nodiscard]] std::size_t size() const noexcept { return keep.size(); }
  void clear() noexcept {
    keep.clear();
    score.clear();
  }
};

/// Runs task(0) ... task(count - 1), possibly at the same time, and returns once every one has returned (rethrowing
/// the first exception). The library never starts a thread: a caller that owns threads (the pipeline) passes one in
/// to spread a filter's work over cores.
using TaskRunner = std::function<void(int count, const std::function<void(int)>& task)>;

/// One named figure of a filter's run so far (for example "curvature_undefined" or "noise_rate_hz").
struct ReportItem {
  std::string key;
  double value = 0.0;
};

/// The memory one filter may give its per-pixel state (docs/operations.md, "Limits"): 256 bytes per pixel of the
/// largest accepted sensor (kMaxSensorSide^2 = 4.2 M pixels), 1 GiB. The filters need 2-60 bytes per pixel (the
/// curvature filter's grid index about 20 per row-band task).
inline constexpr std::size_t kMaxFilterBytesPerPixel = 256;
inline constexpr std::size_t kMaxFilterStateBytes =
    kMaxFilterBytesPerPixel * static_cast<std::size_t>(kMaxSensorSide) * static_cast<std::size_t>(kMaxSensorSide);
/// The most filters one chain may hold (`evdenoise --filter A,B,...`, `denoise.filter`): each holds its own per-pixel
/// state (up to 250 MB each on the largest sensor with the filters there are), and 40 chained copies of one filter
/// took 3.4 GB. The project's chains have two.
inline constexpr std::size_t kMaxChainFilters = 8;
/// Called by every filter before it allocates per-pixel state: throws std::invalid_argument naming `filter` when the
/// sensor is beyond kMaxSensorSide or `bytes_per_pixel` x its pixels exceeds kMaxFilterStateBytes (issue 17: a
/// declared 65536 x 65536 sensor made baf, ynoise and stcf abort on bad_alloc).
void check_pixel_budget(std::string_view filter, const SensorGeometry& geometry, std::size_t bytes_per_pixel);

class Filter {
 public:
  Filter() = default;
  virtual ~Filter() = default;
  Filter(const Filter&) = delete;
  Filter& operator=(const Filter&) = delete;

  [[nodiscard]] virtual std::string_view name() const noexcept = 0;
  /// Feeds the next time-ordered events (t_us non-decreasing across pushes) and appends to `out` the decisions
  /// that became final: those of the oldest undecided events, in input order.
  virtual void push(EventSpan events, Decisions& out) = 0;
  /// End of the stream: appends the decisions of every pending event.
  virtual void finish(Decisions& out) = 0;
  /// Forgets all state (as if newly built). Pending events are dropped undecided: call finish() first.
  virtual void reset() = 0;
  /// The source's clock jumped (EventBatch::discontinuity_before): decide what is pending as at the end of a
  /// stream, then start afresh so that no neighbourhood spans the jump.
  void discontinuity(Decisions& out) {
    finish(out);
    reset();
  }
  /// Events pushed whose decision is not out yet.
  [[nodiscard]] virtual std::size_t pending() const noexcept { return 0; }
  /// Longest time, in sensor time, an event waits for later events before it is decided (0 = on arrival).
  [[nodiscard]] virtual std::int64_t latency_us() const noexcept { return 0; }
  /// True when push()/finish() fill Decisions::score.
  [[nodiscard]] virtual bool has_score() const noexcept { return false; }
  /// Figures of the run so far (counters, estimates); printed by `evdenoise --metrics`.
  [[nodiscard]] virtual std::vector<ReportItem> report() const { return {}; }
  /// Lets the filter split its work into up to `tasks` independent tasks run by `runner` (tasks <= 1 or an empty
  /// runner: one task, in the caller's thread). Decisions never depend on it. Filters whose work does not split
  /// ignore it (the default).
  virtual void set_parallelism(int tasks, TaskRunner runner) {
    (void)tasks;
    (void)runner;
  }
};

/// A causal filter whose whole logic is one per-event decision: `bool accept(const Event&) noexcept` and
/// `void reset() noexcept`. If it also has `float last_score() const noexcept` (the score of the event just
/// accepted or rejected), the adapter exposes it.
template <class Impl>
concept PerEventDecision = requires(Impl impl, const Event& e) {
  { impl.accept(e) }
  noexcept->std::same_as<bool>;
  { impl.reset() }
  noexcept;
};

template <class Impl>
concept PerEventScore = requires(const Impl impl) {
  { impl.last_score() }
  noexcept->std::convertible_to<float>;
};

/// Adapts a per-event decision to the Filter interface. The same `accept` serves a whole batch here and one
/// event at a time elsewhere (impl()), so batch and stream results are identical by construction.
template <PerEventDecision Impl>
class PerEventFilter final : public Filter {
 public:
  template <class... Args>
  explicit PerEventFilter(std::string name, Args&&... args)
      : name_(std::move(name)), impl_(std::forward<Args>(args)...) {}

  [[nodiscard]] std::string_view name() const noexcept override { return name_; }
  void push(EventSpan events, Decisions& out) override {
    // Written through raw pointers into pre-sized storage: a uint8_t store through vector::push_back may alias
    // anything, which would make the compiler reload the filter's state after every event.
    const std::size_t base = out.keep.size();
    out.keep.resize(base + events.size());
    std::uint8_t* keep = out.keep.data() + base;
    float* score = nullptr;
    if constexpr (PerEventScore<Impl>) {
      out.score.resize(base + events.size());
      score = out.score.data() + base;
    }
    Impl& impl = impl_;
    for (std::size_t i = 0; i < events.size(); ++i) {
      keep[i] = impl.accept(events[i]) ? 1 : 0;
      if constexpr (PerEventScore<Impl>) {
        score[i] = static_cast<float>(impl.last_score());
      }
    }
    (void)score;
  }
  void finish(Decisions& /*out*/) override {}
  void reset() override { impl_.reset(); }
  [[nodiscard]] bool has_score() const noexcept override { return PerEventScore<Impl>; }
  [[nodiscard]] std::vector<ReportItem> report() const override {
    if constexpr (requires(const Impl& i) { i.report(); }) {
      return impl_.report();
    } else {
      return {};
    }
  }

  [[nodiscard]] Impl& impl() noexcept { return impl_; }
  [[nodiscard]] const Impl& impl() const noexcept { return impl_; }

 private:
  std::string name_;
  Impl impl_;
};

/// Runs `filter` over a whole span (pushes of `chunk_events`, 0 = one push) and finishes it: one decision per
/// event.
Decisions run_filter(Filter& filter, EventSpan events, std::size_t chunk_events = 0);

/// Number of kept events.
std::size_t count_kept(const Decisions& decisions) noexcept;

}  // namespace evpipe::denoise
