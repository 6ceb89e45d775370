// The run configuration's validation through the real binaries (issue 17): rows 1, 2, 3, 12 and 13 of the table
// each gave a crash, a hang or a silent wrong run; each must now end with exit 2 and a message naming the input.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "evpipe_run.hpp"
#include "evpipe_test_data.hpp"

namespace {

using evpipe::testing::q;

const std::string kEvpipe = EVPIPE_EXE;
const std::string kEvsim = EVSIM_EXE;
const std::string kSample = (evpipe::testing::source_dir() / "tests/data/demo-sample.aedat4").string();

evpipe::testing::Run run(const std::string& cmd) {
  static const auto dir = evpipe::testing::temp_dir("config-cli");
  // `timeout`: a regression to a hang must fail the test, not stall it (row 2 span for ever).
  return evpipe::testing::run("timeout -s KILL 60 " + cmd, dir);
}

std::string write(const std::string& name, const std::string& text) {
  static const auto dir = evpipe::testing::temp_dir("config-cli-files");
  const auto path = (dir / name).string();
  std::ofstream(path, std::ios::binary) << text;
  return path;
}

}  // namespace

// Row 1: a sequence or map as a key threw YAML::TypedBadConversion out of main: abort, exit 134.
TEST(ConfigCli, KeyThatIsASequenceOrMapExitsTwoNamingFileLineAndKey) {
  for (const auto& [name, yaml, where] :
       {std::tuple{"top.yaml", "? [a, b]\n: 1\n", ": line 1: <top level>: a key must be a plain name"},
        std::tuple{"section.yaml", "log: {level: info}\nwindow:\n  ? [a, b]\n  : 1\n", ": line 3: window: a key must"},
        std::tuple{"params.yaml", "denoise:\n  params:\n    ? {a: 1}\n    : 2\n", ": line 3: denoise.params: a key"},
        std::tuple{"value.yaml", "window:\n  length_us: [1, 2]\n",
                   ": line 2: window.length_us: expected an integer, "
                   "got a sequence"}}) {
    SCOPED_TRACE(name);
    const auto path = write(name, yaml);
    const auto r = run(kEvpipe + " --replay " + q(kSample) + " --speed max --no-lcm --config " + q(path));
    EXPECT_EQ(r.status, 2) << r.err;
    EXPECT_NE(r.err.find(path + where), std::string::npos) << r.err;
  }
}

// Row 2: window.length_us: INT64_MAX passed; t0 + w overflowed and the denoise thread spun at 100 % for ever.
TEST(ConfigCli, HugeWindowIsRefused) {
  const auto path = write("window.yaml", "window:\n  length_us: 9223372036854775807\n  hop_us: 1\n");
  const auto r = run(kEvpipe + " --replay " + q(kSample) + " --speed max --no-lcm --config " + q(path));
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find(": line 2: window.length_us: must be in [1000, 1000000]"), std::string::npos) << r.err;
}

// Row 12: --speed 1e-300 turned pacing off silently.
TEST(ConfigCli, SpeedOutOfRangeIsRefused) {
  for (const char* speed : {"1e-300", "0", "1e9", "nan"}) {
    const auto r = run(kEvpipe + " --replay " + q(kSample) + " --no-lcm --speed " + speed);
    EXPECT_EQ(r.status, 2) << speed << ": " << r.err;
    EXPECT_NE(r.err.find("--speed: speed must be 'max' or a number in [0.01, 1000]"), std::string::npos) << r.err;
  }
}

// Row 3: a declared 65536 x 65536 sensor made the filters abort on bad_alloc.
TEST(ConfigCli, SensorBeyondTheLargestIsAnErrorNotACrash) {
  const auto rec = write("huge.txt", "# width=65536 height=65536\n1 1 1 1\n2 2 2 0\n");
  for (const char* filter : {"curvature", "baf", "ynoise", "stcf"}) {
    const auto r = run(kEvpipe + " --replay " + q(rec) + " --speed max --no-lcm --no-progress --denoise " + filter);
    EXPECT_EQ(r.status, 1) << filter << ": " << r.err;
    EXPECT_NE(r.err.find("0 < N <= 2048"), std::string::npos) << r.err;
  }
  const auto cfg = write("default-size.yaml", "source: {default_width: 32768}\n");
  const auto r = run(kEvpipe + " --replay " + q(rec) + " --no-lcm --config " + q(cfg));
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("source.default_width: must be in [1, 2048]"), std::string::npos) << r.err;
}

// Row 13: evsim --noise-hz nan gave no noise and --t0-us near INT64_MAX wrote 0 events, both exit 0.
TEST(ConfigCli, EvsimRefusesNonFiniteNumbersAndOverflowingTimes) {
  const auto out = write("sim.txt", "");
  for (const std::string args : {"--noise-hz nan", "--noise-hz inf", "--duration-ms nan", "--speed nan",
                                 "--t0-us 9223372036854775000", "--t0-us -9223372036854775000"}) {
    const auto r = run(kEvsim + " --scene demo --duration-ms 100 --out " + q(out) + " " + args);
    EXPECT_EQ(r.status, 2) << args << ": " << r.err;
    EXPECT_NE(r.err.find(args.substr(0, args.find(' '))), std::string::npos) << r.err;
  }
  const auto ok = run(kEvsim + " --scene demo --duration-ms 100 --noise-hz 1 --t0-us 1000000 --out " + q(out));
  EXPECT_EQ(ok.status, 0) << ok.err;
}

// Also seen: a 640x480 calibration on a 346x260 recording was accepted silently (wrong poses).
TEST(ConfigCli, CalibrationOfAnotherSensorSizeIsRefused) {
  const auto cam = write("cam640.yaml",
                         "camera:\n  width: 640\n  height: 480\n  fx: 500\n  fy: 500\n  cx: 320\n"
                         "  cy: 240\n  distortion: [0, 0, 0, 0, 0]\n");
  const auto model = (evpipe::testing::source_dir() / "config/roadheader-wireframe.yaml").string();
  const auto r = run(kEvpipe + " --replay " + q(kSample) + " --speed max --no-lcm --no-progress --camera " + q(cam) +
                     " --model " + q(model));
  EXPECT_EQ(r.status, 2) << r.err;
  EXPECT_NE(r.err.find("pose.camera: " + cam + ": the calibration is for a 640x480 sensor, the recording is 346x260"),
            std::string::npos)
      << r.err;
}
