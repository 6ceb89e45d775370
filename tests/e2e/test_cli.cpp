// End-to-end: the real evpipe / evconvert / evsim binaries on recorded files.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <regex>
#include <set>
#include <sstream>

#include "evpipe/camera/camera_model.hpp"
#include "evpipe/camera/line_model.hpp"
#include "evpipe/camera/prior.hpp"
#include "evpipe/camera/trajectory.hpp"
#include "evpipe/io/reader.hpp"
#include "evpipe_run.hpp"
#include "evpipe_test_data.hpp"

namespace fs = std::filesystem;

namespace {

using evpipe::testing::q;
using evpipe::testing::Run;
using evpipe::testing::slurp;

Run run(const std::string& cmd) {
  return evpipe::testing::run(cmd, evpipe::testing::temp_dir("e2e"));
}

using evpipe::testing::json_field;

const std::string kEvpipe = EVPIPE_EXE;
const std::string kEvconvert = EVCONVERT_EXE;
const std::string kSample = (evpipe::testing::source_dir() / "tests/data/demo-sample.aedat4").string();

}  // namespace

TEST(Evpipe, ReplaysTheBundledSample) {
  const auto r = run(kEvpipe + " --replay " + q(kSample) + " --speed max --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto expected = evpipe::io::read_all(kSample);
  EXPECT_EQ(json_field(r.out, "events"), std::to_string(expected.events.size()));
  EXPECT_EQ(json_field(r.out, "format"), "aedat4");
  EXPECT_EQ(json_field(r.out, "width"), "346");
  EXPECT_EQ(json_field(r.out, "height"), "260");
  EXPECT_EQ(json_field(r.out, "first_t_us"), std::to_string(expected.events.front().t_us));
  EXPECT_EQ(json_field(r.out, "last_t_us"), std::to_string(expected.events.back().t_us));
  EXPECT_EQ(json_field(r.out, "out_of_order"), "0");
  EXPECT_EQ(json_field(r.out, "error"), "");
  // evpipe's significance filter by default; 30 ms fixed windows over a 1.5 s recording: each kept event in exactly
  // one.
  EXPECT_EQ(json_field(r.out, "denoise_filter"), "significance");
  EXPECT_EQ(json_field(r.out, "denoise_in"), std::to_string(expected.events.size()));
  const auto kept = std::stoull(json_field(r.out, "denoise_kept"));
  EXPECT_GT(kept, expected.events.size() / 4);
  EXPECT_LT(kept, expected.events.size());
  EXPECT_EQ(json_field(r.out, "window_events"), std::to_string(kept));
  EXPECT_EQ(json_field(r.out, "windows"), "50");
}

TEST(Evpipe, DenoiseNonePassesEveryEvent) {
  const auto r = run(kEvpipe + " --replay " + q(kSample) + " --speed max --json --denoise none");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto expected = evpipe::io::read_all(kSample);
  EXPECT_EQ(json_field(r.out, "denoise_filter"), "none");
  EXPECT_EQ(json_field(r.out, "window_events"), std::to_string(expected.events.size()));
}

TEST(Evpipe, BadDenoiseParameterIsAConfigurationError) {
  const auto dir = evpipe::testing::temp_dir("denoise-cfg");
  const auto cfg = (dir / "bad.yaml").string();
  std::ofstream(cfg) << "denoise:\n  filter: baf\n  params: {duration_us: -3}\n";
  const auto r = run(kEvpipe + " --replay " + q(kSample) + " --speed max --config " + q(cfg));
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("denoise: baf: duration_us=-3: must be > 0"), std::string::npos) << r.err;
  const auto u = run(kEvpipe + " --replay " + q(kSample) + " --speed max --denoise nosuch");
  EXPECT_EQ(u.status, 2);
  EXPECT_NE(u.err.find("unknown filter 'nosuch'"), std::string::npos) << u.err;
}

TEST(Evpipe, TextSummaryNamesEverything) {
  const auto r = run(kEvpipe + " --replay " + q(kSample) + " --speed max");
  ASSERT_EQ(r.status, 0) << r.err;
  for (const char* k : {"events", "duration", "mean rate", "peak rate", "resolution", "ON share", "out-of-order"})
    EXPECT_NE(r.out.find(k), std::string::npos) << k << " missing from:\n" << r.out;
  EXPECT_EQ(r.err.find("\x1b"), std::string::npos) << "no progress bar when stderr is not a terminal";
}

TEST(Evpipe, RealTimePacingTakesTheRecordingsDuration) {
  // --speed 4 on the 1.5 s sample: at least 0.37 s of wall time (a lower bound only).
  const auto r = run(kEvpipe + " --replay " + q(kSample) + " --speed 4 --json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_GE(std::stod(json_field(r.out, "wall_s")), 0.37);
}

TEST(Evpipe, RealRecordingsMatchTheirProvenance) {
  struct Case {
    const char* rel;
    const char* events;
    const char* first;
    const char* last;
  };
  for (const Case& c : {Case{"davis346-faery/davis346.aedat4", "78830", "1589163147368868", "1589163149728813"},
                        Case{"davis240c-rotdisk/IMU_rotDisk.aedat", "374296", "341678", "3508437"},
                        Case{"davis240-text-taro/test-02.txt", "1224", "1645793388095964", "1645793388104036"}}) {
    const auto path = evpipe::testing::real(c.rel);
    if (path.empty()) GTEST_SKIP() << "real recordings not available under " << evpipe::testing::shared_data_dir();
    const auto r = run(kEvpipe + " --replay " + q(path) + " --speed max --json");
    ASSERT_EQ(r.status, 0) << c.rel << ": " << r.err;
    EXPECT_EQ(json_field(r.out, "events"), c.events) << c.rel;
    EXPECT_EQ(json_field(r.out, "first_t_us"), c.first) << c.rel;
    EXPECT_EQ(json_field(r.out, "last_t_us"), c.last) << c.rel;
  }
}

TEST(Evpipe, UnknownFormatFailsWithTheFileName) {
  const auto path = evpipe::testing::real("prophesee-evt3-imx636/evt3.raw");
  if (path.empty()) GTEST_SKIP() << "real recordings not available";
  const auto r = run(kEvpipe + " --replay " + q(path) + " --speed max");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find(path), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("EVT 3.0"), std::string::npos) << r.err;
}

TEST(Evpipe, MissingAndEmptyFiles) {
  auto r = run(kEvpipe + " --replay /nonexistent/x.aedat4");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("/nonexistent/x.aedat4"), std::string::npos) << r.err;
  const auto dir = evpipe::testing::temp_dir("e2e-empty");
  const auto empty = (dir / "empty.aedat4").string();
  std::ofstream(empty).close();
  r = run(kEvpipe + " --replay " + q(empty));
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find(empty), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("empty"), std::string::npos) << r.err;
}

TEST(Evpipe, TruncatedFileKeepsWhatWasReadAndSaysWhere) {
  const auto dir = evpipe::testing::temp_dir("e2e-trunc");
  const auto cut = (dir / "cut.aedat4").string();
  const auto bytes = slurp(kSample);
  std::ofstream(cut, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size() * 2 / 3));
  const auto r = run(kEvpipe + " --replay " + q(cut) + " --speed max --json");
  // Recoverable: a warning naming the file, the events before the cut, exit 0.
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_NE(r.err.find(cut), std::string::npos) << r.err;
  const auto events = std::stoull(json_field(r.out, "events"));
  EXPECT_GT(events, 0U);
  EXPECT_LT(events, evpipe::io::read_all(kSample).events.size());
}

TEST(Evpipe, ConfigErrorsExitTwoWithTheKey) {
  const auto dir = evpipe::testing::temp_dir("e2e-cfg");
  const auto cfg = (dir / "bad.yaml").string();
  std::ofstream(cfg) << "window:\n  hop_us: -3\n";
  auto r = run(kEvpipe + " --replay " + q(kSample) + " --config " + q(cfg));
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("window.hop_us"), std::string::npos) << r.err;
  r = run(kEvpipe + " --replay " + q(kSample) + " --speed fast");
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--speed"), std::string::npos) << r.err;
  r = run(kEvpipe + " --no-such-option");
  EXPECT_EQ(r.status, 2);
}

TEST(Evpipe, ShippedConfigIsAccepted) {
  const auto cfg = (evpipe::testing::source_dir() / "config/evpipe.yaml").string();
  const auto r = run(kEvpipe + " --config " + q(cfg) + " --replay " + q(kSample) + " --speed max --json");
  EXPECT_EQ(r.status, 0) << r.err;
}

TEST(Evconvert, RoundTripsThroughEveryWritableFormat) {
  const auto dir = evpipe::testing::temp_dir("e2e-conv");
  const auto original = evpipe::io::read_all(kSample);
  for (const char* ext : {".txt", ".aedat3", ".aedat4"}) {
    const auto out = (dir / (std::string("x") + ext)).string();
    const auto r = run(kEvconvert + " " + q(kSample) + " " + q(out));
    ASSERT_EQ(r.status, 0) << ext << ": " << r.err;
    const auto back = evpipe::io::read_all(out);
    EXPECT_EQ(back.events, original.events) << ext;
  }
  const auto r = run(kEvconvert + " " + q(kSample) + " " + q((dir / "x.mp4").string()));
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("x.mp4"), std::string::npos);
}

TEST(Evsim, SameSeedSameBytes) {
  const auto dir = evpipe::testing::temp_dir("e2e-sim");
  const std::string args = " --scene demo --duration-ms 200 --noise-hz 2 --seed 9 --out ";
  const auto a = (dir / "a.aedat4").string();
  const auto b = (dir / "b.aedat4").string();
  ASSERT_EQ(run(std::string(EVSIM_EXE) + args + q(a)).status, 0);
  ASSERT_EQ(run(std::string(EVSIM_EXE) + args + q(b)).status, 0);
  EXPECT_EQ(slurp(a), slurp(b));
  EXPECT_FALSE(slurp(a).empty());
}

TEST(Evpipe, VersionNamesTheLibcaerItWasBuiltWith) {
  const auto r = run(kEvpipe + " --version");
  EXPECT_EQ(r.status, 0);
  if (EVPIPE_REAL_LIBCAER) {
    EXPECT_TRUE(std::regex_match(
        r.out, std::regex("evpipe " + std::string(EVPIPE_VERSION) + "\nlibcaer: [0-9]+\\.[0-9]+\\.[0-9]+\n")))
        << r.out;
  } else {
    EXPECT_EQ(r.out, "evpipe " + std::string(EVPIPE_VERSION) + "\nlibcaer: stub: no camera support\n");
  }
}

TEST(Evpipe, LiveModeWithoutLibcaerSaysSo) {
  // With the libcaer stub (CI has no libcaer), asking for the camera must fail clearly.
  if (EVPIPE_REAL_LIBCAER) GTEST_SKIP() << "built against the real libcaer";
  const auto r = run(kEvpipe + " --speed max");
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("libcaer"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--replay"), std::string::npos) << r.err;
}

// ---- evsim 3D target scenes (docs/simulation.md) ----------------------------------------------------------

namespace {

const std::string kEvsim = EVSIM_EXE;
std::string config(const std::string& name) {
  return (evpipe::testing::source_dir() / "config" / name).string();
}

/// Every regular file of a folder, by name.
std::map<std::string, std::string> files_of(const fs::path& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.is_regular_file()) out[e.path().filename().string()] = slurp(e.path());
  return out;
}

/// Lines of a labelled text file that hold events (not '#' comments), and how many carry label 1.
std::pair<std::size_t, std::size_t> count_text_events(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::size_t n = 0, signal = 0;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    ++n;
    signal += line.back() == '1' ? 1 : 0;  // fifth column, the label
  }
  return {n, signal};
}

/// "  key: value" of a manifest section (the first match after "section:").
std::string manifest_value(const std::string& manifest, const std::string& section, const std::string& key) {
  const auto s = manifest.find("\n" + section + ":\n");
  if (s == std::string::npos) return "<no section " + section + ">";
  const std::regex re("\n  " + key + ": ([^\n]*)");
  std::smatch m;
  const std::string rest = manifest.substr(s);
  if (!std::regex_search(rest, m, re)) return "<missing " + key + ">";
  return m[1];
}

const std::string k3dArgs = " --camera " + q(config("davis346.yaml")) + " --model " + q(config("target-planar.yaml")) +
                            " --duration-ms 400 --noise-hz 1 --hot-pixels 2";

}  // namespace

TEST(Evsim, TargetSceneSameSeedSameBytesInEveryFile) {
  const auto dir = evpipe::testing::temp_dir("e2e-sim3d-det");
  const auto run_dir = dir / "run";
  fs::remove_all(run_dir);
  fs::remove_all(dir / "first");
  fs::create_directories(run_dir);
  const std::string outs = " --out " + q((run_dir / "rec.aedat4").string()) + " --labels " +
                           q((run_dir / "rec.txt").string()) + " --png " + q((run_dir / "rec.png").string()) +
                           " --png-model";
  auto r = run(kEvsim + k3dArgs + " --seed 7" + outs);
  ASSERT_EQ(r.status, 0) << r.err;
  fs::rename(run_dir, dir / "first");
  fs::create_directories(run_dir);
  r = run(kEvsim + k3dArgs + " --seed 7" + outs);
  ASSERT_EQ(r.status, 0) << r.err;

  const auto a = files_of(dir / "first");
  const auto b = files_of(run_dir);
  std::vector<std::string> names;
  for (const auto& [name, bytes] : a) names.push_back(name);
  EXPECT_EQ(names, (std::vector<std::string>{"rec.aedat4", "rec.camera.yaml", "rec.gt.csv", "rec.manifest.yaml",
                                             "rec.model.yaml", "rec.png", "rec.prior.yaml", "rec.txt"}));
  ASSERT_EQ(a.size(), b.size());
  for (const auto& [name, bytes] : a) {
    ASSERT_TRUE(b.count(name)) << name;
    EXPECT_FALSE(bytes.empty()) << name;
    EXPECT_TRUE(bytes == b.at(name)) << name << " differs between two runs with the same arguments";
  }
  // A different seed changes the events (the test can fail).
  fs::create_directories(dir / "other");
  ASSERT_EQ(run(kEvsim + k3dArgs + " --seed 8 --out " + q((dir / "other/rec.aedat4").string())).status, 0);
  EXPECT_FALSE(slurp(dir / "other/rec.aedat4") == a.at("rec.aedat4"));
}

TEST(Evsim, TargetSceneOutputsLoadAndAgree) {
  const auto dir = evpipe::testing::temp_dir("e2e-sim3d-out");
  const std::string rec = (dir / "rec.aedat4").string();
  const std::string txt = (dir / "rec.txt").string();
  auto r = run(kEvsim + k3dArgs + " --seed 7 --out " + q(rec) + " --labels " + q(txt));
  ASSERT_EQ(r.status, 0) << r.err;

  // Events: evpipe reads the AEDAT4 back, as many as the labelled text holds; the manifest's counts agree.
  const auto [lines, signal_lines] = count_text_events(txt);
  ASSERT_GT(signal_lines, 1000U);
  ASSERT_GT(lines, signal_lines + 10'000U);  // 1 Hz/pixel over 0.4 s: ~36 000 noise events
  r = run(kEvpipe + " --replay " + q(rec) + " --speed max --json");
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(json_field(r.out, "events"), std::to_string(lines));
  const std::string manifest = slurp(dir / "rec.manifest.yaml");
  EXPECT_EQ(manifest_value(manifest, "events", "total"), std::to_string(lines));
  EXPECT_EQ(manifest_value(manifest, "events", "signal"), std::to_string(signal_lines));
  EXPECT_EQ(manifest_value(manifest, "run", "seed"), "7");
  // std::string first: "x" + std::string(...) draws GCC 12's false -Wrestrict at -O3 (bug 105329).
  EXPECT_EQ(manifest_value(manifest, "evsim", "version"), std::string("\"") + EVPIPE_VERSION + "\"");
  EXPECT_EQ(manifest_value(manifest, "files", "ground_truth"), "\"rec.gt.csv\"");
  // The only absolute paths are the command line's (files are named relative to the manifest).
  std::istringstream manifest_lines(manifest);
  for (std::string line; std::getline(manifest_lines, line);) {
    if (line.rfind("  command:", 0) != 0) {
      EXPECT_EQ(line.find(dir.string()), std::string::npos) << line;
    }
  }

  // Ground truth: >= 1 kHz over the whole recording, read by the camera library.
  const auto gt = evpipe::camera::read_trajectory_csv((dir / "rec.gt.csv").string());
  ASSERT_EQ(gt.size(), 401U);
  EXPECT_EQ(gt.front().t_us, 0);
  EXPECT_EQ(gt.back().t_us, 400'000);
  for (std::size_t i = 1; i < gt.size(); ++i) {
    ASSERT_LE(gt[i].t_us - gt[i - 1].t_us, 1000) << i;
  }

  // Camera and model: what was given, through the evpipe YAML writers.
  EXPECT_EQ(evpipe::camera::load_camera((dir / "rec.camera.yaml").string()),
            evpipe::camera::load_camera(config("davis346.yaml")));
  const auto model = evpipe::camera::load_line_model((dir / "rec.model.yaml").string());
  const auto original = evpipe::camera::load_line_model(config("target-planar.yaml"));
  EXPECT_EQ(model.name, original.name);
  EXPECT_EQ(model.segments_m, original.segments_m);

  // Prior: the first ground-truth pose, 0.05 m and 10 degrees off, tolerances 0.3 m and 45 degrees.
  const auto prior = evpipe::camera::load_prior((dir / "rec.prior.yaml").string());
  EXPECT_NEAR(evpipe::camera::translation_distance_m(prior.pose, gt.front().pose), 0.05, 2e-6);
  EXPECT_NEAR(evpipe::camera::rotation_angle_deg(prior.pose, gt.front().pose), 10.0, 1e-4);
  EXPECT_EQ(prior.position_tolerance_m, 0.3);
  EXPECT_EQ(prior.angle_tolerance_deg, 45.0);
}

TEST(Evsim, TrajectoryInputReproducesTheGeneratedScene) {
  // Rendering from the ground truth of a generated scene, with the same seed, gives the same events: the
  // ground-truth file is exactly the motion that made them.
  const auto dir = evpipe::testing::temp_dir("e2e-sim3d-traj");
  const std::string a = (dir / "a.aedat4").string();
  const std::string b = (dir / "b.aedat4").string();
  ASSERT_EQ(run(kEvsim + k3dArgs + " --seed 7 --out " + q(a)).status, 0);
  const auto r =
      run(kEvsim + " --camera " + q(config("davis346.yaml")) + " --model " + q(config("target-planar.yaml")) +
          " --noise-hz 1 --hot-pixels 2 --seed 7 --trajectory " + q((dir / "a.gt.csv").string()) + " --out " + q(b));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_TRUE(slurp(dir / "b.gt.csv") == slurp(dir / "a.gt.csv"));
  EXPECT_TRUE(slurp(b) == slurp(a));
  EXPECT_EQ(slurp(dir / "b.prior.yaml"), slurp(dir / "a.prior.yaml"));

  // A sparse trajectory (10 Hz) is densified to 1 kHz, keeping its rows.
  const std::string sparse = (dir / "sparse.csv").string();
  std::ofstream(sparse) << "t_us,x_m,y_m,z_m,qw,qx,qy,qz\n"
                           "1000000,0,0,0.8,1,0,0,0\n"
                           "1100000,0.01,0,0.8,1,0,0,0\n"
                           "1200000,0.01,0.01,0.85,0.9998477,0.0174524,0,0\n";
  const std::string c = (dir / "c.aedat4").string();
  ASSERT_EQ(run(kEvsim + " --camera " + q(config("davis346.yaml")) + " --model " + q(config("target-planar.yaml")) +
                " --noise-hz 0 --trajectory " + q(sparse) + " --out " + q(c))
                .status,
            0);
  const auto gt = evpipe::camera::read_trajectory_csv((dir / "c.gt.csv").string());
  ASSERT_EQ(gt.size(), 201U);
  EXPECT_EQ(gt[100].t_us, 1'100'000);
  EXPECT_EQ(gt[100].pose.t_cam_model_m, Eigen::Vector3d(0.01, 0, 0.8));
  const auto events = evpipe::io::read_all(c).events;
  ASSERT_FALSE(events.empty());
  EXPECT_GE(events.front().t_us, 1'000'000);
  EXPECT_LT(events.back().t_us, 1'200'000);
}

TEST(Evsim, RoadheaderDxfAndPureNoise) {
  const auto dir = evpipe::testing::temp_dir("e2e-sim3d-dxf");
  const std::string rec = (dir / "rh.aedat4").string();
  auto r =
      run(kEvsim + " --camera " + q(config("davis346.yaml")) + " --model " + q(config("roadheader-wireframe.dxf")) +
          " --distance-m 1.0 --duration-ms 200 --noise-hz 0 --out " + q(rec));
  ASSERT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(evpipe::camera::load_line_model((dir / "rh.model.yaml").string()).segments_m,
            evpipe::camera::load_line_model(config("roadheader-wireframe.dxf")).segments_m);
  const auto manifest = slurp(dir / "rh.manifest.yaml");
  EXPECT_EQ(manifest_value(manifest, "target3d", "orientation_source"), "\"default: front-left three-quarter\"");
  EXPECT_EQ(manifest_value(manifest, "events", "noise"), "0");
  EXPECT_GT(evpipe::io::read_all(rec).events.size(), 5000U);

  const std::string noise = (dir / "noise.txt").string();
  r = run(kEvsim + " --pure-noise 3000 --seed 4 --out " + q(noise));
  ASSERT_EQ(r.status, 0) << r.err;
  const auto ev = evpipe::io::read_all(noise).events;
  ASSERT_EQ(ev.size(), 3000U);
  EXPECT_GE(ev.front().t_us, 0);
  EXPECT_LT(ev.back().t_us, 30'000);
}

TEST(Evsim, UsageErrorsExitTwo) {
  const auto dir = evpipe::testing::temp_dir("e2e-sim-usage");
  const std::string out = " --out " + q((dir / "x.aedat4").string());
  auto r = run(kEvsim + " --model " + q(config("target-planar.yaml")) + out);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--camera"), std::string::npos) << r.err;
  r = run(kEvsim + " --camera " + q(config("davis346.yaml")) + " --model " + q(config("target-planar.yaml")) +
          " --trajectory x.csv --distance-m 1" + out);
  EXPECT_EQ(r.status, 2);
  r = run(kEvsim + " --camera " + q(config("davis346.yaml")) + " --model " + q(config("target-planar.yaml")) +
          " --orientation 1,0,0" + out);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--orientation"), std::string::npos) << r.err;
  // The 2D speed factor is bounded: --speed 1e300 generated events for ever (hostile test, session 23).
  r = run(kEvsim + " --scene rotating-bar --duration-ms 10 --speed 1e300" + out);
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("--speed"), std::string::npos) << r.err;
  // A bad model file is an input error (1) naming the file.
  const std::string bad = (dir / "bad.yaml").string();
  std::ofstream(bad) << "model:\n  units: cm\n  lines: [[0, 0, 0, 1, 0, 0]]\n";
  r = run(kEvsim + " --camera " + q(config("davis346.yaml")) + " --model " + q(bad) + out);
  EXPECT_EQ(r.status, 1);
  EXPECT_NE(r.err.find("model.units"), std::string::npos) << r.err;
}

TEST(Evsim, DistractorsAddEventsAndKeepTheTargetsStopsHoldTheTruth) {
  // Distractors draw from their own random streams: the target's events and ground truth are the same with and
  // without them, and the distractor events come on top, labelled signal.
  const auto dir = evpipe::testing::temp_dir("e2e-sim-clutter");
  const auto lines_of = [](const fs::path& p) {
    std::multiset<std::string> out;
    std::ifstream f(p);
    for (std::string ln; std::getline(f, ln);)
      if (!ln.empty() && ln[0] != '#') out.insert(ln);
    return out;
  };
  const std::string plain = (dir / "plain.txt").string();
  const std::string clutter = (dir / "clutter.txt").string();
  ASSERT_EQ(run(kEvsim + k3dArgs + " --seed 3 --out " + q(plain)).status, 0);
  auto r = run(kEvsim + k3dArgs + " --seed 3 --distractor decoy,flicker --distractor moving-lines --out " + q(clutter));
  ASSERT_EQ(r.status, 0) << r.err;
  const auto a = lines_of(plain);
  const auto b = lines_of(clutter);
  EXPECT_GT(b.size(), a.size() + 1000);
  EXPECT_TRUE(std::includes(b.begin(), b.end(), a.begin(), a.end()));
  EXPECT_TRUE(slurp(dir / "plain.gt.csv") == slurp(dir / "clutter.gt.csv"));
  const std::string manifest = slurp(dir / "clutter.manifest.yaml");
  EXPECT_NE(manifest.find("distractors:"), std::string::npos);
  EXPECT_NE(manifest.find("  flicker: "), std::string::npos);

  // A stop: the truth rows inside it are all the same pose.
  const std::string stop = (dir / "stop.txt").string();
  r = run(kEvsim + k3dArgs + " --seed 3 --stop 0.1:0.2 --out " + q(stop));
  ASSERT_EQ(r.status, 0) << r.err;
  const auto gt = evpipe::camera::read_trajectory_csv((dir / "stop.gt.csv").string());
  std::size_t still = 0;
  for (const auto& p : gt) {
    if (p.t_us < 100'000 || p.t_us > 300'000) continue;
    EXPECT_LT((p.pose.t_cam_model_m - gt[100].pose.t_cam_model_m).norm(), 2e-6);
    ++still;
  }
  EXPECT_GE(still, 200u);
  // Usage errors: overlapping stops, an unknown distractor, a stop with --trajectory.
  EXPECT_EQ(run(kEvsim + k3dArgs + " --stop 0.1:0.1,0.25:0.1 --out " + q(stop)).status, 2);
  r = run(kEvsim + k3dArgs + " --distractor tree --out " + q(stop));
  EXPECT_EQ(r.status, 2);
  EXPECT_NE(r.err.find("moving-lines"), std::string::npos) << r.err;
  EXPECT_EQ(run(kEvsim + " --scene demo --stop 1:1 --out " + q(stop)).status, 2);
}

TEST(Evpipe, SigintEndsAPacedReplayPromptly) {
  // A 30 s silence in a real-time replay: SIGINT after 1 s must end the sleep at once, print the summary
  // of what was read, and exit 0.
  const auto dir = evpipe::testing::temp_dir("e2e-sigint");
  const auto path = (dir / "gap.txt").string();
  std::ofstream(path) << "# width=346 height=260\n0 1 1 1\n30000000 2 2 0\n";
  const auto t0 = std::chrono::steady_clock::now();
  const auto r = run("timeout --preserve-status -s INT 1 " + kEvpipe + " --replay " + q(path) + " --json");
  const auto wall = std::chrono::steady_clock::now() - t0;
  EXPECT_EQ(r.status, 0) << r.err;
  EXPECT_EQ(json_field(r.out, "interrupted"), "true");
  EXPECT_EQ(json_field(r.out, "events"), "1");
  EXPECT_LT(wall, std::chrono::seconds(10));
}
