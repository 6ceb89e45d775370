// evpose-eval ESTIMATE.csv TRUTH.csv [--json] [--png PLOT.png] [--only-tracking] [--max-gap-us N]
//
// Accuracy of an estimated trajectory against ground truth (docs/evpose-eval.md): ATE, per-axis and rotation
// errors, coverage. Both files are trajectory CSVs of T_cam_model (interfaces.md); the truth is interpolated at
// each estimated pose's time, with no alignment (both are in the camera frame).
// Exit status: 0 success, 1 input/output error (missing or malformed file, no overlap, image not written),
// 2 usage error.

#include <fmt/format.h>
#include <CLI/CLI.hpp>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "evpipe/camera/error.hpp"
#include "evpipe/camera/trajectory.hpp"
#include "evpipe/core/file.hpp"
#include "evpipe/core/json_quote.hpp"
#include "evpipe/metrics/trajectory.hpp"
#include "plot.hpp"

using namespace evpipe;
namespace fs = std::filesystem;

namespace {

struct Options {
  std::string estimate;
  std::string truth;
  bool json = false;
  std::string png;
  bool only_tracking = false;
  std::int64_t max_gap_us = 100'000;
};

// ---- text -----------------------------------------------------------------------------------------------------

std::string opt_num(const std::optional<double>& v, const char* spec = "{:.3f}") {
  return v ? fmt::format(fmt::runtime(spec), *v) : std::string("n/a");
}

std::string pct(const std::optional<double>& v) {
  return v ? fmt::format("{:.1f} %", 100.0 * *v) : std::string("n/a");
}

std::string stats_row(const std::string& name, const metrics::ErrorStats& s, const std::string& extra = {}) {
  return fmt::format("{:<16}{:>10.3f}{:>10.3f}{:>10.3f}{:>10.3f}{:>10.3f}{}\n", name, s.rmse, s.mean, s.median, s.std,
                     s.max, extra);
}

void print_text(const Options& o, const metrics::TrajectoryEval& r) {
  std::string out = fmt::format("evpose-eval: {} against {}\n", o.estimate, o.truth);
  out += fmt::format("poses: {} in, {} evaluated, {} before and {} after the truth's time range", r.poses_in,
                     r.poses_evaluated, r.poses_before_truth, r.poses_after_truth);
  if (o.only_tracking) out += fmt::format(", {} not tracking (skipped)", r.poses_not_tracking);
  out += "\n";
  if (r.poses_tracking) out += fmt::format("status: {} of {} poses tracking\n", *r.poses_tracking, r.poses_in);
  out += fmt::format(
      "coverage: {} of the poses have truth, {} of the truth's time span covered (gaps <= {} ms), "
      "first pose {} ms after the truth starts\n",
      pct(r.matched_fraction), pct(r.time_coverage), static_cast<double>(o.max_gap_us) / 1000.0,
      opt_num(r.first_pose_delay_ms, "{:.1f}"));
  out += fmt::format("{:<16}{:>10}{:>10}{:>10}{:>10}{:>10}\n", "", "RMSE", "mean", "median", "std", "max");
  out += stats_row("ATE (mm)", *r.ate_mm);
  const char* names[3] = {"|x| (mm)", "|y| (mm)", "|z| (mm)"};
  for (int a = 0; a < 3; ++a) {
    out += stats_row(names[a], r.axis_mm[a]->abs, fmt::format("   bias {:+.3f}", r.axis_mm[a]->bias));
  }
  out += stats_row("rotation (deg)", *r.rotation_deg);
  std::fputs(out.c_str(), stdout);
}

// ---- JSON -----------------------------------------------------------------------------------------------------

std::string json_num(double v) {
  return fmt::format("{}", v);  // shortest round-trip form; the values are finite by construction
}

std::string json_opt(const std::optional<double>& v) {
  return v ? json_num(*v) : std::string("null");
}

std::string json_stats(const metrics::ErrorStats& s) {
  return fmt::format(R"({{"rmse":{},"mean":{},"median":{},"std":{},"max":{}}})", json_num(s.rmse), json_num(s.mean),
                     json_num(s.median), json_num(s.std), json_num(s.max));
}

void print_json(const Options& o, const metrics::TrajectoryEval& r) {
  using evpipe::json_quote;
  std::string out = "{";
  out += fmt::format(R"("estimate":{},"truth":{},"only_tracking":{},"max_gap_us":{},)", json_quote(o.estimate),
                     json_quote(o.truth), o.only_tracking ? "true" : "false", o.max_gap_us);
  out += fmt::format(
      R"("poses_in":{},"poses_evaluated":{},"poses_before_truth":{},"poses_after_truth":{},"poses_not_tracking":{},)",
      r.poses_in, r.poses_evaluated, r.poses_before_truth, r.poses_after_truth, r.poses_not_tracking);
  out += fmt::format(R"("poses_tracking":{},)", r.poses_tracking ? std::to_string(*r.poses_tracking) : "null");
  out += fmt::format(R"("matched_fraction":{},"time_coverage":{},"first_pose_delay_ms":{},)",
                     json_opt(r.matched_fraction), json_opt(r.time_coverage), json_opt(r.first_pose_delay_ms));
  out += fmt::format(R"("ate_mm":{},"axis_mm":{{)", json_stats(*r.ate_mm));
  const char* names[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    const auto& s = r.axis_mm[a]->abs;
    out += fmt::format(R"({}"{}":{{"bias":{},"rmse":{},"mean":{},"median":{},"std":{},"max":{}}})", a ? "," : "",
                       names[a], json_num(r.axis_mm[a]->bias), json_num(s.rmse), json_num(s.mean), json_num(s.median),
                       json_num(s.std), json_num(s.max));
  }
  out += fmt::format(R"(}},"rotation_deg":{}}})", json_stats(*r.rotation_deg));
  out += "\n";
  std::fputs(out.c_str(), stdout);
}

// ---- run ------------------------------------------------------------------------------------------------------

std::string time_range(const std::vector<camera::StampedPose>& t) {
  return fmt::format("[{}, {}] us", t.front().t_us, t.back().t_us);
}

int run(const Options& o) {
  const std::vector<camera::StampedPose> estimate = camera::read_trajectory_csv(o.estimate);
  const std::vector<camera::StampedPose> truth = camera::read_trajectory_csv(o.truth);
  if (estimate.empty()) throw std::runtime_error(fmt::format("{}: no pose rows", o.estimate));
  if (truth.empty()) throw std::runtime_error(fmt::format("{}: no pose rows", o.truth));
  std::vector<std::string> status;
  if (const auto column = camera::read_trajectory_column(o.estimate, "status")) {
    status = *column;
  } else if (o.only_tracking) {
    throw std::runtime_error(fmt::format("{}: line 1: no status column (needed by --only-tracking)", o.estimate));
  }

  metrics::TrajectoryEvalOptions opt;
  opt.only_tracking = o.only_tracking;
  opt.max_gap_us = o.max_gap_us;
  const metrics::TrajectoryEval r = metrics::evaluate_trajectory(estimate, truth, opt, status);
  if (r.poses_evaluated == 0) {
    if (o.only_tracking && r.poses_not_tracking == r.poses_in) {
      throw std::runtime_error(fmt::format("{}: no pose has status 'tracking' ({} poses)", o.estimate, r.poses_in));
    }
    throw std::runtime_error(fmt::format("{}: no pose within the time range of {} {} (poses span {})", o.estimate,
                                         o.truth, time_range(truth), time_range(estimate)));
  }

  if (!o.png.empty()) {  // first: a failure leaves no partial report on stdout
    evpipe::check_output_file(o.png, std::vector<std::string>{o.estimate, o.truth});
    evpose_eval::PlotInput in;
    in.truth = truth;
    in.eval = &r;
    in.max_gap_us = o.max_gap_us;
    in.title = fmt::format(
        "estimate {}  vs  truth {}{}\nATE RMSE {:.2f} mm, mean {:.2f}, median {:.2f}, max {:.2f} mm;  rotation RMSE "
        "{:.2f} deg;  {} poses, {} of the time covered",
        fs::path(o.estimate).filename().string(), fs::path(o.truth).filename().string(),
        o.only_tracking ? "  (tracking poses only)" : "", r.ate_mm->rmse, r.ate_mm->mean, r.ate_mm->median,
        r.ate_mm->max, r.rotation_deg->rmse, r.poses_evaluated, pct(r.time_coverage));
    evpose_eval::write_plot(o.png, in);
  }
  if (o.json) {
    print_json(o, r);
  } else {
    print_text(o, r);
  }
  std::fflush(stdout);
  if (std::ferror(stdout)) throw std::runtime_error("stdout: write error");
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{
      "evpose-eval: accuracy of an estimated trajectory against ground truth (ATE, per-axis and rotation error, "
      "coverage); both are trajectory CSVs of T_cam_model, compared without alignment"};
  app.add_option("ESTIMATE", o.estimate, "Estimated poses (evpipe --poses-out)")->required();
  app.add_option("TRUTH", o.truth, "Ground truth (evsim's <stem>.gt.csv, motion capture)")->required();
  app.add_flag("--json", o.json, "Print one JSON object instead of the table (docs/evpose-eval.md)");
  app.add_option("--png", o.png, "Also draw x/y/z estimated vs truth and the error per axis over time");
  app.add_flag("--only-tracking", o.only_tracking, "Evaluate only rows whose status column is 'tracking'");
  app.add_option("--max-gap-us", o.max_gap_us,
                 "Time coverage: consecutive poses at most this far apart cover the time between them (default "
                 "100000)")
      ->check(CLI::Range(std::int64_t{0}, std::int64_t{3'600'000'000}));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);
    return code == 0 ? 0 : 2;
  }
  try {
    return run(o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "evpose-eval: %s\n", e.what());
    return 1;
  }
}
