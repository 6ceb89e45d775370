// End-to-end: the real evpipe / evconvert / evsim binaries on recorded files.
#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sys/wait.h>

#include "evpipe/io/reader.hpp"
#include "evpipe_test_data.hpp"

namespace fs = std::filesystem;

namespace {

struct Run {
  int status = -1;
  std::string out;
  std::string err;
};

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

Run run(const std::string& cmd) {
  static int counter = 0;
  const auto dir = evpipe::testing::temp_dir("e2e");
  const auto out = dir / ("out" + std::to_string(counter) + ".txt");
  const auto err = dir / ("err" + std::to_string(counter++) + ".txt");
  const std::string full = cmd + " >" + out.string() + " 2>" + err.string() + " </dev/null";
  const int rc = std::system(full.c_str());
  Run r;
  r.status = WIFEXITED(rc) ? WEXITSTATUS(rc) : 128 + WTERMSIG(rc);
  r.out = slurp(out);
  r.err = slurp(err);
  return r;
}

std::string q(const std::string& s) { return "'" + s + "'"; }

// Minimal extraction of a number/bool/string field from evpipe's flat --json summary.
std::string field(const std::string& json, const std::string& key) {
  const std::regex re("\"" + key + "\":(\"[^\"]*\"|[^,}]*)");
  std::smatch m;
  if (!std::regex_search(json, m, re)) return "<missing " + key + ">";
  std::string v = m[1];
  if (!v.empty() && v.front() == '"') v = v.substr(1, v.size() - 2);
  return v;
}

const std::string kEvpipe = EVPIPE_EXE;
const std::string kEvconvert = EVCONVERT_EXE;
const std::string kSample = (evpipe::testing::source_dir() / "tests/data/demo-sample.aedat4").string();

}  // namespace

TEST(Evpipe, ReplaysTheBundledSample) {
  const auto r = run(kEvpipe + " --replay " + q(kSample) + " --speed max --json");
  ASSERT_EQ(r.status, 0) << r.err;
  const auto expected = evpipe::io::read_all(kSample);
  EXPECT_EQ(field(r.out, "events"), std::to_string(expected.events.size()));
  EXPECT_EQ(field(r.out, "format"), "aedat4");
  EXPECT_EQ(field(r.out, "width"), "346");
  EXPECT_EQ(field(r.out, "height"), "260");
  EXPECT_EQ(field(r.out, "first_t_us"), std::to_string(expected.events.front().t_us));
  EXPECT_EQ(field(r.out, "last_t_us"), std::to_string(expected.events.back().t_us));
  EXPECT_EQ(field(r.out, "out_of_order"), "0");
  EXPECT_EQ(field(r.out, "error"), "");
  // 30 ms fixed windows over a 1.5 s recording: every window holds events, each event in exactly one.
  EXPECT_EQ(field(r.out, "window_events"), std::to_string(expected.events.size()));
  EXPECT_EQ(field(r.out, "windows"), "50");
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
  EXPECT_GE(std::stod(field(r.out, "wall_s")), 0.37);
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
    EXPECT_EQ(field(r.out, "events"), c.events) << c.rel;
    EXPECT_EQ(field(r.out, "first_t_us"), c.first) << c.rel;
    EXPECT_EQ(field(r.out, "last_t_us"), c.last) << c.rel;
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
  const auto events = std::stoull(field(r.out, "events"));
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
