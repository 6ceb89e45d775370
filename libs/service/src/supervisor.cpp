#include "evpipe/service/supervisor.hpp"

#include <algorithm>
#include <stdexcept>
#include <utility>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "evpipe/service/notify.hpp"

namespace evpipe::service {

namespace {
std::chrono::microseconds check_period(const std::optional<std::chrono::microseconds>& watchdog_usec,
                                       std::chrono::microseconds status_period) {
  // Half the watchdog period: a ping that is late by up to one check still arrives in time (sd_watchdog_enabled
  // man page recommends pinging at half the interval).
  if (watchdog_usec) return std::max(std::chrono::microseconds(1), *watchdog_usec / 2);
  return std::max(std::chrono::microseconds(1), status_period);
}
}  // namespace

Supervisor::Supervisor(SupervisorOptions options)
    : options_(std::move(options)),
      watchdog_usec_(options_.watchdog_usec ? options_.watchdog_usec : watchdog_interval()),
      period_(check_period(watchdog_usec_, options_.status_period)) {
  if (watchdog_usec_ && watchdog_usec_->count() <= 0) watchdog_usec_.reset();
}

Supervisor::~Supervisor() {
  stop();
}

void Supervisor::watch(std::string stage, std::function<HeartbeatSample()> probe) {
  if (!probe) throw std::invalid_argument("service::Supervisor::watch: stage '" + stage + "' has no probe");
  std::lock_guard lock(check_mutex_);
  if (started_) throw std::logic_error("service::Supervisor::watch: register stage '" + stage + "' before start()");
  stages_.push_back(Stage{std::move(stage), std::move(probe)});
  stages_.back().last_count = stages_.back().probe().count;
}

void Supervisor::watch(std::string stage, const Heartbeat& heartbeat) {
  watch(std::move(stage), [&heartbeat] { return heartbeat.sample(); });
}

void Supervisor::take_baseline() {
  for (auto& s : stages_) s.last_count = s.probe().count;
}

bool Supervisor::start() {
  std::lock_guard lock(check_mutex_);
  if (started_) return thread_.joinable();
  started_ = true;
  if (!notify_socket_set()) return false;
  take_baseline();
  if (watchdog_usec_) watchdog_ping();
  {
    std::lock_guard wake_lock(wake_mutex_);
    stop_requested_ = false;
  }
  thread_ = std::thread([this] { run(); });
  return true;
}

void Supervisor::stop() {
  {
    std::lock_guard lock(wake_mutex_);
    stop_requested_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void Supervisor::run() {
  std::unique_lock lock(wake_mutex_);
  while (!wake_.wait_for(lock, period_, [this] { return stop_requested_; })) {
    lock.unlock();
    check();
    lock.lock();
  }
}

CheckResult Supervisor::check() {
  std::lock_guard lock(check_mutex_);
  CheckResult result;
  for (auto& s : stages_) {
    const HeartbeatSample now = s.probe();
    const bool advanced = now.count != s.last_count;
    s.last_count = now.count;
    if (advanced || now.idle) {
      if (s.reported_stuck) spdlog::warn("watchdog: stage '{}' is progressing (or idle) again", s.name);
      s.reported_stuck = false;
      continue;
    }
    result.stuck.push_back(s.name);
    if (!s.reported_stuck) {
      // Once per episode: the journal then shows which stage hung right before systemd's SIGABRT.
      spdlog::error("watchdog: stage '{}' made no progress for {} ms and is not idle (heartbeat {}); {}", s.name,
                    period_.count() / 1000, now.count,
                    watchdog_usec_ ? "withholding the watchdog ping so that systemd restarts evpipe"
                                   : "no systemd watchdog configured (WatchdogSec=), nothing will restart it");
      s.reported_stuck = true;
    }
  }
  result.healthy = result.stuck.empty();

  std::string message;
  if (result.healthy && watchdog_usec_) message = "WATCHDOG=1";
  std::string summary;
  if (options_.status) summary = options_.status();
  if (!result.healthy)
    summary = fmt::format("STUCK: {}{}{}", fmt::join(result.stuck, ","), summary.empty() ? "" : "; ", summary);
  if (!summary.empty()) {
    if (!message.empty()) message += '\n';
    message += "STATUS=" + one_line(summary);
  }
  // One datagram for ping and status: they describe the same instant.
  if (!message.empty()) {
    const bool sent = notify(message);
    result.pinged = sent && result.healthy && watchdog_usec_.has_value();
  }
  checks_.fetch_add(1);
  if (result.healthy) {
    consecutive_stuck_.store(0);
  } else {
    consecutive_stuck_.fetch_add(1);
  }
  return result;
}

}  // namespace evpipe::service
