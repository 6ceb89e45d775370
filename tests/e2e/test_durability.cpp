// Issue 17 row 6: what a kill, a hang-up or a closed stdout may lose of evpipe's poses CSV. The real binary replays
// the bundled roadheader sample in real time (--speed 1) with the pose stage and --poses-out.
#include <gtest/gtest.h>

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "evpipe/camera/trajectory.hpp"
#include "evpipe/transport/lcm_capture.hpp"
#include "evpipe_run.hpp"
#include "evpipe_test_data.hpp"
#include "lcm_net.hpp"

extern char** environ;

namespace {

using evpipe::testing::q;
using evpipe::testing::slurp;
using Clock = std::chrono::steady_clock;

const std::string kEvpipe = EVPIPE_EXE;

std::string stem() {
  return (evpipe::testing::source_dir() / "tests/data/roadheader-sample").string();
}

std::string pose_args(const std::string& csv) {
  const std::string s = stem();
  return " --replay " + q(s + ".aedat4") + " --camera " + q(s + ".camera.yaml") + " --model " + q(s + ".model.yaml") +
         " --prior " + q(s + ".prior.yaml") + " --poses-out " + q(csv) + " --no-progress";
}

pid_t spawn_shell(const std::string& cmd) {
  std::vector<std::string> args = {"/bin/sh", "-c", "exec " + cmd};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = -1;
  if (posix_spawn(&pid, "/bin/sh", nullptr, nullptr, argv.data(), environ) != 0) return -1;
  return pid;
}

int wait_status(pid_t pid) {
  int st = 0;
  if (waitpid(pid, &st, 0) != pid) return -1;
  return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

// Every line of the CSV is whole: the file ends with a newline and every row parses (read_trajectory_csv checks
// every cell); the extra columns are there too.
std::vector<evpipe::camera::StampedPose> whole_rows(const std::string& csv) {
  const std::string text = slurp(csv);
  EXPECT_FALSE(text.empty());
  if (!text.empty()) {
    EXPECT_EQ(text.back(), '\n') << "the CSV ends inside a row";
  }
  std::vector<evpipe::camera::StampedPose> rows;
  EXPECT_NO_THROW(rows = evpipe::camera::read_trajectory_csv(csv));
  const auto status = evpipe::camera::read_trajectory_column(csv, "sigma_px");
  EXPECT_TRUE(status.has_value());
  if (status) {
    EXPECT_EQ(status->size(), rows.size());
  }
  return rows;
}

}  // namespace

// SIGKILL mid-run: every valid pose published at least 1 s before the kill is in the CSV, every row whole. The
// published poses are seen on LCM (udpm on loopback in a private network namespace). The kill comes 1.5 s after the
// 10th valid pose (quarter real time: the 3 s recording lasts 12 s, whatever the first initialisation takes on a
// busy machine). Without multicast: the CSV must hold 10 rows while evpipe runs, and still hold them after the kill.
TEST(EvpipeDurability, SigkillLosesNoRowPublishedMoreThanASecondBefore) {
  const auto net = evpipe::testing::ensure_multicast_route();
  const std::string url = "udpm://239.255.76.67:" + std::to_string(20000 + ::getpid() % 20000) + "?ttl=0";
  std::unique_ptr<evpipe::transport::LcmCapture> capture;
  if (net.ok) {
    capture = std::make_unique<evpipe::transport::LcmCapture>(url);
    if (capture->good()) {
      capture->subscribe("EVPIPE_POSE");
    } else {
      capture.reset();
    }
  }
  const auto dir = evpipe::testing::temp_dir("durability-kill");
  const std::string csv = (dir / "poses.csv").string();
  const std::string err = (dir / "stderr.txt").string();
  const std::string lcm = capture ? " --lcm-url " + q(url) : std::string(" --no-lcm");
  const auto t_spawn = Clock::now();
  const pid_t pid = spawn_shell(kEvpipe + pose_args(csv) + " --speed 0.25" + lcm + " >/dev/null 2>" + q(err));
  ASSERT_GT(pid, 0);

  constexpr std::size_t kPoses = 10;
  std::map<std::int64_t, Clock::time_point> received;  // valid pose t_us -> when it arrived here
  Clock::time_point t_enough{};
  std::size_t rows_seen = 0;
  while (Clock::now() - t_spawn < std::chrono::seconds(30)) {
    if (capture) {
      capture->drain(std::chrono::milliseconds(10));
      for (const auto& p : capture->poses()) {
        if (p.pose_valid && !received.count(p.t_us)) received[p.t_us] = Clock::now();
      }
      if (t_enough == Clock::time_point{} && received.size() >= kPoses) t_enough = Clock::now();
    } else {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      const std::string text = slurp(csv);
      rows_seen = static_cast<std::size_t>(std::count(text.begin(), text.end(), '\n'));
      if (t_enough == Clock::time_point{} && rows_seen > kPoses) t_enough = Clock::now();
    }
    if (t_enough != Clock::time_point{} && Clock::now() - t_enough >= std::chrono::milliseconds(1500)) break;
  }
  const auto t_kill = Clock::now();
  ASSERT_EQ(::kill(pid, SIGKILL), 0);
  EXPECT_EQ(wait_status(pid), 128 + SIGKILL) << "evpipe ended before the kill: " << slurp(err);
  ASSERT_NE(t_enough, Clock::time_point{})
      << (capture ? "fewer than 10 valid poses published in 30 s"
                  : "fewer than 10 rows in the CSV while evpipe ran (not flushed?)")
      << slurp(err);

  const auto rows = whole_rows(csv);
  std::set<std::int64_t> in_csv;
  for (const auto& r : rows) in_csv.insert(r.t_us);
  if (capture) {
    std::size_t checked = 0;
    for (const auto& [t_us, at] : received) {
      if (at > t_kill - std::chrono::seconds(1)) continue;
      ++checked;
      EXPECT_TRUE(in_csv.count(t_us)) << "pose at t_us " << t_us << " published "
                                      << std::chrono::duration<double>(t_kill - at).count()
                                      << " s before the kill is not in the CSV";
    }
    std::cout << rows.size() << " rows in the CSV after SIGKILL; " << checked
              << " valid poses published >= 1 s before the kill, all checked (" << net.message << ")\n";
    EXPECT_GE(checked, kPoses);
  } else {
    EXPECT_GE(rows.size(), kPoses);
    std::cout << rows.size() << " rows in the CSV after SIGKILL (no multicast: " << net.message << ")\n";
  }
}

// SIGUSR1 logs the status line and the run goes on; SIGHUP (a closed terminal) stops like SIGTERM: drained,
// summary, exit 0, every row whole.
TEST(EvpipeDurability, Sigusr1LogsTheStatusAndSighupStopsCleanly) {
  const auto dir = evpipe::testing::temp_dir("durability-hup");
  const std::string csv = (dir / "poses.csv").string();
  const std::string out = (dir / "stdout.txt").string();
  const std::string err = (dir / "stderr.txt").string();
  // Quarter real time (12 s): the signals come while it runs even when the first pose is late on a busy machine.
  const pid_t pid = spawn_shell(kEvpipe + pose_args(csv) + " --speed 0.25 --no-lcm --json >" + q(out) + " 2>" + q(err));
  ASSERT_GT(pid, 0);
  // Not a fixed sleep: before evpipe has installed its handlers, USR1 and HUP would kill it (their default action).
  // A row in the CSV means the pipeline runs, and the handlers are installed before it starts.
  const auto t_spawn = Clock::now();
  for (std::string text;
       std::count(text.begin(), text.end(), '\n') < 2 && Clock::now() - t_spawn < std::chrono::seconds(30);
       text = slurp(csv))
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ASSERT_EQ(::kill(pid, SIGUSR1), 0);
  for (const auto t_usr1 = Clock::now();
       slurp(err).find("status: ") == std::string::npos && Clock::now() - t_usr1 < std::chrono::seconds(5);)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_NE(slurp(err).find("status: "), std::string::npos) << slurp(err);
  ASSERT_EQ(::kill(pid, SIGHUP), 0);
  const auto t_hup = Clock::now();
  EXPECT_EQ(wait_status(pid), 0);
  EXPECT_LT(Clock::now() - t_hup, std::chrono::seconds(5));
  EXPECT_EQ(evpipe::testing::json_field(slurp(out), "interrupted"), "true") << slurp(out);
  (void)whole_rows(csv);
}

// A closed stdout (`evpipe --json | true`): SIGPIPE no longer kills evpipe before its CSV is complete; the rows
// are those of a run whose stdout stays open (--speed max: deterministic), and the exit status is 0.
TEST(EvpipeDurability, ClosedStdoutLosesNoRow) {
  const auto dir = evpipe::testing::temp_dir("durability-pipe");
  const std::string ref = (dir / "ref.csv").string();
  const std::string csv = (dir / "piped.csv").string();
  const std::string rc = (dir / "rc.txt").string();
  const auto r = evpipe::testing::run(kEvpipe + pose_args(ref) + " --speed max --no-lcm --json", dir);
  ASSERT_EQ(r.status, 0) << r.err;
  const std::string cmd = "(" + kEvpipe + pose_args(csv) + " --speed max --no-lcm --json 2>" +
                          q((dir / "err.txt").string()) + "; echo $? >" + q(rc) + ") | true";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  EXPECT_EQ(slurp(rc), "0\n") << slurp(dir / "err.txt");
  EXPECT_NE(slurp(dir / "err.txt").find("could not write the summary to standard output"), std::string::npos)
      << slurp(dir / "err.txt");
  EXPECT_EQ(slurp(csv), slurp(ref));
  EXPECT_GT(whole_rows(csv).size(), 10U);
}
