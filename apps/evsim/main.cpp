// evsim: writes synthetic DAVIS346 recordings with ground truth (docs/simulation.md). Deterministic: the same
// evsim build, arguments and seed give the same bytes in every output file.
//
//   evsim --scene demo --duration-ms 1000 --noise-hz 1 --seed 1 --out demo.aedat4 --labels demo.txt
//   evsim --pure-noise 3000 --seed 4 --out noise.txt        (the paper's section 4.1 protocol, 30 ms)
//   evsim --camera config/davis346.yaml --model config/target-planar.yaml --distance-m 0.8 --duration-ms 3000
//         --noise-hz 1 --seed 1 --out rec.aedat4 --labels rec.txt --png rec.png
//     3D target: also writes rec.gt.csv, rec.camera.yaml, rec.model.yaml, rec.prior.yaml
// Every mode writes <stem>.manifest.yaml (unless --no-manifest).
// Exit status: 0 success, 1 input/output error, 2 usage error.

#include <fmt/format.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/error.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/prior.hpp"
#include "evpipe/camera/trajectory.hpp"
#include "evpipe/camera/yaml_writer.hpp"
#include "evpipe/cli/cli.hpp"
#include "evpipe/core/file.hpp"
#include "evpipe/io/writer.hpp"
#include "evpipe/sim/distractors.hpp"
#include "evpipe/sim/noise.hpp"
#include "evpipe/sim/recording.hpp"
#include "evpipe/sim/scene2d.hpp"
#include "evpipe/sim/target3d.hpp"

#ifndef EVSIM_VERSION
#define EVSIM_VERSION "unknown"
#endif

namespace fs = std::filesystem;
using namespace evpipe;

namespace {

constexpr std::int64_t kPreviewSpan_us = 30'000;    // the 30 ms window of --png (and of the pure-noise protocol)
constexpr std::int64_t kPureNoiseSpan_us = 30'000;  // paper, section 4.1
constexpr double kMaxDuration_s = 3600.0;           // bounds the trajectory and event memory
constexpr std::int64_t kMaxAbsT0_us =
    1'000'000'000'000'000'000;                   // 31 700 years: t0 + duration + windows never overflow
constexpr double kMaxExpectedNoiseEvents = 2e8;  // ~3 GB of events: refuse rather than exhaust memory
constexpr int kPreviewScale = 2;

/// A problem with the command line (exit 2), as opposed to an input/output failure (exit 1).
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Everything the command line sets. Library defaults come from the library's option structs.
struct Config {
  std::vector<std::string> command;  // argv[1..], recorded in the manifest
  // Output
  std::string out;
  std::string labels_out;
  std::string png_out;
  double png_t_ms = -1;  // < 0: centred on the middle of the recording
  bool png_model = false;
  bool manifest = true;
  // Common
  std::uint64_t seed = 1;
  std::int64_t t0_us = 0;
  double duration_ms = 1000;
  bool duration_given = false;
  sim::NoiseOptions noise;
  // Pure noise
  std::size_t pure_noise = 0;
  // 2D
  std::string scene_name = "demo";
  double speed = 1.0;
  // 3D
  std::string camera_file;
  std::string model_file;
  std::string trajectory_file;
  double distance_m = 0.8;
  std::string orientation_text;
  double view_azimuth_deg = sim::kDefaultViewAzimuth_deg;
  double view_elevation_deg = sim::kDefaultViewElevation_deg;
  bool view_given = false;
  sim::MotionOptions motion;
  sim::EdgeOptions edge;
  double prior_offset_m = 0.05;
  double prior_offset_deg = 10.0;
  double prior_position_tolerance_m = 0.3;
  double prior_angle_tolerance_deg = 45.0;
  std::vector<std::string> stop_text;        // --stop AT_S:FOR_S, parsed into motion.stops
  std::vector<std::string> distractor_text;  // --distractor KIND
  sim::FlickerOptions flicker;
};

enum class Mode { pure_noise, scene2d, target3d };

const char* mode_name(Mode m) {
  switch (m) {
    case Mode::pure_noise:
      return "pure-noise";
    case Mode::scene2d:
      return "scene2d";
    case Mode::target3d:
      return "target3d";
  }
  return "?";
}

/// Independent random streams of one seed (3D scenes): the signal, the motion and the prior do not change
/// when only the noise options change, so a scene at several noise levels has identical signal events.
std::mt19937_64 stream(std::uint64_t seed, std::uint32_t id) {
  std::seed_seq seq{static_cast<std::uint32_t>(seed), static_cast<std::uint32_t>(seed >> 32), id};
  return std::mt19937_64(seq);
}
enum StreamId : std::uint32_t {
  kMotionStream = 1,
  kSignalStream = 2,
  kNoiseStream = 3,
  kPriorStream = 4,
  kDistractorMotionStream = 5,
  kDistractorSignalStream = 6,
  kFlickerStream = 7
};

/// --stop AT_S:FOR_S cells (CLI11 already split comma lists) into sorted, checked stops.
std::vector<sim::MotionStop> parse_stops(const std::vector<std::string>& cells, double ramp_s) {
  std::vector<sim::MotionStop> stops;
  for (const auto& cell : cells) {
    const auto colon = cell.find(':');
    double v[2] = {0, 0};
    bool ok = colon != std::string::npos;
    for (int i = 0; ok && i < 2; ++i) {
      const std::string part = i == 0 ? cell.substr(0, colon) : cell.substr(colon + 1);
      const auto [ptr, ec] = std::from_chars(part.data(), part.data() + part.size(), v[i]);
      ok = !part.empty() && ec == std::errc{} && ptr == part.data() + part.size() && std::isfinite(v[i]) && v[i] >= 0;
    }
    if (!ok) throw UsageError(fmt::format("--stop '{}': expected AT_S:FOR_S (two non-negative numbers)", cell));
    stops.push_back({v[0], v[1]});
  }
  std::sort(stops.begin(), stops.end(), [](const auto& a, const auto& b) { return a.at_s < b.at_s; });
  try {
    (void)sim::motion_time_s(0.0, stops, ramp_s);
  } catch (const std::invalid_argument& e) {
    throw UsageError(
        fmt::format("--stop: {} (each stop needs --stop-ramp-s {} s free before and after it)", e.what(), ramp_s));
  }
  return stops;
}

Eigen::Quaterniond parse_orientation(const std::string& text) {
  std::vector<double> v;
  std::size_t pos = 0;
  while (pos <= text.size()) {
    std::size_t end = text.find(',', pos);
    if (end == std::string::npos) end = text.size();
    std::string cell = text.substr(pos, end - pos);
    cell.erase(0, cell.find_first_not_of(' '));
    cell.erase(cell.find_last_not_of(' ') + 1);
    double x = 0;
    const auto [ptr, ec] = std::from_chars(cell.data(), cell.data() + cell.size(), x);
    if (cell.empty() || ec != std::errc{} || ptr != cell.data() + cell.size() || !std::isfinite(x)) {
      throw UsageError(fmt::format("--orientation: '{}' is not a number (expected qw,qx,qy,qz)", cell));
    }
    v.push_back(x);
    pos = end + 1;
  }
  if (v.size() != 4) throw UsageError(fmt::format("--orientation: expected 4 numbers qw,qx,qy,qz, got {}", v.size()));
  try {
    return camera::from_wire(v[0], v[1], v[2], v[3]);
  } catch (const std::invalid_argument&) {
    throw UsageError("--orientation: the quaternion is zero");
  }
}

void check_expected_noise(const Config& c, const SensorGeometry& g, double span_s) {
  const double expected =
      ((c.noise.rate_hz_per_pixel + c.noise.leak_rate_hz_per_pixel) * static_cast<double>(g.pixels()) +
       c.noise.hot_pixels * c.noise.hot_rate_hz) *
      span_s;
  if (expected > kMaxExpectedNoiseEvents) {
    throw UsageError(fmt::format("the noise options ask for ~{:.3g} events, over the {:.0e} evsim accepts", expected,
                                 kMaxExpectedNoiseEvents));
  }
}

/// Output path `<stem><suffix>` beside --out (stem: --out without its extension).
std::string beside(const std::string& out, const std::string& suffix) {
  fs::path p(out);
  p.replace_extension();
  return p.string() + suffix;
}

/// The input files (--camera, --model, --trajectory) and the outputs written so far: no output may be one of them
/// (the same device and inode, links followed; evpipe/core/file.hpp), so no file evsim reads or has just written is
/// overwritten.
std::vector<std::string> g_files;

void write_text_file(const std::string& path, const std::string& text) {
  const UniqueFile f = open_output_file(path, g_files);
  if (std::fwrite(text.data(), 1, text.size(), f.get()) != text.size() || std::fflush(f.get()) != 0)
    throw std::runtime_error(path + ": write failed");
  g_files.push_back(path);
}

void write_events(const std::string& path, const sim::LabelledEvents& rec, SensorGeometry geometry) {
  io::WriterOptions o;
  o.geometry = geometry;
  o.source_name = "evsim";
  o.inputs = g_files;
  auto w = io::open_writer(path, io::format_for_output(path), o);
  w->write(rec.events, rec.labels);
  w->close();
  g_files.push_back(path);
}

/// The manifest: a YAML document built line by line (numbers in their shortest exact form).
class Manifest {
 public:
  void section(std::string_view name) { text_ += fmt::format("{}:\n", name); }
  void str(std::string_view key, std::string_view v, int indent = 2) {
    line(key, evpipe::camera::yaml_quoted(v), indent);
  }
  void num(std::string_view key, double v, int indent = 2) { line(key, fmt::format("{}", v + 0.0), indent); }
  void integer(std::string_view key, long long v, int indent = 2) { line(key, std::to_string(v), indent); }
  void boolean(std::string_view key, bool v, int indent = 2) { line(key, v ? "true" : "false", indent); }
  void list(std::string_view key, const std::vector<double>& v, int indent = 2) {
    std::string s = "[";
    for (std::size_t i = 0; i < v.size(); ++i) s += fmt::format("{}{}", i ? ", " : "", v[i] + 0.0);
    line(key, s + "]", indent);
  }
  void strings(std::string_view key, const std::vector<std::string>& v, int indent = 2) {
    std::string s = "[";
    for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + evpipe::camera::yaml_quoted(v[i]);
    line(key, s + "]", indent);
  }
  void comment(std::string_view c) { text_ += fmt::format("# {}\n", c); }
  [[nodiscard]] const std::string& text() const { return text_; }

 private:
  void line(std::string_view key, const std::string& value, int indent) {
    text_ += fmt::format("{:{}}{}: {}\n", "", indent, key, value);
  }
  std::string text_;
};

/// A path for the manifest: relative to the manifest's folder (the scene folder can be moved as a whole).
std::string relative_to(const std::string& path, const fs::path& dir) {
  const fs::path abs = fs::absolute(path).lexically_normal();
  const fs::path base = fs::absolute(dir.empty() ? fs::path(".") : dir).lexically_normal();
  const fs::path rel = abs.lexically_relative(base);
  return rel.empty() ? abs.string() : rel.string();
}

/// The --png preview: white background, red ON, blue OFF, scaled kPreviewScale x; optionally the model at the
/// ground-truth pose in grey underneath.
void write_preview(const std::string& path, const sim::LabelledEvents& rec, SensorGeometry g, std::int64_t t0_us,
                   const sim::TargetScene* scene) {
  const int s = kPreviewScale;
  cv::Mat img(g.height * s, g.width * s, CV_8UC3, cv::Scalar(255, 255, 255));
  if (scene != nullptr) {
    if (const auto T = camera::interpolate(scene->trajectory, t0_us + kPreviewSpan_us / 2)) {
      // Scaled pixel coordinates of a pixel centre (u, v): block [s u, s u + s) → centre s u + (s - 1) / 2.
      constexpr int kShift = 4;  // cv::line's fixed-point bits, for sub-pixel endpoints
      auto to_img = [&](const Eigen::Vector2d& px) {
        return cv::Point(static_cast<int>(std::lround((px.x() * s + (s - 1) * 0.5) * (1 << kShift))),
                         static_cast<int>(std::lround((px.y() * s + (s - 1) * 0.5) * (1 << kShift))));
      };
      for (const auto& seg : scene->model.segments_m) {
        // Sampled, so that the distorted image of the line is drawn as the curve it is.
        constexpr int kPieces = 16;
        std::optional<Eigen::Vector2d> prev;
        for (int k = 0; k <= kPieces; ++k) {
          const Eigen::Vector3d p = seg.a_m + (seg.b_m - seg.a_m) * (static_cast<double>(k) / kPieces);
          const auto px = scene->camera.project(T->apply(p));
          if (px && prev && std::abs(px->x()) < 1e5 && std::abs(px->y()) < 1e5 && std::abs(prev->x()) < 1e5 &&
              std::abs(prev->y()) < 1e5) {
            cv::line(img, to_img(*prev), to_img(*px), cv::Scalar(190, 190, 190), 1, cv::LINE_AA, kShift);
          }
          prev = px;
        }
      }
    }
  }
  const auto frame = sim::event_frame(rec.events, g, t0_us, t0_us + kPreviewSpan_us);
  for (int y = 0; y < g.height; ++y) {
    for (int x = 0; x < g.width; ++x) {
      const auto p = frame[static_cast<std::size_t>(y) * static_cast<std::size_t>(g.width) + x];
      if (p == 0) continue;
      const cv::Scalar colour = p > 0 ? cv::Scalar(0, 0, 255) : cv::Scalar(255, 0, 0);  // BGR: red ON, blue OFF
      cv::rectangle(img, cv::Rect(x * s, y * s, s, s), colour, cv::FILLED);
    }
  }
  check_output_file(path, g_files);
  if (!cv::imwrite(path, img)) throw std::runtime_error(path + ": could not write the image");
  g_files.push_back(path);
}

int run(Config& c) {
  g_files = {c.camera_file, c.model_file, c.trajectory_file};
  const Mode mode = c.pure_noise > 0 ? Mode::pure_noise : (!c.model_file.empty() ? Mode::target3d : Mode::scene2d);
  if (!(c.duration_ms * 1e-3 <= kMaxDuration_s)) {
    throw UsageError(fmt::format("--duration-ms {} is over the {} s evsim accepts", c.duration_ms, kMaxDuration_s));
  }
  if (mode == Mode::target3d && c.camera_file.empty()) {
    throw UsageError("--model needs --camera FILE (the calibration, e.g. config/davis346.yaml)");
  }
  if (mode != Mode::target3d && (!c.camera_file.empty() || !c.trajectory_file.empty())) {
    throw UsageError("--camera and --trajectory need --model (a 3D target scene)");
  }
  if (mode != Mode::target3d && c.png_model) throw UsageError("--png-model needs --model (a 3D target scene)");
  if (mode != Mode::target3d && (!c.stop_text.empty() || !c.distractor_text.empty())) {
    throw UsageError("--stop and --distractor need --model (a 3D target scene)");
  }
  c.motion.stops = parse_stops(c.stop_text, c.motion.stop_ramp_s);
  std::vector<sim::DistractorKind> distractors;
  for (const auto& d : c.distractor_text) {
    try {
      distractors.push_back(sim::distractor_kind(d));
    } catch (const std::invalid_argument& e) {
      throw UsageError(fmt::format("--distractor: {}", e.what()));
    }
  }
  if (c.edge.threshold_log <= 0 || c.edge.contrast_log < c.edge.threshold_log) {
    throw UsageError(fmt::format("--contrast ({}) must be >= --threshold ({}) > 0 (no events otherwise)",
                                 c.edge.contrast_log, c.edge.threshold_log));
  }
  if (c.motion.min_freq_hz > c.motion.max_freq_hz) throw UsageError("--min-freq-hz is above --max-freq-hz");
  if (!(c.motion.rate_hz >= 1000.0 && c.motion.rate_hz <= 1e6)) {
    throw UsageError("--gt-rate-hz must be in [1000, 1e6] (ground truth at >= 1 kHz)");
  }
  if (static_cast<double>(c.pure_noise) > kMaxExpectedNoiseEvents) {
    throw UsageError(
        fmt::format("--pure-noise {} is over the {:.0e} events evsim accepts", c.pure_noise, kMaxExpectedNoiseEvents));
  }
  // Check the output names before anything is written, so that a bad one leaves no partial set of files.
  (void)io::format_for_output(c.out);  // throws std::invalid_argument naming the path
  if (!c.labels_out.empty()) (void)io::format_for_output(c.labels_out);
  if (!c.png_out.empty() && !cv::haveImageWriter(c.png_out)) {
    throw UsageError(fmt::format("--png {}: not an image type OpenCV can write (use .png)", c.png_out));
  }

  SensorGeometry g = kDavis346;
  std::int64_t t0_us = c.t0_us;
  std::int64_t t1_us = t0_us + static_cast<std::int64_t>(std::llround(c.duration_ms * 1000.0));
  std::vector<Event> signal;
  std::vector<Event> noise;
  std::vector<std::pair<std::string, std::size_t>> distractor_counts;  // kind, events
  std::vector<std::pair<std::string, std::string>> files;              // role, path
  Manifest m;
  m.comment("evsim manifest: how this recording was made. The same evsim version, arguments and seed give");
  m.comment("identical bytes in every file (docs/simulation.md). Times in microseconds; the events lie in");
  m.comment("[run.t0_us, run.t1_us).");
  m.section("evsim");
  m.str("version", EVSIM_VERSION);
  m.strings("command", c.command);
  m.section("run");
  m.str("mode", mode_name(mode));
  m.integer("seed", static_cast<long long>(c.seed));

  // Things only the 3D mode has.
  sim::TargetScene scene;
  std::string orientation_source;

  if (mode == Mode::pure_noise) {
    std::mt19937_64 rng(c.seed);
    t1_us = t0_us + kPureNoiseSpan_us;
    noise = sim::uniform_noise(g, t0_us, kPureNoiseSpan_us, c.pure_noise, rng);
  } else if (mode == Mode::scene2d) {
    // One generator, render then noise: this order is what tools/make_sample.sh's bundled sample was made with.
    std::mt19937_64 rng(c.seed);
    check_expected_noise(c, g, static_cast<double>(t1_us - t0_us) * 1e-6);
    const auto s2 = sim::named_scene(c.scene_name, c.speed, g);
    signal = sim::render(s2, t0_us, t1_us, {}, rng);
    noise = sim::background_activity(g, t0_us, t1_us, c.noise, rng);
  } else {
    scene.camera = camera::load_camera(c.camera_file);
    scene.model = camera::load_line_model(c.model_file);
    scene.edge = c.edge;
    g = SensorGeometry{scene.camera.width, scene.camera.height};
    std::vector<camera::StampedPose> trajectory;
    if (!c.trajectory_file.empty()) {
      trajectory = camera::read_trajectory_csv(c.trajectory_file);
      if (trajectory.size() < 2 || trajectory.back().t_us <= trajectory.front().t_us) {
        throw std::runtime_error(c.trajectory_file + ": a trajectory needs at least two rows spanning some time");
      }
      t0_us = trajectory.front().t_us;
      t1_us = trajectory.back().t_us;
      if (c.duration_given)
        t1_us = std::min(t1_us, t0_us + static_cast<std::int64_t>(std::llround(c.duration_ms * 1e3)));
      if (static_cast<double>(t1_us - t0_us) * 1e-6 > kMaxDuration_s) {
        throw UsageError(fmt::format("{}: spans {} s, over the {} s evsim accepts (limit it with --duration-ms)",
                                     c.trajectory_file, static_cast<double>(t1_us - t0_us) * 1e-6, kMaxDuration_s));
      }
      // Keep the rows before t1 and the first at or after it (rendering interpolates up to t1), then make it
      // at least as dense as --gt-rate-hz: inserted rows lie on the interpolation, so this is the same motion.
      const auto end = std::lower_bound(trajectory.begin(), trajectory.end(), t1_us,
                                        [](const camera::StampedPose& p, std::int64_t t) { return p.t_us < t; });
      trajectory.erase(end == trajectory.end() ? end : end + 1, trajectory.end());
      trajectory = sim::densify(trajectory, static_cast<std::int64_t>(std::floor(1e6 / c.motion.rate_hz)));
      orientation_source = "trajectory";
    } else {
      Eigen::Quaterniond R;
      if (!c.orientation_text.empty()) {
        R = parse_orientation(c.orientation_text);
        orientation_source = "--orientation";
      } else if (c.view_given) {
        R = sim::look_at_z_up(c.view_azimuth_deg, c.view_elevation_deg);
        orientation_source = "--view-azimuth-deg/--view-elevation-deg";
      } else {
        R = sim::default_view(scene.model);
        orientation_source = R.isApprox(Eigen::Quaterniond::Identity(), 0.0) ? "default: planar model, facing"
                                                                             : "default: front-left three-quarter";
      }
      if (!(c.distance_m > 0)) throw UsageError("--distance-m must be > 0");
      c.motion.base = sim::facing_pose(scene.model, c.distance_m, R);
      c.motion.pivot_model_m = sim::bbox_centre(scene.model);
      auto rng = stream(c.seed, kMotionStream);
      trajectory = sim::generate_motion(t0_us, t1_us, c.motion, rng);
    }
    check_expected_noise(c, g, static_cast<double>(t1_us - t0_us) * 1e-6);

    // The ground truth is written first and read back: the events are rendered from exactly what the file
    // holds (its 1 µm / 1e-9 rounding included), so a reader of gt.csv has the very trajectory that made them.
    const std::string gt_path = beside(c.out, ".gt.csv");
    {
      camera::TrajectoryCsvWriter w(gt_path, {}, g_files);
      for (const auto& p : trajectory) w.write(p);
      w.flush();
    }
    g_files.push_back(gt_path);
    files.emplace_back("ground_truth", gt_path);
    scene.trajectory = camera::read_trajectory_csv(gt_path);

    auto signal_rng = stream(c.seed, kSignalStream);
    signal = sim::render_target(scene, t0_us, t1_us, signal_rng);
    // Distractors: their own streams, so the target's events are the same with and without them.
    if (!distractors.empty()) {
      auto motion_rng = stream(c.seed, kDistractorMotionStream);
      auto body_rng = stream(c.seed, kDistractorSignalStream);
      auto flicker_rng = stream(c.seed, kFlickerStream);
      const int levels = std::max(1, static_cast<int>(std::floor(c.edge.contrast_log / c.edge.threshold_log + 1e-9)));
      for (const auto kind : distractors) {
        std::vector<Event> ev;
        if (kind == sim::DistractorKind::flicker) {
          const auto patch =
              sim::flicker_patch(scene.camera, scene.model, scene.trajectory.front().pose, c.flicker.size_px);
          ev = sim::flicker_events(patch, t0_us, t1_us, c.flicker, levels, c.edge.jitter_us, flicker_rng);
        } else {
          const auto body =
              sim::make_distractor_body(kind, scene.camera, scene.model, scene.trajectory, c.motion, motion_rng);
          sim::TargetScene ds;
          ds.camera = scene.camera;
          ds.model = body.model;
          ds.trajectory = body.trajectory;
          ds.edge = scene.edge;
          ev = sim::render_target(ds, t0_us, t1_us, body_rng);
        }
        distractor_counts.emplace_back(sim::to_string(kind), ev.size());
        signal.insert(signal.end(), ev.begin(), ev.end());
      }
      std::stable_sort(signal.begin(), signal.end(), [](const Event& a, const Event& b) { return a.t_us < b.t_us; });
    }
    auto noise_rng = stream(c.seed, kNoiseStream);
    noise = sim::background_activity(g, t0_us, t1_us, c.noise, noise_rng);

    const std::string camera_path = beside(c.out, ".camera.yaml");
    write_text_file(camera_path, camera::to_yaml(scene.camera));
    files.emplace_back("camera", camera_path);
    const std::string model_path = beside(c.out, ".model.yaml");
    write_text_file(model_path, camera::to_yaml(scene.model, "mm"));
    files.emplace_back("model", model_path);

    camera::PosePrior prior;
    auto prior_rng = stream(c.seed, kPriorStream);
    prior.pose = sim::perturb_pose(scene.trajectory.front().pose, c.prior_offset_m, c.prior_offset_deg, prior_rng);
    prior.position_tolerance_m = c.prior_position_tolerance_m;
    prior.angle_tolerance_deg = c.prior_angle_tolerance_deg;
    const std::string prior_path = beside(c.out, ".prior.yaml");
    write_text_file(prior_path, camera::to_yaml(prior));
    files.emplace_back("prior", prior_path);
  }

  const sim::LabelledEvents rec = sim::merge_labelled(signal, noise);
  write_events(c.out, rec, g);
  files.insert(files.begin(), {"events", c.out});
  if (!c.labels_out.empty()) {
    write_events(c.labels_out, rec, g);
    files.insert(files.begin() + 1, {"labels", c.labels_out});
  }
  std::int64_t preview_t0_us = 0;
  if (!c.png_out.empty()) {
    preview_t0_us = c.png_t_ms >= 0 ? t0_us + static_cast<std::int64_t>(std::llround(c.png_t_ms * 1000.0))
                                    : std::max(t0_us, t0_us + (t1_us - t0_us) / 2 - kPreviewSpan_us / 2);
    write_preview(c.png_out, rec, g, preview_t0_us, mode == Mode::target3d && c.png_model ? &scene : nullptr);
    files.emplace_back("preview", c.png_out);
  }

  // ---- manifest ----
  m.integer("t0_us", t0_us);
  m.integer("t1_us", t1_us);
  m.integer("width", g.width);
  m.integer("height", g.height);
  if (mode == Mode::pure_noise) {
    m.section("pure_noise");
    m.integer("events", static_cast<long long>(c.pure_noise));
    m.integer("span_us", kPureNoiseSpan_us);
  } else if (mode == Mode::scene2d) {
    m.section("scene2d");
    m.str("scene", c.scene_name);
    m.num("speed", c.speed);
    m.num("max_step_px", sim::RenderOptions{}.max_step_px);
    m.num("jitter_us", sim::RenderOptions{}.jitter_us);
  } else {
    m.section("target3d");
    m.str("camera", c.camera_file);
    m.str("model", c.model_file);
    m.str("model_name", scene.model.name);
    m.integer("model_segments", static_cast<long long>(scene.model.segments_m.size()));
    m.str("trajectory", c.trajectory_file.empty() ? "generated" : c.trajectory_file);
    m.integer("trajectory_rows", static_cast<long long>(scene.trajectory.size()));
    m.num("gt_rate_hz", c.motion.rate_hz);
    m.str("orientation_source", orientation_source);
    if (c.trajectory_file.empty()) {
      const auto& base = c.motion.base;
      const auto q = camera::to_wire(base.q_cam_model);
      m.num("distance_m", c.distance_m);
      m.list("base_position_m", {base.t_cam_model_m.x(), base.t_cam_model_m.y(), base.t_cam_model_m.z()});
      m.list("base_orientation", {q.qw, q.qx, q.qy, q.qz});
      m.list("pivot_model_m", {c.motion.pivot_model_m.x(), c.motion.pivot_model_m.y(), c.motion.pivot_model_m.z()});
      if (c.view_given) {
        m.num("view_azimuth_deg", c.view_azimuth_deg);
        m.num("view_elevation_deg", c.view_elevation_deg);
      }
      m.num("range_m", c.motion.range_m);
      m.num("range_deg", c.motion.range_deg);
      m.num("max_speed_m_s", c.motion.max_speed_m_s);
      m.num("max_angular_speed_deg_s", c.motion.max_angular_speed_deg_s);
      m.num("min_freq_hz", c.motion.min_freq_hz);
      m.num("max_freq_hz", c.motion.max_freq_hz);
      if (!c.motion.stops.empty()) {
        std::vector<double> at, dur;
        for (const auto& st : c.motion.stops) {
          at.push_back(st.at_s);
          dur.push_back(st.for_s);
        }
        m.list("stops_at_s", at);
        m.list("stops_for_s", dur);
        m.num("stop_ramp_s", c.motion.stop_ramp_s);
      }
    }
    if (!distractor_counts.empty()) {
      m.comment("distractors: real scene edges that are not the target, labelled signal (1); the ground truth is");
      m.comment("the target's only");
      m.section("distractors");
      for (const auto& [kind, n] : distractor_counts) m.integer(kind, static_cast<long long>(n));
      m.num("flicker_hz", c.flicker.rate_hz);
      m.integer("flicker_size_px", c.flicker.size_px);
      m.integer("motion_stream", kDistractorMotionStream);
      m.integer("signal_stream", kDistractorSignalStream);
      m.integer("flicker_stream", kFlickerStream);
    }
    m.section("edge");
    m.num("contrast_log", c.edge.contrast_log);
    m.num("threshold_log", c.edge.threshold_log);
    m.integer("events_per_crossing",
              std::max(1, static_cast<int>(std::floor(c.edge.contrast_log / c.edge.threshold_log + 1e-9))));
    m.num("blur_px", c.edge.blur_px);
    m.integer("refractory_us", c.edge.refractory_us);
    m.num("jitter_us", c.edge.jitter_us);
    m.num("max_step_px", c.edge.max_step_px);
    m.section("prior");
    m.num("offset_m", c.prior_offset_m);
    m.num("offset_deg", c.prior_offset_deg);
    m.num("position_tolerance", c.prior_position_tolerance_m);
    m.num("angle_tolerance_deg", c.prior_angle_tolerance_deg);
    m.comment("std::mt19937_64 per stream, seeded with std::seed_seq{seed low 32 bits, seed high 32 bits, stream}");
    m.section("random_streams");
    m.integer("motion", kMotionStream);
    m.integer("signal", kSignalStream);
    m.integer("noise", kNoiseStream);
    m.integer("prior", kPriorStream);
  }
  if (mode != Mode::pure_noise) {
    m.section("noise");
    m.num("rate_hz_per_pixel", c.noise.rate_hz_per_pixel);
    m.num("on_share", c.noise.on_share);
    m.num("leak_rate_hz_per_pixel", c.noise.leak_rate_hz_per_pixel);
    m.integer("hot_pixels", c.noise.hot_pixels);
    m.num("hot_rate_hz", c.noise.hot_rate_hz);
  }
  std::size_t on = 0;
  for (const auto& e : rec.events) on += e.polarity ? 1 : 0;
  m.section("events");
  m.integer("total", static_cast<long long>(rec.events.size()));
  m.integer("signal", static_cast<long long>(signal.size()));
  m.integer("noise", static_cast<long long>(noise.size()));
  m.integer("on", static_cast<long long>(on));
  m.integer("off", static_cast<long long>(rec.events.size() - on));
  if (!rec.events.empty()) {
    m.integer("first_t_us", rec.events.front().t_us);
    m.integer("last_t_us", rec.events.back().t_us);
  }
  if (!c.png_out.empty()) {
    m.section("preview");
    m.integer("t0_us", preview_t0_us);
    m.integer("span_us", kPreviewSpan_us);
    m.integer("scale", kPreviewScale);
    m.boolean("model_overlay", c.png_model);
  }
  const std::string manifest_path = beside(c.out, ".manifest.yaml");
  if (c.manifest) {
    files.emplace_back("manifest", manifest_path);
    m.comment("paths relative to this manifest's folder");
    m.section("files");
    for (const auto& [role, path] : files) m.str(role, relative_to(path, fs::path(manifest_path).parent_path()));
    write_text_file(manifest_path, m.text());
  }
  std::printf("evsim: %zu events (%zu signal, %zu noise) -> %s\n", rec.events.size(), signal.size(), noise.size(),
              c.out.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Config c;
  for (int i = 1; i < argc; ++i) c.command.emplace_back(argv[i]);
  evpipe::cli::App app{
      "evsim: synthetic DAVIS346 event recordings with ground truth (docs/simulation.md). Modes: a 2D scene "
      "(--scene, default), the paper's pure-noise protocol (--pure-noise N), or a 3D line-model target "
      "(--camera + --model)."};
  app.set_version_flag("--version", std::string("evsim ") + EVSIM_VERSION);
  app.always_capture_default();  // --help shows every default
  app.add_option("--out", c.out, "Output recording (.aedat4, .aedat3 or .txt); other files go beside it")->required();
  app.add_option("--labels", c.labels_out, "Also write labelled text 't x y p label' (1 signal, 0 noise) here");
  app.add_option("--png", c.png_out, "Also write a 30 ms event frame (white, red ON, blue OFF, 2x) here");
  app.add_option("--png-t-ms", c.png_t_ms,
                 "Start of the --png window, ms after the recording's start "
                 "(default: the window centred on the middle)")
      ->check(evpipe::cli::non_negative_number())
      ->default_str("middle");
  app.add_flag("--png-model", c.png_model, "3D: draw the model at the ground-truth pose in grey under the events");
  app.add_flag("!--no-manifest", c.manifest, "Do not write <stem>.manifest.yaml");
  app.add_option("--seed", c.seed, "Random seed");
  auto* t0 = app.add_option("--t0-us", c.t0_us, "Timestamp of the start (not with --trajectory: its own times)");
  auto* dur = app.add_option("--duration-ms", c.duration_ms,
                             "Length of the recording (with --trajectory: cut the trajectory to this)")
                  ->check(evpipe::cli::positive_number());
  app.add_option("--noise-hz", c.noise.rate_hz_per_pixel, "Background activity per pixel (Hz)")
      ->check(evpipe::cli::non_negative_number());
  app.add_option("--noise-on-share", c.noise.on_share, "Share of noise events that are ON")
      ->check(evpipe::cli::range(0.0, 1.0));
  app.add_option("--leak-hz", c.noise.leak_rate_hz_per_pixel, "Leak events per pixel (Hz, ON only)")
      ->check(evpipe::cli::non_negative_number());
  app.add_option("--hot-pixels", c.noise.hot_pixels, "Number of hot pixels")->check(evpipe::cli::non_negative_number());
  app.add_option("--hot-rate-hz", c.noise.hot_rate_hz, "Rate of each hot pixel (Hz)")
      ->check(evpipe::cli::non_negative_number());
  auto* pure =
      app.add_option("--pure-noise", c.pure_noise, "Paper protocol: exactly N noise events in 30 ms, no scene");
  // 2D
  auto* scene = app.add_option("--scene", c.scene_name, "2D scene: rotating-bar, translating-rect, demo");
  // Bounded: the events grow with the speed (x1 is 60-240 px/s; x100 is beyond any sensor's pixel rate), and 1e300
  // generated events for ever.
  auto* speed =
      app.add_option("--speed", c.speed, "2D scene speed factor, in (0, 100]")->check(evpipe::cli::range(1e-6, 100.0));
  // 3D
  auto* cam = app.add_option("--camera", c.camera_file, "3D: camera calibration (evpipe YAML or OpenCV FileStorage)");
  auto* model = app.add_option("--model", c.model_file, "3D: line model of the target (YAML or DXF)");
  auto* traj = app.add_option("--trajectory", c.trajectory_file,
                              "3D: follow this trajectory CSV (t_us,x_m,...) instead of generated motion");
  auto* dist = app.add_option("--distance-m", c.distance_m, "3D: distance of the model's bounding-box centre");
  auto* orient = app.add_option("--orientation", c.orientation_text,
                                "3D: R_cam_model as qw,qx,qy,qz (default: per model, see docs/simulation.md)");
  auto* az = app.add_option("--view-azimuth-deg", c.view_azimuth_deg,
                            "3D, z-up models: view from this azimuth (0 front, 90 left side)");
  auto* el = app.add_option("--view-elevation-deg", c.view_elevation_deg, "3D, z-up models: view from this elevation")
                 ->check(evpipe::cli::range(-89.0, 89.0));
  std::vector<evpipe::cli::Option*> motion_opts = {dist, orient, az, el};
  motion_opts.push_back(app.add_option("--range-m", c.motion.range_m, "3D motion: max excursion per axis (m)")
                            ->check(evpipe::cli::non_negative_number()));
  motion_opts.push_back(app.add_option("--range-deg", c.motion.range_deg, "3D motion: max rotation per axis (deg)")
                            ->check(evpipe::cli::non_negative_number()));
  motion_opts.push_back(app.add_option("--max-speed-m-s", c.motion.max_speed_m_s, "3D motion: max speed")
                            ->check(evpipe::cli::non_negative_number()));
  motion_opts.push_back(
      app.add_option("--max-angular-speed-deg-s", c.motion.max_angular_speed_deg_s, "3D motion: max angular speed")
          ->check(evpipe::cli::non_negative_number()));
  motion_opts.push_back(app.add_option("--min-freq-hz", c.motion.min_freq_hz, "3D motion: lowest frequency")
                            ->check(evpipe::cli::positive_number()));
  motion_opts.push_back(app.add_option("--max-freq-hz", c.motion.max_freq_hz, "3D motion: highest frequency")
                            ->check(evpipe::cli::positive_number()));
  auto* stop = app.add_option("--stop", c.stop_text,
                              "3D motion: stand still from AT_S for FOR_S seconds, AT_S:FOR_S (repeatable or "
                              "comma-separated); the motion pauses and continues where it stopped")
                   ->delimiter(',');
  motion_opts.push_back(stop);
  motion_opts.push_back(app.add_option("--stop-ramp-s", c.motion.stop_ramp_s,
                                       "3D motion: slowing down before / speeding up after each stop (s)")
                            ->check(evpipe::cli::non_negative_number()));
  app.add_option("--distractor", c.distractor_text,
                 "3D clutter (repeatable or comma-separated): lines, moving-lines, decoy, decoy-static, flicker "
                 "(docs/simulation.md); its events are labelled signal, the ground truth is the target's")
      ->delimiter(',');
  app.add_option("--flicker-hz", c.flicker.rate_hz, "3D clutter: flicker cycles per second")
      ->check(evpipe::cli::positive_number());
  app.add_option("--flicker-size-px", c.flicker.size_px, "3D clutter: side of the flicker patch (px)")
      ->check(evpipe::cli::range(1, 100));
  app.add_option("--gt-rate-hz", c.motion.rate_hz, "3D: ground-truth rows per second (>= 1000)");
  app.add_option("--contrast", c.edge.contrast_log, "3D edges: log-intensity step across an edge")
      ->check(evpipe::cli::positive_number());
  app.add_option("--threshold", c.edge.threshold_log, "3D edges: contrast threshold (log units)")
      ->check(evpipe::cli::positive_number());
  app.add_option("--blur-px", c.edge.blur_px, "3D edges: width of the intensity ramp (px)")
      ->check(evpipe::cli::non_negative_number());
  app.add_option("--refractory-us", c.edge.refractory_us, "3D edges: per-pixel refractory period")
      ->check(evpipe::cli::non_negative_number());
  app.add_option("--jitter-us", c.edge.jitter_us, "3D edges: std. dev. of timestamp jitter")
      ->check(evpipe::cli::non_negative_number());
  app.add_option("--max-step-px", c.edge.max_step_px, "3D edges: largest segment motion per simulation step")
      ->check(evpipe::cli::range(0.01, 2.0));
  app.add_option("--prior-offset-m", c.prior_offset_m, "3D: prior = first ground-truth pose moved by this")
      ->check(evpipe::cli::non_negative_number());
  app.add_option("--prior-offset-deg", c.prior_offset_deg, "3D: ... and turned by this")
      ->check(evpipe::cli::range(0.0, 180.0));
  app.add_option("--prior-position-tolerance-m", c.prior_position_tolerance_m, "3D: prior's position_tolerance")
      ->check(evpipe::cli::positive_number());
  app.add_option("--prior-angle-tolerance-deg", c.prior_angle_tolerance_deg, "3D: prior's angle_tolerance_deg")
      ->check(evpipe::cli::range(0.001, 180.0));
  pure->excludes(scene)->excludes(model);
  scene->excludes(model);
  speed->excludes(model)->excludes(pure);
  traj->excludes(t0);
  for (auto* o : motion_opts) traj->excludes(o);
  orient->excludes(az)->excludes(el);
  (void)cam;
  if (const auto status = app.parse(argc, argv)) return *status;
  // Issue 17 row 13: CLI11 parses nan and inf as numbers and its range checks let NaN through (--noise-hz nan gave
  // no noise, exit 0). Every floating-point option must be finite; times must leave room for the recording.
  for (const auto& o : app.options()) {
    if (o->get_type_name().rfind("FLOAT", 0) != 0 || o->count() == 0) continue;  // "FLOAT" or "FLOAT:..." (checks)
    for (const auto& text : o->results()) {
      char* end = nullptr;
      const double v = std::strtod(text.c_str(), &end);
      if (!std::isfinite(v)) {
        std::fprintf(stderr, "evsim: %s: must be a finite number, got '%s'\n", o->get_name().c_str(), text.c_str());
        return 2;
      }
    }
  }
  if (c.t0_us < -kMaxAbsT0_us || c.t0_us > kMaxAbsT0_us) {
    std::fprintf(
        stderr, "evsim: --t0-us: must be in [%lld, %lld] (the recording's times must not overflow), got %lld\n",
        static_cast<long long>(-kMaxAbsT0_us), static_cast<long long>(kMaxAbsT0_us), static_cast<long long>(c.t0_us));
    return 2;
  }
  c.duration_given = dur->count() > 0;
  c.view_given = az->count() > 0 || el->count() > 0;
  try {
    return run(c);
  } catch (const UsageError& e) {
    std::fprintf(stderr, "evsim: %s\n", e.what());
    return 2;
  } catch (const std::invalid_argument& e) {  // unknown scene name, unknown output extension
    std::fprintf(stderr, "evsim: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "evsim: %s\n", e.what());
    return 1;
  }
}
