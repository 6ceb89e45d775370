// evdenoise IN OUT --filter NAME[,NAME...] [--set KEY=VALUE]... [--metrics] [--png FILE]
// evdenoise --list-filters
//
// Denoises an event recording into another (docs/evdenoise.md). The input format is found from the content, the
// output format from OUT's extension (.aedat4 or .txt). Output events are a subset of the input events,
// unchanged and in input order; a labelled text input keeps its labels in a text output. The file is streamed:
// memory is bounded by the filter's window, not by the recording (ROC scores excepted: one bin per distinct
// score).
// Exit status: 0 success, 1 input/output error (missing, unreadable or corrupt input, write failure),
// 2 usage error (command line, unknown filter, unknown or bad parameter).

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "evpipe/cli/cli.hpp"
#include "evpipe/core/error.hpp"
#include "evpipe/core/file.hpp"
#include "evpipe/core/filter_chain.hpp"
#include "evpipe/denoise/filter.hpp"
#include "evpipe/denoise/filtered_stream.hpp"
#include "evpipe/denoise/registry.hpp"
#include "evpipe/io/reader.hpp"
#include "evpipe/io/writer.hpp"
#include "evpipe/metrics/classification.hpp"
#include "evpipe/metrics/esr.hpp"
#include "evpipe/metrics/roc.hpp"
#include "evpipe/runtime/task_pool.hpp"
#include "json.hpp"
#include "preview.hpp"

namespace fs = std::filesystem;
using namespace evpipe;
using evdenoise::JsonWriter;

namespace {

constexpr int kMaxWarningsShown = 20;

/// A problem with the command line or the filter settings (exit 2), as opposed to an input/output failure (1).
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct Options {
  std::string in;
  std::string out;
  std::string filter;
  std::vector<std::string> sets;
  bool metrics = false;
  std::string png;
  bool list_filters = false;
  bool quiet = false;
  std::size_t batch_events = 8192;
  int threads = 1;  ///< threads the filter's blocks are spread over (curvature: row bands; decisions do not change)
};

using Settings = std::vector<std::pair<std::string, std::string>>;

Settings parse_settings(const std::vector<std::string>& sets) {
  Settings out;
  for (const auto& s : sets) {
    const auto eq = s.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == s.size()) {
      throw UsageError(fmt::format("--set '{}': expected KEY=VALUE (or NAME.KEY=VALUE in a chain)", s));
    }
    out.emplace_back(s.substr(0, eq), s.substr(eq + 1));
  }
  return out;
}

/// Every parameter of every stage with the value it runs with: the user's (NAME.KEY or KEY) or the default.
/// make_filter_chain has already rejected unknown and ambiguous keys, so this mirrors its routing.
std::vector<std::pair<std::string, std::vector<std::pair<std::string, std::string>>>> effective_params(
    const std::string& spec, const Settings& settings) {
  std::vector<std::pair<std::string, std::vector<std::pair<std::string, std::string>>>> stages;
  for (const std::string_view part : filter_chain_names(spec)) {
    const std::string name(part);
    const denoise::FilterSpec* fs = denoise::find_filter(name);
    std::vector<std::pair<std::string, std::string>> values;
    if (fs != nullptr) {
      for (const auto& p : denoise::describe(*fs)) {
        std::string v = p.default_value;
        for (const auto& [key, value] : settings) {
          if (key == p.key || key == name + "." + p.key) v = value;
        }
        values.emplace_back(p.key, v);
      }
    }
    stages.emplace_back(name, std::move(values));
  }
  return stages;
}

void list_filters() {
  for (const auto& spec : denoise::filter_specs()) {
    std::printf("%s\n    %s\n", std::string(spec.name).c_str(), std::string(spec.summary).c_str());
    for (const auto& p : denoise::describe(spec)) {
      std::printf("    --set %s=VALUE  (default %s): %s\n", p.key.c_str(), p.default_value.c_str(), p.help.c_str());
    }
  }
  std::printf(
      "Chains: --filter a,b (an event is kept when every stage keeps it); --set NAME.KEY=VALUE names "
      "the stage when several have KEY.\n");
}

/// The time range of a file's events, for --png's frame choice (a pass over the file before the real one).
std::pair<std::int64_t, std::int64_t> time_range(const std::string& path, const io::ReaderOptions& options) {
  std::int64_t first = 0;
  std::int64_t last = -1;
  bool any = false;
  try {
    io::ReaderOptions quiet = options;
    quiet.on_warning = nullptr;
    auto reader = io::open_reader(path, quiet);
    while (!reader->finished()) {
      const auto batch = reader->next();
      if (!batch) continue;
      for (const Event& e : batch->events) {
        if (!any) first = last = e.t_us;
        any = true;
        first = std::min(first, e.t_us);
        last = std::max(last, e.t_us);
      }
    }
  } catch (const SourceError&) {
    // The main pass reports it; the frames cover what was readable.
  }
  return {first, last};
}

/// Runs a setup step whose std::invalid_argument (unknown filter, bad parameter, bad extension) is a usage error.
template <class F>
auto as_usage(F&& f) {
  try {
    return f();
  } catch (const std::invalid_argument& e) {
    throw UsageError(e.what());
  }
}

/// The filter, timed: `filter_s` is the time inside its own calls, apart from the bookkeeping, metrics and writing
/// around them.
class TimedFilter final : public denoise::Filter {
 public:
  explicit TimedFilter(std::unique_ptr<denoise::Filter> filter) : filter_(std::move(filter)) {}

  [[nodiscard]] std::string_view name() const noexcept override { return filter_->name(); }
  void push(EventSpan events, denoise::Decisions& out) override {
    time([&] { filter_->push(events, out); });
  }
  void finish(denoise::Decisions& out) override {
    time([&] { filter_->finish(out); });
  }
  void reset() override {
    time([&] { filter_->reset(); });
  }
  [[nodiscard]] std::size_t pending() const noexcept override { return filter_->pending(); }
  [[nodiscard]] std::int64_t latency_us() const noexcept override { return filter_->latency_us(); }
  [[nodiscard]] bool has_score() const noexcept override { return filter_->has_score(); }
  [[nodiscard]] std::vector<denoise::ReportItem> report() const override { return filter_->report(); }
  void set_parallelism(int tasks, denoise::TaskRunner runner) override {
    // Counts the calls that really split work (a filter that cannot split never calls the runner).
    filter_->set_parallelism(tasks, [this, runner = std::move(runner)](int count, const std::function<void(int)>& f) {
      if (count > 1) ++parallel_runs_;
      runner(count, f);
    });
  }
  /// Calls of the runner with more than one task (--threads > 1 and a filter that splits its blocks).
  [[nodiscard]] std::uint64_t parallel_runs() const noexcept { return parallel_runs_; }

  [[nodiscard]] double seconds() const { return std::chrono::duration<double>(elapsed_).count(); }

 private:
  template <class F>
  void time(F&& f) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    elapsed_ += std::chrono::steady_clock::now() - t0;
  }

  std::unique_ptr<denoise::Filter> filter_;
  std::chrono::steady_clock::duration elapsed_{};
  std::uint64_t parallel_runs_ = 0;
};

int run(const Options& o) {
  const auto wall_t0 = std::chrono::steady_clock::now();
  if (o.in.empty() || o.out.empty() || o.filter.empty()) {
    throw UsageError("expected IN OUT --filter NAME (see --help, --list-filters)");
  }
  const Settings settings = parse_settings(o.sets);
  io::Format out_format = io::Format::unknown;
  try {
    out_format = io::format_for_output(o.out);
  } catch (const std::invalid_argument&) {
  }
  if (out_format != io::Format::aedat4 && out_format != io::Format::text) {
    throw UsageError(fmt::format("{}: cannot tell the output format from the name (use .aedat4 or .txt)", o.out));
  }
  if (!o.png.empty() && !cv::haveImageWriter(o.png)) {
    throw UsageError(fmt::format("--png {}: not an image type OpenCV can write (use .png)", o.png));
  }
  // Filter names and settings are checked before any file is touched.
  (void)as_usage([&] { return denoise::make_filter_chain(o.filter, settings, kDavis346); });
  std::error_code ec;
  if (fs::exists(o.out, ec) && fs::equivalent(o.in, o.out, ec)) {
    throw UsageError(fmt::format("{}: OUT is the input file", o.out));
  }

  std::uint64_t warnings = 0;
  io::ReaderOptions ropt;
  ropt.batch_events = o.batch_events;
  ropt.out_of_order = io::OutOfOrderPolicy::drop;  // filters need time order; dropped events are counted
  ropt.on_warning = [&warnings](const Warning& w) {
    if (++warnings <= kMaxWarningsShown) std::fprintf(stderr, "evdenoise: warning: %s\n", w.message().c_str());
  };
  auto reader = io::open_reader(o.in, ropt);
  const SensorGeometry geometry = reader->info().geometry;
  const bool labelled = reader->info().labelled;
  TimedFilter filter(as_usage([&] { return denoise::make_filter_chain(o.filter, settings, geometry); }));
  const bool scored = filter.has_score();
  // --threads: the caller's thread and threads − 1 workers (filters that cannot split ignore it).
  runtime::TaskPool pool(o.threads - 1, "evdenoise-");
  if (o.threads > 1) filter.set_parallelism(o.threads, pool.runner());

  std::optional<evdenoise::Preview> preview;
  if (!o.png.empty()) {
    const auto [first, last] = time_range(o.in, ropt);
    preview.emplace(geometry, first, last);
  }

  io::WriterOptions wopt;
  wopt.geometry = geometry;
  wopt.source_name = "evdenoise";
  wopt.inputs = {o.in};  // OUT is never IN (nor a link of it): refused before anything is truncated
  auto writer = io::open_writer(o.out, out_format, wopt);
  if (!o.png.empty()) check_output_file(o.png, std::vector<std::string>{o.in, o.out});

  metrics::EsrAccumulator esr_in(geometry);
  metrics::EsrAccumulator esr_out(geometry);
  metrics::ClassificationCounter counts;
  metrics::AucAccumulator auc;
  // Classification counts and AUC see every decision; the kept events are written (and measured) as they come.
  denoise::FilteredStream stream(filter, [&](const denoise::DecidedSegment& d) {
    const auto labels = d.labels();
    counts.add(d.keep(), labels);
    if (scored && !labels.empty()) auc.add(d.score(), labels);
  });
  std::vector<EventBatch> kept;
  auto write_kept = [&] {
    for (const EventBatch& b : kept) {
      writer->write(b.events, b.labels);
      esr_out.add(b.span());
      if (preview) {
        for (const Event& e : b.events) preview->add_output(e);
      }
    }
    kept.clear();
  };
  std::size_t max_pending = 0;

  std::string error;
  // A file reader may return nullptr before its end (an event held back for the next batch): loop on finished().
  while (!reader->finished()) {
    EventBatchPtr batch;
    try {
      batch = reader->next();
    } catch (const SourceError& e) {
      // A fatal format error mid-file: every batch read before it is valid, so it is decided and written, the
      // output is closed properly, and the run then fails.
      error = e.what();
      break;
    }
    if (!batch) continue;
    esr_in.add(batch->span());
    if (preview) {
      for (const Event& e : batch->events) preview->add_input(e);
    }
    stream.push(batch, kept);
    max_pending = std::max(max_pending, stream.pending());
    write_kept();
  }
  stream.finish(kept);
  write_kept();
  writer->close();
  if (preview) preview->write(o.png, o.filter);

  const auto& cls = counts.result();
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_t0).count();
  if (o.metrics) {
    JsonWriter j;
    j.begin_object();
    j.key("input").value(o.in);
    j.key("input_format").value(reader->info().format);
    j.key("width").value(std::int64_t{geometry.width});
    j.key("height").value(std::int64_t{geometry.height});
    j.key("output").value(o.out);
    j.key("output_format").value(io::format_name(out_format));
    j.key("filter").value(o.filter);
    j.key("filters").begin_array();
    for (const auto& [name, params] : effective_params(o.filter, settings)) {
      j.begin_object().key("name").value(name).key("params").begin_object();
      for (const auto& [key, value] : params) j.key(key).number_or_string(value);
      j.end_object().end_object();
    }
    j.end_array();
    j.key("events_in").value(cls.events_in);
    j.key("events_kept").value(cls.events_kept);
    j.key("events_removed").value(cls.events_removed());
    j.key("kept_fraction").value(cls.kept_fraction());
    j.key("nrr").value(cls.nrr());
    j.key("latency_us").value(filter.latency_us());
    j.key("max_pending_events").value(std::uint64_t{max_pending});
    j.key("threads").value(std::int64_t{o.threads});
    j.key("parallel_runs").value(static_cast<std::int64_t>(filter.parallel_runs()));
    j.key("filter_s").value(filter.seconds());
    j.key("throughput_mev_s")
        .value(filter.seconds() > 0 ? std::optional<double>(static_cast<double>(cls.events_in) / filter.seconds() / 1e6)
                                    : std::nullopt);
    j.key("wall_s").value(wall_s);
    j.key("report").begin_object();
    for (const auto& item : filter.report()) j.key(item.key).value(item.value);
    j.end_object();
    for (const auto& [key, acc] : {std::pair{"esr_raw", &esr_in}, std::pair{"esr_filtered", &esr_out}}) {
      j.key(key).begin_object();
      j.key("mean").value(acc->mean());
      j.key("chunks").value(std::uint64_t{acc->chunks()});
      j.end_object();
    }
    const auto& c = cls.confusion;
    const bool has_labels = labelled && c.has_value();
    auto count_or_null = [&](std::uint64_t v) -> JsonWriter& { return has_labels ? j.value(v) : j.null(); };
    auto ratio_or_null = [&](std::optional<double> v) -> JsonWriter& { return has_labels ? j.value(v) : j.null(); };
    j.key("labelled").value(has_labels);
    j.key("signal_in");
    count_or_null(has_labels ? c->signal() : 0);
    j.key("noise_in");
    count_or_null(has_labels ? c->noise() : 0);
    j.key("tp");
    count_or_null(has_labels ? c->tp : 0);
    j.key("fp");
    count_or_null(has_labels ? c->fp : 0);
    j.key("tn");
    count_or_null(has_labels ? c->tn : 0);
    j.key("fn");
    count_or_null(has_labels ? c->fn : 0);
    j.key("sr");
    ratio_or_null(has_labels ? metrics::signal_retention(*c) : std::nullopt);
    j.key("nr");
    ratio_or_null(has_labels ? metrics::noise_removal(*c) : std::nullopt);
    j.key("precision");
    ratio_or_null(has_labels ? metrics::precision(*c) : std::nullopt);
    j.key("f1");
    ratio_or_null(has_labels ? metrics::f1(*c) : std::nullopt);
    j.key("has_score").value(scored);
    j.key("auc").value(has_labels && scored ? auc.auc() : std::nullopt);
    const auto& st = reader->stats();
    j.key("out_of_order_dropped").value(st.out_of_order);
    j.key("discontinuities").value(st.discontinuities);
    j.key("warnings").value(warnings);
    j.key("error");
    if (error.empty()) {
      j.null();
    } else {
      j.value(error);
    }
    j.end_object();
    std::printf("%s\n", j.str().c_str());
  } else if (!o.quiet) {
    std::printf("%s: %llu events -> %s: %llu kept (%.2f%%), filter %s, %.3f s\n", o.in.c_str(),
                static_cast<unsigned long long>(cls.events_in), o.out.c_str(),
                static_cast<unsigned long long>(cls.events_kept), 100.0 * cls.kept_fraction().value_or(0.0),
                o.filter.c_str(), wall_s);
  }
  if (!error.empty()) {
    std::fprintf(stderr, "evdenoise: %s (the %llu events decided before it were written to %s)\n", error.c_str(),
                 static_cast<unsigned long long>(cls.events_in), o.out.c_str());
    return 1;
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  evpipe::cli::App app{
      "evdenoise: remove noise events from an event recording (AEDAT 2.0/3.1/4.0 or text in; "
      ".aedat4 or .txt out)"};
  app.add_option("IN", o.in, "Input recording (format detected from content)");
  app.add_option("OUT", o.out, "Output file: .aedat4 or .txt (labels of a labelled input kept in .txt)");
  app.add_option("--filter", o.filter, "Filter name, or a chain NAME,NAME,... (see --list-filters)");
  app.add_option("--set", o.sets, "Filter parameter KEY=VALUE, or NAME.KEY=VALUE in a chain (repeatable)")
      ->expected(1)
      ->allow_extra_args(false)
      ->multi_option_policy(evpipe::cli::MultiOptionPolicy::take_all);
  app.add_flag("--metrics", o.metrics, "Print one JSON object of metrics to stdout (docs/evdenoise.md)");
  app.add_option("--png", o.png, "Also write a grid of 30 ms frames before (top) / after (bottom) filtering");
  app.add_flag("--list-filters", o.list_filters, "List every filter with its parameters and defaults, then exit");
  app.add_flag("-q,--quiet", o.quiet, "No summary line");
  app.add_option("--batch-events", o.batch_events, "Events per read batch (decisions do not depend on it)")
      ->check(evpipe::cli::range(std::size_t{1}, std::size_t{1} << 24));
  app.add_option("--threads", o.threads,
                 "Threads one 30 ms block of the curvature filter is spread over (same decisions for any value)")
      ->check(evpipe::cli::range(1, 64));
  if (const auto status = app.parse(argc, argv)) return *status;
  try {
    if (o.list_filters) {
      list_filters();
      return 0;
    }
    return run(o);
  } catch (const UsageError& e) {
    std::fprintf(stderr, "evdenoise: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "evdenoise: %s\n", e.what());
    return 1;
  }
}
