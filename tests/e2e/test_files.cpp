// Issue 17: how every program opens its inputs and outputs (evpipe/core/file.hpp), end to end on the real binaries.
// Row 4/5: an output that is one of the inputs is refused before anything is truncated; row 7: the run configuration
// is read with a size cap; row 8: an LCM log on a full disk fails the run; row 9: a FIFO without a writer as any
// input fails at once instead of blocking; row 10: LCM URLs are checked at start; row 11: a cut AEDAT header.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "evpipe_run.hpp"
#include "evpipe_test_data.hpp"

namespace fs = std::filesystem;
using ::testing::HasSubstr;

namespace {

using evpipe::testing::q;
using Result = evpipe::testing::Run;
using evpipe::testing::slurp;

const std::string kEvpipe = EVPIPE_EXE;
const std::string kEvconvert = EVCONVERT_EXE;
const std::string kEvdenoise = EVDENOISE_EXE;
const std::string kEvsim = EVSIM_EXE;
const std::string kEvposeEval = EVPOSE_EVAL_EXE;

class Files : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = evpipe::testing::temp_dir(std::string("files-") +
                                     ::testing::UnitTest::GetInstance()->current_test_info()->name());
    for (const char* ext : {".aedat4", ".camera.yaml", ".model.yaml", ".prior.yaml", ".gt.csv"}) {
      fs::copy_file(source(ext), path(std::string("rh") + ext), fs::copy_options::overwrite_existing);
    }
    std::ofstream(path("evpipe.yaml")) << "log:\n  level: info\n";
  }
  void TearDown() override { fs::remove_all(dir_); }
  static std::string source(const std::string& ext) {
    return (evpipe::testing::source_dir() / ("tests/data/roadheader-sample" + ext)).string();
  }
  [[nodiscard]] std::string path(const std::string& name) const { return (dir_ / name).string(); }
  Result run(const std::string& cmd) const { return evpipe::testing::run("timeout 20 " + cmd, dir_); }
  // evpipe with every input it takes (copies in the test's folder) and `extra` options.
  Result evpipe(const std::string& extra) const {
    return run(kEvpipe + " --replay " + q(path("rh.aedat4")) + " --camera " + q(path("rh.camera.yaml")) + " --model " +
               q(path("rh.model.yaml")) + " --prior " + q(path("rh.prior.yaml")) + " --ground-truth " +
               q(path("rh.gt.csv")) + " --config " + q(path("evpipe.yaml")) + " --speed max --no-progress " + extra);
  }
  fs::path dir_;
};

}  // namespace

// Row 4: `evconvert IN IN`, or OUT a hard or symbolic link of IN, destroyed IN (AEDAT 4.0: exit 0).
TEST_F(Files, EvconvertEvdenoiseRefuseToOverwriteTheirInput) {
  const std::string in = path("rh.aedat4");
  fs::create_hard_link(in, path("hard.aedat4"));
  fs::create_symlink(in, path("soft.aedat4"));
  for (const std::string& out : {in, path("hard.aedat4"), path("soft.aedat4")}) {
    SCOPED_TRACE(out);
    const auto c = run(kEvconvert + " " + q(in) + " " + q(out));
    EXPECT_EQ(c.status, 1);
    EXPECT_THAT(c.err, HasSubstr("refusing to overwrite it")) << c.err;
    const auto d = run(kEvdenoise + " " + q(in) + " " + q(out) + " --filter baf");
    EXPECT_NE(d.status, 0);
    EXPECT_THAT(d.err, HasSubstr("OUT is the input file")) << d.err;  // evdenoise's own check, before the helper's
    EXPECT_EQ(slurp(in), slurp(source(".aedat4")));
  }
}

TEST_F(Files, EvsimAndEvposeEvalRefuseToOverwriteTheirInputs) {
  // evsim writes <stem>.camera.yaml beside --out: here that is its own --camera.
  fs::copy_file(source(".camera.yaml"), path("sim.camera.yaml"));
  const auto s = run(kEvsim + " --camera " + q(path("sim.camera.yaml")) + " --model " + q(path("rh.model.yaml")) +
                     " --duration-ms 100 --out " + q(path("sim.txt")));
  EXPECT_NE(s.status, 0);
  EXPECT_THAT(s.err, HasSubstr("sim.camera.yaml: is also an input of this program")) << s.err;
  EXPECT_EQ(slurp(path("sim.camera.yaml")), slurp(source(".camera.yaml")));
  // --labels naming --out (written just before) is refused too.
  const auto l = run(kEvsim + " --scene demo --duration-ms 100 --out " + q(path("d.txt")) + " --labels " +
                     q(path("d.txt")) + " --no-manifest");
  EXPECT_NE(l.status, 0);
  EXPECT_THAT(l.err, HasSubstr("d.txt: is also an input of this program")) << l.err;
  const auto e =
      run(kEvposeEval + " " + q(path("rh.gt.csv")) + " " + q(path("rh.gt.csv")) + " --png " + q(path("rh.gt.csv")));
  EXPECT_NE(e.status, 0);
  EXPECT_THAT(e.err, HasSubstr("refusing to overwrite it")) << e.err;
  EXPECT_EQ(slurp(path("rh.gt.csv")), slurp(source(".gt.csv")));
  // --errors-out naming the estimate (read before it is written) is refused too, the estimate kept.
  fs::copy_file(source(".gt.csv"), path("est.csv"));
  const auto eo =
      run(kEvposeEval + " " + q(path("est.csv")) + " " + q(path("rh.gt.csv")) + " --errors-out " + q(path("est.csv")));
  EXPECT_NE(eo.status, 0);
  EXPECT_THAT(eo.err, HasSubstr("est.csv: is also an input of this program")) << eo.err;
  EXPECT_EQ(slurp(path("est.csv")), slurp(source(".gt.csv")));
  // --png naming --errors-out (written just before) likewise.
  const auto ep = run(kEvposeEval + " " + q(path("est.csv")) + " " + q(path("rh.gt.csv")) + " --errors-out " +
                      q(path("err.csv")) + " --png " + q(path("err.csv")));
  EXPECT_NE(ep.status, 0);
  EXPECT_THAT(ep.err, HasSubstr("err.csv: is also an input of this program")) << ep.err;
  EXPECT_THAT(slurp(path("err.csv")), ::testing::StartsWith("t_us,status,")) << ep.err;
}

// Row 5: --poses-out (or an LCM log) naming one of evpipe's own inputs truncated it before it was read.
TEST_F(Files, EvpipeOutputsNamingAnInputAreRefusedBeforeTruncating) {
  for (const std::string name :
       {"rh.aedat4", "rh.camera.yaml", "rh.model.yaml", "rh.prior.yaml", "rh.gt.csv", "evpipe.yaml"}) {
    SCOPED_TRACE(name);
    const std::string before = slurp(path(name));
    const auto r = evpipe("--no-lcm --poses-out " + q(path(name)));
    EXPECT_EQ(r.status, 2);
    EXPECT_THAT(r.err, HasSubstr(path(name) + ": is also an input of this program: refusing to overwrite it")) << r.err;
    EXPECT_EQ(slurp(path(name)), before);
    const auto l = evpipe("--lcm-url " + q("file://" + path(name) + "?mode=w"));
    EXPECT_EQ(l.status, 2);
    EXPECT_THAT(l.err, HasSubstr("refusing to overwrite it")) << l.err;
    EXPECT_EQ(slurp(path(name)), before);
  }
  fs::create_hard_link(path("rh.gt.csv"), path("link.csv"));
  const auto h = evpipe("--no-lcm --poses-out " + q(path("link.csv")));
  EXPECT_EQ(h.status, 2);
  EXPECT_THAT(h.err, HasSubstr("is the same file as the input " + path("rh.gt.csv"))) << h.err;
  // The LCM log is not the poses CSV either.
  const auto both =
      evpipe("--poses-out " + q(path("p.csv")) + " --lcm-url " + q("file://" + path("p.csv") + "?mode=w"));
  EXPECT_EQ(both.status, 2);
  EXPECT_THAT(both.err, HasSubstr("refusing to overwrite it")) << both.err;
  // Nor is --video one of the outputs, even when it did not exist before the run (the LCM log's name).
  const auto video_csv = evpipe("--no-lcm --poses-out " + q(path("csv.mp4")) + " --video " + q(path("csv.mp4")));
  EXPECT_EQ(video_csv.status, 2);
  EXPECT_THAT(video_csv.err, HasSubstr("--video: " + path("csv.mp4"))) << video_csv.err;
  EXPECT_THAT(slurp(path("csv.mp4")), ::testing::StartsWith("t_us,")) << "the poses CSV's header is kept";
  const auto video_log =
      evpipe("--lcm-url " + q("file://" + path("log.mp4") + "?mode=w") + " --video " + q(path("log.mp4")));
  EXPECT_EQ(video_log.status, 2);
  EXPECT_THAT(video_log.err, HasSubstr("--video: " + path("log.mp4"))) << video_log.err;
}

// Hostile test (session 23): --png-every stills are named evpipe-NNNNNN.png in --png-dir; an input or an output of
// that name there (or a link of one) was overwritten by a still, exit 0.
TEST_F(Files, StillsNeverOverwriteAnInputOrAnOutput) {
  fs::create_directories(path("stills"));
  fs::create_hard_link(path("rh.camera.yaml"), path("stills/evpipe-000003.png"));
  const std::string before = slurp(path("rh.camera.yaml"));
  const auto r = evpipe("--no-lcm --png-every 1 --png-dir " + q(path("stills")));
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("--png-dir: " + path("stills/evpipe-000003.png") + " is ")) << r.err;
  EXPECT_EQ(slurp(path("rh.camera.yaml")), before);
  fs::remove(path("stills/evpipe-000003.png"));
  const auto csv = evpipe("--no-lcm --poses-out " + q(path("stills/evpipe-000002.png")) + " --png-every 1 --png-dir " +
                          q(path("stills")));
  EXPECT_EQ(csv.status, 2);
  EXPECT_THAT(slurp(path("stills/evpipe-000002.png")), ::testing::StartsWith("t_us,")) << csv.err;
  const auto ok = evpipe("--no-lcm --png-every 10 --png-dir " + q(path("stills")));
  EXPECT_EQ(ok.status, 0) << ok.err;
  EXPECT_TRUE(fs::exists(path("stills/evpipe-000000.png")));
}

// Hostile test (session 23): a ground truth with a header and no row was accepted silently (no ATE, exit 0).
TEST_F(Files, AGroundTruthWithoutRowsIsAConfigurationError) {
  std::ofstream(path("empty.gt.csv")) << "t_us,x_m,y_m,z_m,qw,qx,qy,qz\n";
  const auto r = run(kEvpipe + " --no-lcm --replay " + q(path("rh.aedat4")) + " --camera " + q(path("rh.camera.yaml")) +
                     " --model " + q(path("rh.model.yaml")) + " --ground-truth " + q(path("empty.gt.csv")) +
                     " --speed max --no-progress");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("empty.gt.csv: no trajectory row")) << r.err;
}

// Row 9: a FIFO without a writer as an input blocked open() for ever.
TEST_F(Files, AFifoAsAnyInputFailsAtOnce) {
  const std::string fifo = path("fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string rh = path("rh");
  const std::vector<std::string> commands = {
      kEvpipe + " --no-lcm --replay " + q(fifo),
      kEvpipe + " --no-lcm --replay " + q(rh + ".aedat4") + " --config " + q(fifo),
      kEvpipe + " --no-lcm --replay " + q(rh + ".aedat4") + " --camera " + q(fifo) + " --model " +
          q(rh + ".model.yaml"),
      kEvpipe + " --no-lcm --replay " + q(rh + ".aedat4") + " --camera " + q(rh + ".camera.yaml") + " --model " +
          q(fifo),
      kEvpipe + " --no-lcm --replay " + q(rh + ".aedat4") + " --camera " + q(rh + ".camera.yaml") + " --model " +
          q(rh + ".model.yaml") + " --prior " + q(fifo),
      kEvpipe + " --no-lcm --replay " + q(rh + ".aedat4") + " --camera " + q(rh + ".camera.yaml") + " --model " +
          q(rh + ".model.yaml") + " --ground-truth " + q(fifo),
      kEvconvert + " " + q(fifo) + " " + q(path("o.txt")),
      kEvdenoise + " " + q(fifo) + " " + q(path("o.aedat4")) + " --filter baf",
      kEvposeEval + " " + q(fifo) + " " + q(rh + ".gt.csv"),
      kEvsim + " --camera " + q(fifo) + " --model " + q(rh + ".model.yaml") + " --out " + q(path("s.aedat4")),
  };
  for (const auto& cmd : commands) {
    SCOPED_TRACE(cmd);
    const auto r = run(cmd);
    EXPECT_NE(r.status, 124) << "blocked on the FIFO";
    EXPECT_NE(r.status, 0);
    EXPECT_THAT(r.err, HasSubstr(fifo + ": is a FIFO, not a regular file")) << r.err;
  }
}

// Row 7: --config had no size limit (/dev/urandom grew to 4 GB).
TEST_F(Files, ConfigIsReadWithASizeCapAndMustBeARegularFile) {
  {
    std::ofstream big(path("big.yaml"));
    const std::string comment = "# " + std::string(1000, 'x') + "\n";
    for (int i = 0; i < 1100; ++i) big << comment;
  }
  const auto b = run(kEvpipe + " --no-lcm --replay " + q(path("rh.aedat4")) + " --config " + q(path("big.yaml")));
  EXPECT_EQ(b.status, 2);
  EXPECT_THAT(b.err, HasSubstr("more than the 1048576 accepted for a run configuration")) << b.err;
  const auto u = run(kEvpipe + " --no-lcm --replay " + q(path("rh.aedat4")) + " --config /dev/urandom");
  EXPECT_EQ(u.status, 2);
  EXPECT_THAT(u.err, HasSubstr("/dev/urandom: is a character device, not a regular file")) << u.err;
}

// Row 8: an LCM file:// log on a full disk: exit 0, "written", 0 bytes, no warning.
TEST_F(Files, LcmLogOnAFullDiskIsReported) {
  const auto r = evpipe("--json --lcm-url 'file:///dev/full?mode=w'");
  EXPECT_EQ(r.status, 1) << r.err;
  EXPECT_NE(evpipe::testing::json_field(r.out, "lcm_failures"), "0") << r.out;
  EXPECT_EQ(evpipe::testing::json_field(r.out, "lcm_poses"), "0") << r.out;
  EXPECT_THAT(r.err, HasSubstr("No space left on device")) << r.err;
  EXPECT_THAT(r.err, HasSubstr("nothing could be written")) << r.err;
  // A log that works: every message written and readable.
  const auto ok = evpipe("--json --lcm-url " + q("file://" + path("run.lcmlog") + "?mode=w"));
  EXPECT_EQ(ok.status, 0) << ok.err;
  EXPECT_EQ(evpipe::testing::json_field(ok.out, "lcm_failures"), "0");
  EXPECT_GT(fs::file_size(path("run.lcmlog")), 1000U);
}

// Row 10: ?ttl=300 sent with TTL 44, ?ttl=-1 with 255, garbage URLs retried for ever.
TEST_F(Files, LcmUrlIsCheckedAtStart) {
  for (const auto& [url, reason] : std::vector<std::pair<std::string, std::string>>{
           {"udpm://239.255.76.67:7667?ttl=300", "ttl '300' is not an integer 0-255"},
           {"udpm://239.255.76.67:7667?ttl=-1", "ttl '-1' is not an integer 0-255"},
           {"garbage", "'garbage' is not an LCM URL"},
           {"udpm://999.1.1.1:7667", "is not an IPv4 address"},
           {"file:///tmp/x.lcmlog", "needs mode=w"}}) {
    SCOPED_TRACE(url);
    const auto r = run(kEvpipe + " --replay " + q(path("rh.aedat4")) + " --speed max --lcm-url " + q(url));
    EXPECT_EQ(r.status, 2);
    EXPECT_THAT(r.err, HasSubstr("configuration error: lcm.url (--lcm-url): ")) << r.err;
    EXPECT_THAT(r.err, HasSubstr(reason)) << r.err;
  }
}

// Row 11: a 5-byte '#!AER' file was read as an empty text recording (exit 0, 0 events).
TEST_F(Files, CutAedatHeaderIsAnErrorNamingTheFile) {
  std::ofstream(path("cut.aedat4")) << "#!AER";
  const auto r = run(kEvpipe + " --no-lcm --speed max --replay " + q(path("cut.aedat4")));
  EXPECT_EQ(r.status, 1);
  EXPECT_THAT(r.err, HasSubstr(path("cut.aedat4") + ": byte 0: unrecognised content: the AEDAT version line is cut"))
      << r.err;
  const auto c = run(kEvconvert + " " + q(path("cut.aedat4")) + " " + q(path("o.txt")));
  EXPECT_EQ(c.status, 1);
  EXPECT_THAT(c.err, HasSubstr("cut after 5 byte(s)")) << c.err;
}

// preview_t on the pose (or statistics) channel would reach the controller's pose subscription as another type.
TEST_F(Files, PreviewChannelMayNotBeThePoseChannel) {
  std::ofstream(path("evpipe.yaml")) << "lcm:\n  preview: true\n  preview_channel: EVPIPE_POSE\n";
  const auto r = evpipe("--no-lcm");
  EXPECT_EQ(r.status, 2);
  EXPECT_THAT(r.err, HasSubstr("lcm.preview_channel: 'EVPIPE_POSE' is also the pose or statistics channel")) << r.err;
}
