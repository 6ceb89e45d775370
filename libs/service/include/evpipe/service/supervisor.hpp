#pragma once
// The watchdog supervisor: a thread that pings systemd's watchdog at WATCHDOG_USEC/2, but only while every
// registered pipeline stage makes progress. A stage that neither advances its heartbeat between two checks nor
// declares itself idle is stuck: the supervisor withholds the ping and logs which stage, systemd's watchdog
// expires and it kills (SIGABRT) and restarts the process (Restart=on-failure). A process whose supervisor still
// pings while a consumer hangs would be a zombie that looks healthy.
//
// It also mirrors a one-line summary, provided by the application, into STATUS= on every check.
// Outside systemd (no $NOTIFY_SOCKET) start() does nothing.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

namespace evpipe::service {

/// What a stage reports at each check.
struct HeartbeatSample {
  std::uint64_t count = 0;  ///< monotonically increasing progress counter (batches, windows, poses, ...)
  bool idle = false;        ///< legitimately waiting (e.g. on an empty input queue): not advancing is fine
};

/// A ready-made heartbeat for a stage: beat() after each unit of work, set_idle(true) while blocked on an
/// empty input (and false again before working). Lock-free; safe to call from the stage thread while the
/// supervisor samples it.
class Heartbeat {
 public:
  void beat() noexcept { count_.fetch_add(1, std::memory_order_relaxed); }
  void set_idle(bool idle) noexcept { idle_.store(idle, std::memory_order_relaxed); }
  [[nodiscard]] HeartbeatSample sample() const noexcept {
    return {count_.load(std::memory_order_relaxed), idle_.load(std::memory_order_relaxed)};
  }

 private:
  std::atomic<std::uint64_t> count_{0};
  std::atomic<bool> idle_{false};
};

struct SupervisorOptions {
  /// Watchdog period; nullopt = ask systemd (watchdog_interval()). Pings go out at half of it.
  std::optional<std::chrono::microseconds> watchdog_usec;
  /// Check/STATUS period when the watchdog is off but $NOTIFY_SOCKET is set (STATUS= still mirrored).
  std::chrono::microseconds status_period{std::chrono::seconds(1)};
  /// One-line summary for STATUS= (called on the supervisor thread at every check); empty = no STATUS=.
  std::function<std::string()> status;
};

/// The outcome of one check.
struct CheckResult {
  bool healthy = true;             ///< every stage advanced or was idle
  bool pinged = false;             ///< WATCHDOG=1 was sent (healthy and the watchdog is on)
  std::vector<std::string> stuck;  ///< names of the stages that neither advanced nor were idle
};

class Supervisor {
 public:
  explicit Supervisor(SupervisorOptions options = {});
  ~Supervisor();  ///< stops the thread
  Supervisor(const Supervisor&) = delete;
  Supervisor& operator=(const Supervisor&) = delete;

  /// Registers a stage. `probe` is called on the supervisor thread at every check and must be cheap and
  /// thread-safe (read atomics). Register every stage before start(); throws std::logic_error afterwards.
  void watch(std::string stage, std::function<HeartbeatSample()> probe);
  /// The same for a Heartbeat, which must outlive the supervisor.
  void watch(std::string stage, const Heartbeat& heartbeat);

  /// Starts the supervisor thread when $NOTIFY_SOCKET is set (sends a first WATCHDOG=1 right away, and takes
  /// the current heartbeats as the baseline). Returns whether a thread was started.
  bool start();
  /// Stops and joins the thread (idempotent). Call it before stopping the stages on shutdown, so that a slow
  /// drain does not read as a hang.
  void stop();

  /// One check, as the thread runs it: samples every stage against the previous sample, pings if all are
  /// healthy, logs newly stuck stages, sends STATUS=. Public so tests can step it deterministically.
  CheckResult check();

  /// The check period: WATCHDOG_USEC/2, or status_period without a watchdog.
  [[nodiscard]] std::chrono::microseconds period() const { return period_; }
  [[nodiscard]] bool watchdog_enabled() const { return watchdog_usec_.has_value(); }
  /// Checks done and consecutive unhealthy checks so far (for tests and the application's stats).
  [[nodiscard]] std::uint64_t checks() const { return checks_.load(); }
  [[nodiscard]] std::uint64_t consecutive_stuck() const { return consecutive_stuck_.load(); }

 private:
  struct Stage {
    std::string name;
    std::function<HeartbeatSample()> probe;
    std::uint64_t last_count = 0;
    bool reported_stuck = false;
  };
  void run();
  void take_baseline();

  SupervisorOptions options_;
  std::optional<std::chrono::microseconds> watchdog_usec_;
  std::chrono::microseconds period_;
  std::vector<Stage> stages_;
  std::mutex check_mutex_;  // one check at a time (thread vs. a test calling check())
  std::mutex wake_mutex_;
  std::condition_variable wake_;
  bool stop_requested_ = false;
  bool started_ = false;
  std::thread thread_;
  std::atomic<std::uint64_t> checks_{0};
  std::atomic<std::uint64_t> consecutive_stuck_{0};
};

}  // namespace evpipe::service
