// evpose-eval ESTIMATE.csv TRUTH.csv [--json] [--png PLOT.png] [--only-tracking] [--max-gap-us N]
//             [--wrong-max-mm MM] [--wrong-max-deg DEG] [--symmetry planar-rect|FILE] [--model MODEL]
//             [--errors-out FILE]
//
// Accuracy of an estimated trajectory against ground truth (docs/evpose-eval.md): ATE, per-axis and rotation
// errors, coverage. Both files are trajectory CSVs of T_cam_model (interfaces.md); the truth is interpolated at
// each estimated pose's time, with no alignment (both are in the camera frame).
// Exit status: 0 success, 1 input/output error (missing or malformed file, no overlap, image not written),
// 2 usage error.

#include <fmt/format.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "evpipe/camera/error.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/trajectory.hpp"
#include "evpipe/cli/cli.hpp"
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
  double wrong_max_mm = 20.0;
  double wrong_max_deg = 2.0;
  std::string symmetry;  // "", "planar-rect" or a file
  std::string model;     // the line model, for --symmetry planar-rect
  std::string errors_out;
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
  if (r.poses_tracking) {
    out += fmt::format("status: {} of {} poses tracking, {} holding\n", *r.poses_tracking, r.poses_in,
                       r.poses_holding.value_or(0));
  }
  out += fmt::format("wrong confident poses (tracking/holding, > {} mm or > {} deg): {} of {}\n", o.wrong_max_mm,
                     o.wrong_max_deg, r.wrong_confident, r.confident_evaluated);
  out += r.nees_mean ? fmt::format(
                           "NEES (tracking poses with a covariance, 6 = honest): mean {:.2f}, median {:.2f} "
                           "over {} poses{}\n",
                           *r.nees_mean, *r.nees_median, r.nees_count,
                           r.nees_invalid ? fmt::format(", {} not positive definite", r.nees_invalid) : "")
                     : std::string("NEES: n/a (no covariance)\n");
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
  out += fmt::format(R"("poses_holding":{},)", r.poses_holding ? std::to_string(*r.poses_holding) : "null");
  out +=
      fmt::format(R"("wrong_max_mm":{},"wrong_max_deg":{},"symmetry":{},"confident_evaluated":{},"wrong_confident":{},)"
                  R"("wrong_confident_share":{},)",
                  json_num(o.wrong_max_mm), json_num(o.wrong_max_deg), json_quote(o.symmetry), r.confident_evaluated,
                  r.wrong_confident, json_opt(r.wrong_confident_share));
  out += fmt::format(R"("nees_count":{},"nees_invalid":{},"nees_mean":{},"nees_median":{},)", r.nees_count,
                     r.nees_invalid, json_opt(r.nees_mean), json_opt(r.nees_median));
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

/// The cov_0..cov_35 columns (evpipe --poses-out): one optional 6x6 matrix per row; empty cells (or no columns)
/// give nullopt. A row with some but not all 36 cells, or a cell that is not a number, is an error.
std::vector<std::optional<Eigen::Matrix<double, 6, 6>>> read_covariances(const std::string& path, std::size_t rows) {
  std::vector<std::optional<Eigen::Matrix<double, 6, 6>>> out;
  std::vector<std::vector<std::string>> cols;
  for (int k = 0; k < 36; ++k) {
    auto c = camera::read_trajectory_column(path, fmt::format("cov_{}", k));
    if (!c) {
      if (k == 0) return out;  // no covariance columns at all
      throw std::runtime_error(fmt::format("{}: line 1: cov_0 present but no cov_{} column", path, k));
    }
    cols.push_back(std::move(*c));
  }
  out.resize(rows);
  for (std::size_t i = 0; i < rows && i < cols[0].size(); ++i) {
    int empty = 0;
    Eigen::Matrix<double, 6, 6> P;
    for (int k = 0; k < 36; ++k) {
      const std::string& cell = cols[static_cast<std::size_t>(k)][i];
      if (cell.empty()) {
        ++empty;
        continue;
      }
      std::size_t used = 0;
      double v = 0;
      try {
        v = std::stod(cell, &used);
      } catch (const std::exception&) {
        used = 0;
      }
      if (used != cell.size()) {
        throw std::runtime_error(
            fmt::format("{}: pose row {}: column cov_{}: not a number: '{}'", path, i + 1, k, cell));
      }
      P(k / 6, k % 6) = v;
    }
    if (empty == 0) {
      out[i] = P;
    } else if (empty != 36) {
      throw std::runtime_error(
          fmt::format("{}: pose row {}: {} of the 36 cov_ cells empty (all or none)", path, i + 1, empty));
    }
  }
  return out;
}

/// --symmetry: "planar-rect" (needs --model) or a trajectory CSV whose rows are the transforms S (t_us ignored).
std::vector<camera::Pose> load_symmetries(const Options& o) {
  if (o.symmetry.empty()) return {};
  if (o.symmetry == "planar-rect") {
    if (o.model.empty()) throw std::runtime_error("--symmetry planar-rect needs --model MODEL (the line model)");
    const auto model = camera::load_line_model(o.model);
    std::vector<Eigen::Vector3d> pts;
    for (const auto& s : model.segments_m) {
      pts.push_back(s.a_m);
      pts.push_back(s.b_m);
    }
    try {
      return metrics::planar_rect_symmetries(pts);
    } catch (const std::invalid_argument&) {
      throw std::runtime_error(
          fmt::format("{}: --symmetry planar-rect: the model's points do not share one z", o.model));
    }
  }
  std::vector<camera::Pose> out;
  for (const auto& sp : camera::read_trajectory_csv(o.symmetry)) out.push_back(sp.pose);
  if (out.empty()) throw std::runtime_error(fmt::format("{}: no transform rows", o.symmetry));
  return out;
}

/// --errors-out: one row per evaluated pose; never one of the inputs (refused before anything is truncated).
void write_errors(const std::string& path, const metrics::TrajectoryEval& r, const std::vector<std::string>& inputs) {
  UniqueFile f = open_output_file(path, inputs);
  fmt::print(f.get(), "t_us,status,confident,wrong,error_mm,rotation_deg,ex_mm,ey_mm,ez_mm,nees,symmetry\n");
  for (const auto& s : r.samples) {
    fmt::print(f.get(), "{},{},{},{},{:.4f},{:.5f},{:.4f},{:.4f},{:.4f},{},{}\n", s.t_us, s.status, s.confident ? 1 : 0,
               s.wrong ? 1 : 0, s.error_mm.norm(), s.rotation_error_deg, s.error_mm.x(), s.error_mm.y(), s.error_mm.z(),
               s.nees ? fmt::format("{:.4f}", *s.nees) : std::string(), s.symmetry_index);
  }
  const bool failed = std::ferror(f.get()) != 0;
  if (std::fclose(f.release()) != 0 || failed) throw std::runtime_error(path + ": write failed");
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
  opt.wrong_max_mm = o.wrong_max_mm;
  opt.wrong_max_deg = o.wrong_max_deg;
  opt.symmetries = load_symmetries(o);
  const auto covariance = read_covariances(o.estimate, estimate.size());
  const metrics::TrajectoryEval r = metrics::evaluate_trajectory(estimate, truth, opt, status, covariance);
  if (r.poses_evaluated == 0) {
    if (o.only_tracking && r.poses_not_tracking == r.poses_in) {
      throw std::runtime_error(
          fmt::format("{}: no pose has status 'tracking' or 'holding' ({} poses)", o.estimate, r.poses_in));
    }
    throw std::runtime_error(fmt::format("{}: no pose within the time range of {} {} (poses span {})", o.estimate,
                                         o.truth, time_range(truth), time_range(estimate)));
  }

  const std::vector<std::string> inputs = {o.estimate, o.truth, o.model,
                                           o.symmetry == "planar-rect" ? std::string() : o.symmetry};
  if (!o.errors_out.empty()) write_errors(o.errors_out, r, inputs);
  if (!o.png.empty()) {  // first: a failure leaves no partial report on stdout
    auto files = inputs;
    files.push_back(o.errors_out);  // an output already written is not overwritten either
    evpipe::check_output_file(o.png, files);
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
  evpipe::cli::App app{
      "evpose-eval: accuracy of an estimated trajectory against ground truth (ATE, per-axis and rotation error, "
      "coverage); both are trajectory CSVs of T_cam_model, compared without alignment"};
  app.add_option("ESTIMATE", o.estimate, "Estimated poses (evpipe --poses-out)")->required();
  app.add_option("TRUTH", o.truth, "Ground truth (evsim's <stem>.gt.csv, motion capture)")->required();
  app.add_flag("--json", o.json, "Print one JSON object instead of the table (docs/evpose-eval.md)");
  app.add_option("--png", o.png, "Also draw x/y/z estimated vs truth and the error per axis over time");
  app.add_flag("--only-tracking,--only-valid", o.only_tracking,
               "Evaluate only rows whose status column is 'tracking' or 'holding' (the valid poses)");
  app.add_option("--wrong-max-mm", o.wrong_max_mm, "A tracking/holding pose further off than this is wrong (mm)")
      ->check(evpipe::cli::positive_number());
  app.add_option("--wrong-max-deg", o.wrong_max_deg, "... or turned more than this (deg)")
      ->check(evpipe::cli::positive_number());
  app.add_option("--symmetry", o.symmetry,
                 "Score against each equivalent truth, keep the best: 'planar-rect' (a board; needs --model) or a "
                 "trajectory CSV of model-frame transforms");
  app.add_option("--model", o.model, "The line model (for --symmetry planar-rect)");
  app.add_option("--errors-out", o.errors_out,
                 "Write one CSV row per evaluated pose (t_us,status,confident,wrong,error_mm,rotation_deg,ex/ey/ez_mm,"
                 "nees,symmetry)");
  app.add_option("--max-gap-us", o.max_gap_us,
                 "Time coverage: consecutive poses at most this far apart cover the time between them (default "
                 "100000)")
      ->check(evpipe::cli::range(std::int64_t{0}, std::int64_t{3'600'000'000}));
  if (const auto status = app.parse(argc, argv)) return *status;
  try {
    return run(o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "evpose-eval: %s\n", e.what());
    return 1;
  }
}
