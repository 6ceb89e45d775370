#include "evpipe/denoise/curvature.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <functional>
#include <limits>
#include <stdexcept>

#include "evpipe/denoise/neighbourhood.hpp"
#include "evpipe/denoise/noise_rate.hpp"
#include "evpipe/denoise/quadric.hpp"
#include "evpipe/denoise/selection.hpp"

namespace evpipe::denoise {

// ------------------------------------------------------------------------------------------------ options

namespace {

[[noreturn]] void bad_option(std::string_view key, const std::string& value, std::string_view why) {
  throw std::invalid_argument(fmt::format("curvature: {}={}: {}", key, value, why));
}

std::int64_t floor_div(std::int64_t a, std::int64_t b) noexcept {
  const std::int64_t q = a / b;
  return (a % b != 0 && (a < 0) != (b < 0)) ? q - 1 : q;
}

constexpr std::int64_t kMaxWindowUs = 1'000'000'000;  // keeps a block + margins within int32 µs offsets

}  // namespace

void validate(const CurvatureOptions& o) {
  if (!(o.radius_px > 0.0 && o.radius_px <= kMaxSphereRadiusPx)) {
    bad_option("radius", fmt::format("{}", o.radius_px), "must be in (0, 4] pixels (at most 64 sites)");
  }
  if (o.lt_us < 1 || o.lt_us > kMaxSphereLtUs) {
    bad_option("lt_us", fmt::format("{}", o.lt_us), fmt::format("must be in [1, {}]", kMaxSphereLtUs));
  }
  if (o.density_threshold < 1) {
    bad_option("density_threshold", fmt::format("{}", o.density_threshold), "must be an integer >= 1");
  }
  if (!(o.keep_fraction > 0.0 && o.keep_fraction <= 1.0)) {
    bad_option("keep_fraction", fmt::format("{}", o.keep_fraction), "must be in (0, 1]");
  }
  if (o.window_us <= 0 || o.window_us > kMaxWindowUs) {
    bad_option("window_us", fmt::format("{}", o.window_us), fmt::format("must be in [1, {}]", kMaxWindowUs));
  }
  if (!(o.target_noise_pass > 0.0 && o.target_noise_pass < 1.0)) {
    bad_option("target_noise_pass", fmt::format("{}", o.target_noise_pass), "must be in (0, 1)");
  }
  if (o.adaptive_period_us <= 0) {
    bad_option("adaptive_period_us", fmt::format("{}", o.adaptive_period_us), "must be > 0");
  }
  if (o.adaptive_max_threshold != 0 && o.adaptive_max_threshold < 2) {
    bad_option("adaptive_max_threshold", fmt::format("{}", o.adaptive_max_threshold),
               "must be 0 (no limit) or an integer >= 2");
  }
}

std::string_view to_string(CurvatureMode m) noexcept {
  switch (m) {
    case CurvatureMode::frames:
      return "frames";
    case CurvatureMode::stream:
      return "stream";
    case CurvatureMode::causal:
      return "causal";
  }
  return "?";
}

std::string_view to_string(CurvatureRule r) noexcept {
  switch (r) {
    case CurvatureRule::median:
      return "median";
    case CurvatureRule::shortest:
      return "shortest";
    case CurvatureRule::flattest:
      return "flattest";
  }
  return "?";
}

// -------------------------------------------------------------------------------------------------- judge

namespace {

// Everything after the neighbourhood: density test (with the adaptive threshold), singular test, batched
// quadric fits, per-block selection and the decisions. Shared by every backend and mode and by
// curvature_batch, so that equal per-site statistics give equal decisions whatever order queries arrive in
// (only the period of the adaptive estimator needs time order, and queries never straddle a period).
//
// The fits of one block may run as several tasks at once (CurvatureFilter::set_parallelism): each task has its own
// Fitter, which writes its events' results to their slots of the block's arrays in chunks (write_out); the counters
// are summed and the selection runs once the tasks have returned.
class Judge {
 public:
  /// One event's result, kept by its task and written to the block's arrays a chunk at a time.
  struct Judged {
    std::uint32_t slot;
    std::int32_t rho;
    CurvatureStatus status;
    double curvature;
  };
  /// One task's fitting state (lanes of pending fits, its own lazily filled rank table, counters) and results.
  /// Queries come pixel by pixel but slots are in time order: writing each result into the block's arrays as it
  /// comes is a random write over the whole block, interleaved with the queries (and, with tasks, every cache
  /// line is shared). Results are kept in the task's list and written in tight passes of kJudgedChunk, which
  /// also bounds the list's memory.
  static constexpr std::size_t kJudgedChunk = 65536;  // 1.5 MB a task
  struct Fitter {
    explicit Fitter(const Sphere& sphere) : table(sphere), batch(sphere) {}
    SingularMaskTable table;
    QuadricBatch batch;
    int lanes = 0;
    std::size_t lane_slot[QuadricBatch::kLanes] = {};  // positions in `judged`
    std::vector<Judged> judged;
    std::int64_t density_passed = 0, undefined = 0, failed = 0;
  };

  /// One task (set_tasks() adds more).
  Judge(const CurvatureOptions& o, const Sphere& sphere, const SensorGeometry& g)
      : o_(o),
        sites_(sphere.size()),
        rate_(o.adaptive ? make_exposure_model(sphere, o.mode, o.window_us, g) : ExposureModel{}, o) {
    fitters_.emplace_back(sphere);
  }

  void reset() {
    rate_.reset();
    prev_region_ = {};
    have_prev_ = false;
    for (auto& f : fitters_) {
      f.lanes = 0;
      f.judged.clear();
      f.density_passed = f.undefined = f.failed = 0;
    }
    dropped_ = blocks_ = 0;
    started_ = false;
  }
  void set_trace(CurvatureTrace* t) noexcept { trace_ = t; }

  /// The stream's first event (the adaptive estimator's first period is observed from there).
  void start(std::int64_t t_us) {
    if (started_) return;
    started_ = true;
    rate_.start(t_us);
  }

  void begin_block(std::int64_t block, std::size_t n) {
    if (n > std::numeric_limits<std::uint32_t>::max()) throw std::length_error("curvature: block of > 2^32 events");
    block_ = block;
    for (auto& f : fitters_) {  // nothing is pending between blocks, unless a task threw in the last one
      f.lanes = 0;
      f.judged.clear();
    }
    rho_.assign(n, 0);
    status_.assign(n, CurvatureStatus::outside);
    curv_.assign(n, 0.0);
    if (trace_ != nullptr && trace_->with_sites) {
      site_counts_.assign(n * static_cast<std::size_t>(sites_), 0);
      site_sums_.assign(n * static_cast<std::size_t>(sites_), 0);
    }
    ++blocks_;
  }
  /// Causal blocks grow one event at a time.
  std::size_t open_slot() {
    rho_.push_back(0);
    status_.push_back(CurvatureStatus::outside);
    curv_.push_back(0.0);
    if (trace_ != nullptr && trace_->with_sites) {
      site_counts_.resize(site_counts_.size() + static_cast<std::size_t>(sites_), 0);
      site_sums_.resize(site_sums_.size() + static_cast<std::size_t>(sites_), 0);
    }
    return rho_.size() - 1;
  }
  [[nodiscard]] std::size_t slots() const noexcept { return rho_.size(); }

  /// The density threshold in force at t_us (advances the adaptive period; one thread, between tasks).
  std::int64_t threshold(std::int64_t t_us) { return rate_.threshold(t_us); }
  /// The density failures counted by the tasks go to the adaptive estimator (before its next period starts).
  void absorb_failures() {
    for (auto& f : fitters_) {
      rate_.count_failures(f.failed);
      f.failed = 0;
    }
  }
  /// Between blocks: `n` Fitters from now on (the counters of removed ones are kept).
  void set_tasks(int n, const Sphere& sphere) {
    flush();
    absorb_failures();
    while (static_cast<int>(fitters_.size()) > std::max(n, 1)) {
      fitters_.front().density_passed += fitters_.back().density_passed;
      fitters_.front().undefined += fitters_.back().undefined;
      fitters_.pop_back();
    }
    while (static_cast<int>(fitters_.size()) < n) fitters_.emplace_back(sphere);
  }

  /// One event in the caller's thread.
  void add(std::size_t slot, std::int64_t t_us, std::int32_t rho, std::uint64_t mask, const std::int32_t* counts,
           const double* sums) {
    add(0, slot, threshold(t_us), rho, mask, counts, sums);
    absorb_failures();
  }

  /// One event of task `task` against `threshold`: touches only its slot and that task's Fitter.
  void add(int task, std::size_t slot, std::int64_t threshold, std::int32_t rho, std::uint64_t mask,
           const std::int32_t* counts, const double* sums) {
    Fitter& f = fitters_[static_cast<std::size_t>(task)];
    if (trace_ != nullptr && trace_->with_sites) {
      std::copy_n(counts, sites_, site_counts_.begin() + static_cast<std::ptrdiff_t>(slot * sites_));
      for (int s = 0; s < sites_; ++s) site_sums_[slot * sites_ + s] = static_cast<std::int64_t>(sums[s]);
    }
    if (f.judged.size() >= kJudgedChunk) {  // (rarely) solves a part-filled batch first: lanes point into judged
      flush(f);
      write_out(f);
    }
    CurvatureStatus& status =
        f.judged.emplace_back(Judged{static_cast<std::uint32_t>(slot), rho, CurvatureStatus::density_fail, 0.0}).status;
    if (rho < threshold) {
      ++f.failed;
      return;
    }
    ++f.density_passed;
    if (!o_.curvature) {
      status = CurvatureStatus::density_only;
      return;
    }
    if (!f.table.full_rank(mask)) {
      status = CurvatureStatus::undefined;
      ++f.undefined;
      return;
    }
    status = CurvatureStatus::selected;  // fitted; the selection may still drop it
    f.batch.set(f.lanes, counts, sums);
    f.lane_slot[f.lanes++] = f.judged.size() - 1;
    if (f.lanes == QuadricBatch::kLanes) flush(f);
  }

  /// Solves what task `task` has pending (its thread).
  void flush(int task) { flush(fitters_[static_cast<std::size_t>(task)]); }
  /// Solves what is pending and writes every task's results to the block's arrays (after the tasks).
  void flush() {
    for (auto& f : fitters_) {
      flush(f);
      write_out(f);
    }
  }

  /// A task's solved results to the block's arrays, in one tight pass (its own slots only; several tasks may do
  /// this at once: the slots are disjoint).
  void write_out(Fitter& f) {
    for (const Judged& r : f.judged) {
      rho_[r.slot] = r.rho;
      status_[r.slot] = r.status;
      curv_[r.slot] = r.curvature;
    }
    f.judged.clear();
  }

  void flush(Fitter& f) {
    if (f.lanes == 0) return;
    double c[QuadricBatch::kLanes];
    bool ok[QuadricBatch::kLanes];
    f.batch.solve(f.lanes, c, ok);
    for (int l = 0; l < f.lanes; ++l) {
      if (ok[l]) {
        f.judged[f.lane_slot[l]].curvature = c[l];
      } else {
        f.judged[f.lane_slot[l]].status = CurvatureStatus::undefined;
        ++f.undefined;
      }
    }
    f.lanes = 0;
  }

  /// frames/stream: selection over the block's population, then every slot's decision.
  void finish_block(Decisions& out) {
    flush();
    const ConsistencyRegion region = select_block(true);
    emit(0, rho_.size(), region, out);
  }

  /// causal: decisions of slots [from, to) against the previous block's region.
  void emit_causal(std::size_t from, std::size_t to, Decisions& out) {
    flush();
    const bool judged = have_prev_ && prev_block_ == block_ - 1;
    for (std::size_t i = from; i < to; ++i) {
      if (status_[i] == CurvatureStatus::selected && judged && !prev_region_.contains(curv_[i])) {
        status_[i] = CurvatureStatus::not_selected;
        ++dropped_;
      }
    }
    emit(from, to, judged ? prev_region_ : ConsistencyRegion{}, out);
  }
  /// causal: the block is complete; its region judges the next block.
  void end_block_causal() {
    flush();
    prev_region_ = select_block(false);
    prev_block_ = block_;
    have_prev_ = true;
  }

  void report(std::vector<ReportItem>& items) const {
    std::int64_t passed = 0, undefined = 0;
    for (const auto& f : fitters_) passed += f.density_passed, undefined += f.undefined;
    items.push_back({"density_passed", static_cast<double>(passed)});
    items.push_back({"curvature_undefined", static_cast<double>(undefined)});
    items.push_back({"curvature_dropped", static_cast<double>(dropped_)});
    items.push_back({"blocks", static_cast<double>(blocks_)});
    items.push_back({"noise_rate_hz", rate_.rate_hz()});
    items.push_back({"density_threshold_used", static_cast<double>(rate_.current_threshold())});
    items.push_back({"adaptive_periods", static_cast<double>(rate_.periods())});
  }

 private:
  ConsistencyRegion select_block(bool apply) {
    values_.clear();
    which_.clear();
    // The population is every fitted event of the block. In causal mode some were already dropped against the
    // previous block's region (not_selected); they must still count here, or each block's region would be cut
    // from an already trimmed population and shrink block after block (0.8, 0.64, ... of the events).
    for (std::size_t i = 0; i < status_.size(); ++i) {
      if (status_[i] == CurvatureStatus::selected || status_[i] == CurvatureStatus::not_selected) {
        values_.push_back(curv_[i]);
        which_.push_back(static_cast<std::uint32_t>(i));
      }
    }
    const ConsistencyRegion region = select_consistent(values_, o_.keep_fraction, o_.rule, keep_);
    if (apply) {
      for (std::size_t k = 0; k < which_.size(); ++k) {
        if (keep_[k] == 0) {
          status_[which_[k]] = CurvatureStatus::not_selected;
          ++dropped_;
        }
      }
    }
    return region;
  }

  void emit(std::size_t from, std::size_t to, const ConsistencyRegion& region, Decisions& out) {
    for (std::size_t i = from; i < to; ++i) {
      const CurvatureStatus st = status_[i];
      bool keep = false;
      double score = static_cast<double>(rho_[i]);
      switch (st) {
        case CurvatureStatus::outside:
        case CurvatureStatus::density_fail:
          break;
        case CurvatureStatus::density_only:
          keep = true;
          break;
        case CurvatureStatus::undefined:
          keep = o_.singular == SingularPolicy::keep;
          break;
        case CurvatureStatus::selected:
        case CurvatureStatus::not_selected:
          keep = st == CurvatureStatus::selected;
          score += region.consistency(curv_[i]);
          break;
      }
      out.keep.push_back(keep ? 1 : 0);
      out.score.push_back(static_cast<float>(score));
      if (trace_ != nullptr) {
        trace_->rho.push_back(rho_[i]);
        trace_->status.push_back(st);
        trace_->curvature.push_back(curv_[i]);
        if (trace_->with_sites) {
          const auto b = static_cast<std::ptrdiff_t>(i * static_cast<std::size_t>(sites_));
          trace_->counts.insert(trace_->counts.end(), site_counts_.begin() + b, site_counts_.begin() + b + sites_);
          trace_->sums_dt.insert(trace_->sums_dt.end(), site_sums_.begin() + b, site_sums_.begin() + b + sites_);
        }
      }
    }
  }

  CurvatureOptions o_;
  int sites_;
  std::vector<Fitter> fitters_;
  NoiseRateEstimator rate_;
  CurvatureTrace* trace_ = nullptr;
  bool started_ = false;

  std::int64_t block_ = 0;
  std::vector<std::int32_t> rho_;
  std::vector<CurvatureStatus> status_;
  std::vector<double> curv_;
  std::vector<std::int32_t> site_counts_;
  std::vector<std::int64_t> site_sums_;

  std::vector<double> values_;
  std::vector<std::uint32_t> which_;
  std::vector<std::uint8_t> keep_;
  ConsistencyRegion prev_region_;
  std::int64_t prev_block_ = 0;
  bool have_prev_ = false;

  std::int64_t dropped_ = 0, blocks_ = 0;
};

std::int64_t sat_add(std::int64_t a, std::int64_t b) noexcept {
  std::int64_t r = 0;
  if (__builtin_add_overflow(a, b, &r))
    return b > 0 ? std::numeric_limits<std::int64_t>::max() : std::numeric_limits<std::int64_t>::min();
  return r;
}

auto by_time = [](const Event& e, std::int64_t t) { return e.t_us < t; };
auto time_before = [](std::int64_t t, const Event& e) { return t < e.t_us; };

}  // namespace

// ------------------------------------------------------------------------------------------------- filter

struct CurvatureFilter::Impl {
  Impl(const CurvatureOptions& o, const SensorGeometry& g)
      : options((validate(o), o)), geometry(g), sphere(o.radius_px, o.lt_us, o.inclusive_radius), judge(o, sphere, g) {
    if (options.backend == NeighbourhoodBackend::flann) {
      flann = std::make_unique<FlannBallIndex>(sphere);
    } else if (options.mode == CurvatureMode::causal) {
      ring = std::make_unique<GridRingIndex>(sphere, geometry);
    } else {
      grids.push_back(std::make_unique<GridBlockIndex>(sphere, geometry));
    }
  }

  /// Grid index, frames / stream: one row band per task, each with its own index (the other modes and backends
  /// work one event after another or are the reference: they stay in one task).
  void set_parallelism(int tasks, TaskRunner r) {
    if (grids.empty()) return;
    // Each task has its own full-size grid: at most as many as the per-pixel budget holds (kMaxFilterStateBytes).
    const auto grid_bytes = std::max<std::size_t>(kGridBlockBytesPerPixel * geometry.pixels(), 1);
    const int budget_tasks = static_cast<int>(std::clamp<std::size_t>(kMaxFilterStateBytes / grid_bytes, 1, kMaxTasks));
    const int n = r ? std::clamp(tasks, 1, std::min(kMaxTasks, budget_tasks)) : 1;
    runner = std::move(r);
    judge.set_tasks(n, sphere);
    grids.resize(static_cast<std::size_t>(n));
    band_events.resize(static_cast<std::size_t>(n));
    for (auto& g : grids) {
      if (!g) g = std::make_unique<GridBlockIndex>(sphere, geometry);
    }
  }

  void run_tasks(int n, const std::function<void(int)>& task) const {
    if (n > 1 && runner) {
      runner(n, task);
    } else {
      for (int k = 0; k < n; ++k) task(k);
    }
  }

  /// Row bands [band[k], band[k + 1]) holding about equal shares of the queries [q0, q1) of `span`.
  void split_rows(EventSpan span, std::size_t q0, std::size_t q1) {
    const auto n = static_cast<int>(grids.size());
    band.assign(static_cast<std::size_t>(n) + 1, geometry.height);
    band[0] = 0;
    if (n == 1) return;
    row_count.assign(static_cast<std::size_t>(geometry.height), 0);
    std::size_t total = 0;
    for (std::size_t i = q0; i < q1; ++i) {
      if (!geometry.contains(span[i].x, span[i].y)) continue;
      ++row_count[static_cast<std::size_t>(span[i].y)];
      ++total;
    }
    std::size_t seen = 0;
    int k = 1;
    for (int y = 0; y < geometry.height && k < n; ++y) {
      seen += row_count[static_cast<std::size_t>(y)];
      while (k < n && seen * static_cast<std::size_t>(n) >= total * static_cast<std::size_t>(k)) band[k++] = y + 1;
    }
  }

  CurvatureOptions options;
  SensorGeometry geometry;
  Sphere sphere;
  Judge judge;
  static constexpr int kMaxTasks = 64;
  std::vector<std::unique_ptr<GridBlockIndex>> grids;  // one per task (row band); empty for causal / flann
  TaskRunner runner;
  std::vector<int> band;
  std::vector<std::uint32_t> row_count;
  /// Per task: positions in the block's span. Room for the whole span, left uninitialised: a band writes only the
  /// first entries (about its share), so the pages behind them are never touched and cost no memory.
  struct BandEvents {
    std::unique_ptr<std::uint32_t[]> at;
    std::size_t room = 0;
    std::uint32_t* reserve(std::size_t n) {
      if (n > room) {
        at = std::make_unique_for_overwrite<std::uint32_t[]>(n);
        room = n;
      }
      return at.get();
    }
  };
  std::vector<BandEvents> band_events;
  std::unique_ptr<GridRingIndex> ring;
  std::unique_ptr<FlannBallIndex> flann;

  std::vector<Event> buf;  // frames/stream: margin + undecided events; causal + flann: margin + this push
  std::size_t head = 0;    // first undecided event in buf
  bool have_last = false;
  std::int64_t last_t = 0;
  bool block_open = false;  // causal
  std::int64_t causal_block = 0;
  std::size_t emitted = 0;  // causal: slots of the open block already decided
  std::vector<std::uint32_t> members;
  std::int32_t counts[kMaxSphereSites + 1] = {};  // + the zero entry QuadricBatch::set expects
  std::int64_t sums[kMaxSphereSites + 1] = {};
  double sums_d[kMaxSphereSites + 1] = {};

  void add(std::size_t slot, std::int64_t t_us) {
    for (int s = 0; s < sphere.size(); ++s) sums_d[s] = static_cast<double>(sums[s]);
    std::int32_t rho = 0;
    std::uint64_t mask = 0;
    density_and_mask(counts, sphere.size(), rho, mask);
    judge.add(slot, t_us, rho, mask, counts, sums_d);
  }

  void append(EventSpan events) {
    if (events.empty()) return;
    if (!have_last) {
      have_last = true;
      last_t = events.front().t_us;
      judge.start(last_t);
    }
    const std::size_t from = buf.size();
    buf.insert(buf.end(), events.begin(), events.end());  // geometric growth
    // Out-of-order input (contract violation) is treated as arriving at the latest time seen.
    std::int64_t t = last_t;
    for (std::size_t i = from; i < buf.size(); ++i) {
      t = std::max(t, buf[i].t_us);
      buf[i].t_us = t;
    }
    last_t = t;
  }

  void process_block(Decisions& out) {
    const std::int64_t w = options.window_us;
    const std::int64_t reach = sphere.reach_us();
    const std::int64_t k = floor_div(buf[head].t_us, w);
    const std::int64_t blk_start = k * w;
    const std::int64_t blk_end = blk_start + w;
    const auto begin = buf.begin();
    const std::size_t b0 = head;
    const auto b1 = static_cast<std::size_t>(
        std::lower_bound(begin + static_cast<std::ptrdiff_t>(b0), buf.end(), blk_end, by_time) - begin);
    std::size_t e0 = b0;
    std::size_t e1 = b1;
    const bool stream = options.mode == CurvatureMode::stream;
    if (stream) {
      e0 = static_cast<std::size_t>(
          std::lower_bound(begin, begin + static_cast<std::ptrdiff_t>(b0), blk_start - reach, by_time) - begin);
      e1 = static_cast<std::size_t>(
          std::upper_bound(begin + static_cast<std::ptrdiff_t>(b1), buf.end(), blk_end - 1 + reach, time_before) -
          begin);
    }
    const EventSpan span(buf.data() + e0, e1 - e0);
    judge.begin_block(k, b1 - b0);
    const std::size_t q0 = b0 - e0;
    const std::size_t q1 = b1 - e0;
    if (!grids.empty()) {
      const std::int64_t lo = stream ? std::numeric_limits<std::int64_t>::min() / 2 : blk_start;
      const std::int64_t hi = stream ? std::numeric_limits<std::int64_t>::max() / 2 : blk_end - 1;
      const int n = static_cast<int>(grids.size());
      split_rows(span, q0, q1);
      const auto build = [&](int task) {
        const auto b = static_cast<std::size_t>(task);
        if (n == 1) {
          grids[b]->build(span);
          return;
        }
        // One scan picks this band's events (its rows ± the ball's extent); the index build, the ties and the
        // queries then see only those.
        const int y_lo = band[b] - sphere.extent_px();
        const int y_hi = band[b + 1] + sphere.extent_px();
        std::uint32_t* mine = band_events[b].reserve(span.size());
        std::size_t picked = 0;
        if (band[b] < band[b + 1]) {
          // Branch-free: a band boundary splits the rows, so a branch on y mispredicts about every other event.
          const auto rows = static_cast<std::uint32_t>(y_hi - y_lo);
          for (std::size_t i = 0; i < span.size(); ++i) {
            mine[picked] = static_cast<std::uint32_t>(i);
            picked += static_cast<std::uint32_t>(static_cast<int>(span[i].y) - y_lo) < rows ? 1U : 0U;
          }
        }
        grids[b]->build(span, std::span<const std::uint32_t>(mine, picked), band[b], band[b + 1]);
      };
      const auto query = [&](int task, std::size_t a, std::size_t b, std::int64_t threshold) {
        auto sink = [&](std::size_t i, std::int64_t, std::int32_t rho, std::uint64_t mask, const std::int32_t* c,
                        const double* s) { judge.add(task, i - q0, threshold, rho, mask, c, s); };
        grids[static_cast<std::size_t>(task)]->query(a, b, lo, hi, sink);
        judge.flush(task);
      };
      if (!options.adaptive) {
        const std::int64_t threshold = judge.threshold(span[q0].t_us);  // fixed
        run_tasks(n, [&](int task) {
          build(task);
          query(task, q0, q1, threshold);
        });
      } else {
        // Queries arrive grouped by pixel: split them at the adaptive estimator's period borders so that all
        // events of one period are judged (and their failures counted) before the next period's threshold.
        run_tasks(n, build);
        std::size_t a = q0;
        while (a < q1) {
          const std::int64_t period_end =
              (floor_div(span[a].t_us, options.adaptive_period_us) + 1) * options.adaptive_period_us;
          const auto b = static_cast<std::size_t>(std::lower_bound(span.begin() + static_cast<std::ptrdiff_t>(a),
                                                                   span.begin() + static_cast<std::ptrdiff_t>(q1),
                                                                   period_end, by_time) -
                                                  span.begin());
          // The period starts at its first queried event (as if each event asked in turn): a period with none
          // does not count as observed.
          std::size_t first = a;
          while (first < b && !geometry.contains(span[first].x, span[first].y)) ++first;
          if (first < b) {
            const std::int64_t threshold = judge.threshold(span[first].t_us);
            run_tasks(n, [&](int task) { query(task, a, b, threshold); });
            judge.absorb_failures();
          }
          a = b;
        }
      }
      judge.absorb_failures();
    } else {
      flann->build(span, geometry);
      for (std::size_t i = q0; i < q1; ++i) {
        if (!geometry.contains(span[i].x, span[i].y)) continue;
        flann->ball(span[i], members);
        accumulate_ball(
            sphere, span, i, members, [](std::size_t) { return false; }, counts, sums);
        add(i - q0, span[i].t_us);
      }
    }
    judge.finish_block(out);
    head = b1;
    // Keep the margin the next block's balls reach back into.
    const std::int64_t keep_from = stream ? sat_add((k + 1) * w, -reach) : std::numeric_limits<std::int64_t>::max();
    const auto drop = static_cast<std::size_t>(
        std::lower_bound(begin, begin + static_cast<std::ptrdiff_t>(head), keep_from, by_time) - begin);
    compact(drop);
  }

  void compact(std::size_t drop) {
    if (drop == 0) return;
    if (drop == buf.size() || drop >= buf.size() / 2 || drop > 65536) {
      buf.erase(buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(drop));
      head -= drop;
    }
  }

  bool block_ready() const {
    const std::int64_t blk_end = (floor_div(buf[head].t_us, options.window_us) + 1) * options.window_us;
    const std::int64_t need = options.mode == CurvatureMode::stream ? sat_add(blk_end, sphere.reach_us()) : blk_end;
    return last_t >= need;
  }

  void push_blocks(EventSpan events, Decisions& out) {
    append(events);
    while (head < buf.size() && block_ready()) process_block(out);
  }

  void push_causal(EventSpan events, Decisions& out) {
    const std::size_t first_new = buf.size();
    append(events);
    if (flann) flann->build(EventSpan(buf), geometry);
    for (std::size_t i = first_new; i < buf.size(); ++i) {
      const Event& e = buf[i];
      const std::int64_t k = floor_div(e.t_us, options.window_us);
      if (!block_open || k != causal_block) {
        if (block_open) {
          judge.emit_causal(emitted, judge.slots(), out);
          judge.end_block_causal();
        }
        judge.begin_block(k, 0);
        block_open = true;
        causal_block = k;
        emitted = 0;
      }
      const std::size_t slot = judge.open_slot();
      if (!geometry.contains(e.x, e.y)) continue;
      if (ring) {
        ring->query_and_insert(e, counts, sums);
      } else {
        flann->ball(e, members);
        accumulate_ball(
            sphere, EventSpan(buf), i, members, [i](std::size_t j) { return j > i; }, counts, sums);
      }
      add(slot, e.t_us);
    }
    if (block_open) {
      judge.emit_causal(emitted, judge.slots(), out);
      emitted = judge.slots();
    }
    // The FLANN backend rebuilds its index per push over the margin the next balls reach back into.
    if (flann && !buf.empty()) {
      const auto drop = static_cast<std::size_t>(
          std::lower_bound(buf.begin(), buf.end(), sat_add(last_t, -sphere.reach_us()), by_time) - buf.begin());
      buf.erase(buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(drop));
    } else {
      buf.clear();
    }
    head = buf.size();
  }

  void reset() {
    judge.reset();
    buf.clear();
    head = 0;
    have_last = false;
    block_open = false;
    emitted = 0;
    if (ring) ring->reset();
  }
};

CurvatureFilter::CurvatureFilter(const CurvatureOptions& options, const SensorGeometry& geometry)
    : impl_(std::make_unique<Impl>(options, geometry)) {}
CurvatureFilter::~CurvatureFilter() = default;

void CurvatureFilter::set_parallelism(int tasks, TaskRunner runner) {
  impl_->set_parallelism(tasks, std::move(runner));
}

void CurvatureFilter::push(EventSpan events, Decisions& out) {
  if (impl_->options.mode == CurvatureMode::causal) {
    impl_->push_causal(events, out);
  } else {
    impl_->push_blocks(events, out);
  }
}

void CurvatureFilter::finish(Decisions& out) {
  if (impl_->options.mode == CurvatureMode::causal) return;  // decided on arrival
  while (impl_->head < impl_->buf.size()) impl_->process_block(out);
}

void CurvatureFilter::reset() {
  impl_->reset();
}

std::size_t CurvatureFilter::pending() const noexcept {
  return impl_->options.mode == CurvatureMode::causal ? 0 : impl_->buf.size() - impl_->head;
}

std::int64_t CurvatureFilter::latency_us() const noexcept {
  switch (impl_->options.mode) {
    case CurvatureMode::frames:
      return impl_->options.window_us;
    case CurvatureMode::stream:
      return impl_->options.window_us + impl_->sphere.reach_us();
    case CurvatureMode::causal:
      return 0;
  }
  return 0;
}

std::vector<ReportItem> CurvatureFilter::report() const {
  std::vector<ReportItem> items;
  impl_->judge.report(items);
  items.push_back({"latency_us", static_cast<double>(latency_us())});
  return items;
}

void CurvatureFilter::set_trace(CurvatureTrace* trace) noexcept {
  impl_->judge.set_trace(trace);
}
const Sphere& CurvatureFilter::sphere() const noexcept {
  return impl_->sphere;
}
const CurvatureOptions& CurvatureFilter::options() const noexcept {
  return impl_->options;
}

// -------------------------------------------------------------------------------------------------- batch

Decisions curvature_batch(EventSpan all_events, const CurvatureOptions& options, const SensorGeometry& geometry,
                          CurvatureTrace* trace) {
  validate(options);
  const Sphere sphere(options.radius_px, options.lt_us, options.inclusive_radius);
  Judge judge(options, sphere, geometry);
  judge.set_trace(trace);
  Decisions out;
  if (all_events.empty()) return out;
  std::vector<Event> events(all_events.begin(), all_events.end());
  for (std::size_t i = 1; i < events.size(); ++i) events[i].t_us = std::max(events[i].t_us, events[i - 1].t_us);
  judge.start(events.front().t_us);
  FlannBallIndex index(sphere);
  index.build(events, geometry);
  std::vector<std::uint32_t> members;
  std::int32_t counts[kMaxSphereSites + 1] = {};  // + the zero entry QuadricBatch::set expects
  std::int64_t sums[kMaxSphereSites + 1] = {};
  double sums_d[kMaxSphereSites + 1] = {};
  out.keep.reserve(events.size());
  out.score.reserve(events.size());
  const std::int64_t w = options.window_us;
  std::size_t b0 = 0;
  while (b0 < events.size()) {
    const std::int64_t k = floor_div(events[b0].t_us, w);
    std::size_t b1 = b0;
    while (b1 < events.size() && floor_div(events[b1].t_us, w) == k) ++b1;
    judge.begin_block(k, options.mode == CurvatureMode::causal ? 0 : b1 - b0);
    for (std::size_t i = b0; i < b1; ++i) {
      const std::size_t slot = options.mode == CurvatureMode::causal ? judge.open_slot() : i - b0;
      if (!geometry.contains(events[i].x, events[i].y)) continue;
      index.ball(events[i], members);
      switch (options.mode) {
        case CurvatureMode::stream:
          accumulate_ball(
              sphere, events, i, members, [](std::size_t) { return false; }, counts, sums);
          break;
        case CurvatureMode::frames:
          accumulate_ball(
              sphere, events, i, members, [&](std::size_t j) { return floor_div(events[j].t_us, w) != k; }, counts,
              sums);
          break;
        case CurvatureMode::causal:
          accumulate_ball(
              sphere, events, i, members, [i](std::size_t j) { return j > i; }, counts, sums);
          break;
      }
      for (int s = 0; s < sphere.size(); ++s) sums_d[s] = static_cast<double>(sums[s]);
      std::int32_t rho = 0;
      std::uint64_t mask = 0;
      density_and_mask(counts, sphere.size(), rho, mask);
      judge.add(slot, events[i].t_us, rho, mask, counts, sums_d);
    }
    if (options.mode == CurvatureMode::causal) {
      judge.emit_causal(0, b1 - b0, out);
      judge.end_block_causal();
    } else {
      judge.finish_block(out);
    }
    b0 = b1;
  }
  return out;
}

// ---------------------------------------------------------------------------------------------------- spec

CurvatureOptions curvature_options_from(Params& p) {
  CurvatureOptions o;
  o.radius_px = p.real("radius", o.radius_px, "ball radius r in pixels (time counts 1 px per lt_us), in (0, 4]");
  p.require_range("radius", o.radius_px, 0.0, kMaxSphereRadiusPx, true, false);
  o.lt_us = p.integer("lt_us", o.lt_us, "Lt: microseconds that count like one pixel");
  p.require_range("lt_us", static_cast<double>(o.lt_us), 1.0, static_cast<double>(kMaxSphereLtUs));
  o.inclusive_radius = p.boolean("inclusive_radius", o.inclusive_radius, "ball test <= r (true) or < r (false)");
  o.density_threshold = p.integer("density_threshold", o.density_threshold,
                                  "rho_TH: keep for the curvature stage iff 1 + other events in the ball >= it");
  p.require_range("density_threshold", static_cast<double>(o.density_threshold), 1.0, 1e9);
  o.curvature = p.boolean("curvature", o.curvature, "run the curvature stage (false = density only)");
  o.keep_fraction = p.real("keep_fraction", o.keep_fraction, "share of each block's population kept, in (0, 1]");
  p.require_range("keep_fraction", o.keep_fraction, 0.0, 1.0, true, false);
  const std::string rule = p.choice("rule", "median", {"median", "shortest", "flattest"},
                                    "consistent = closest to the median, shortest interval, or smallest |c|");
  o.rule = rule == "median"     ? CurvatureRule::median
           : rule == "shortest" ? CurvatureRule::shortest
                                : CurvatureRule::flattest;
  o.singular = p.choice("singular", "reject", {"reject", "keep"},
                        "rank-deficient fit: drop the event, or keep it without curvature") == "keep"
                   ? SingularPolicy::keep
                   : SingularPolicy::reject;
  o.window_us = p.integer("window_us", o.window_us, "block length: curvature population and frames");
  p.require_range("window_us", static_cast<double>(o.window_us), 1.0, static_cast<double>(kMaxWindowUs));
  const std::string mode = p.choice("mode", "stream", {"stream", "frames", "causal"},
                                    "stream = full ball (latency window + reach), frames = independent blocks, "
                                    "causal = past only (latency 0)");
  o.mode = mode == "stream" ? CurvatureMode::stream : mode == "frames" ? CurvatureMode::frames : CurvatureMode::causal;
  o.backend = p.choice("backend", "grid", {"grid", "flann"}, "neighbourhood index (identical results)") == "flann"
                  ? NeighbourhoodBackend::flann
                  : NeighbourhoodBackend::grid;
  o.adaptive = p.boolean("adaptive", o.adaptive, "set density_threshold per period from the estimated noise rate");
  o.target_noise_pass = p.real("target_noise_pass", o.target_noise_pass,
                               "adaptive: largest share of pure-noise events passing the density test, in (0, 1)");
  p.require_range("target_noise_pass", o.target_noise_pass, 0.0, 1.0, true, true);
  o.adaptive_period_us = p.integer("adaptive_period_us", o.adaptive_period_us, "adaptive: estimation period");
  p.require_positive("adaptive_period_us", static_cast<double>(o.adaptive_period_us));
  o.adaptive_max_threshold = p.integer("adaptive_max_threshold", o.adaptive_max_threshold,
                                       "adaptive: the threshold never goes above this (0 = no limit, else >= 2)");
  if (o.adaptive_max_threshold != 0 && o.adaptive_max_threshold < 2) {
    p.fail("adaptive_max_threshold", "must be 0 (no limit) or an integer >= 2");
  }
  return o;
}

FilterSpec curvature_spec() {
  return {"curvature",
          "the paper's spherical density + quadric curvature-consistency filter (r 2, Lt 1e4 us, rho 5, 80 %)",
          [](Params& p, const SensorGeometry& g) -> std::unique_ptr<Filter> {
            return std::make_unique<CurvatureFilter>(curvature_options_from(p), g);
          }};
}

}  // namespace evpipe::denoise
