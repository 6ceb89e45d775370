#pragma once
// One worker thread that runs one job at a time for a stage that must not wait for it: the pose stage hands an
// initialisation attempt (50-500 ms) to it and keeps publishing a status for every window meanwhile. Submitting
// never blocks (a busy worker refuses the job); the result is collected by polling. The thread starts with the
// object and is joined by the destructor, which waits for a job still running (none is abandoned half-way:
// its inputs are owned by the job) and drops one not yet started. A job that throws hands its exception to
// poll(), which rethrows it on the owner's thread.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <utility>

namespace evpipe::runtime {

/// Names the calling thread and raises its nice value by `nice_increment` (Linux: per thread; best effort, a
/// refusal is ignored). Defined in src/background_task.cpp.
void lower_priority_and_name(const std::string& name, int nice_increment) noexcept;

template <class Result>
class BackgroundTask {
 public:
  /// Starts the worker thread (a failure to create it throws here, not on a later submit), named `name` (at most
  /// 15 characters show in `top -H`) and, with nice_increment > 0, at a lower scheduling priority than the
  /// process: on a 2-core machine a 100 ms job must not take the CPU from the threads that publish.
  explicit BackgroundTask(std::string name, int nice_increment = 0)
      : name_(std::move(name)), nice_increment_(nice_increment), thread_([this] { run(); }) {}
  BackgroundTask(const BackgroundTask&) = delete;
  BackgroundTask& operator=(const BackgroundTask&) = delete;
  ~BackgroundTask() {
    {
      const std::lock_guard lock(mutex_);
      stop_ = true;
    }
    wake_.notify_all();
    if (thread_.joinable()) thread_.join();
  }

  /// Starts `job` on the worker unless one is queued, running or finished but not yet polled (then false).
  bool submit(std::function<Result()> job) {
    {
      const std::lock_guard lock(mutex_);
      if (job_ || running_ || result_ || error_) return false;
      job_ = std::move(job);
      ++submitted_;
    }
    wake_.notify_one();
    return true;
  }

  /// True from submit() until the result has been taken by poll().
  [[nodiscard]] bool pending() const {
    const std::lock_guard lock(mutex_);
    return job_ || running_ || result_ || error_;
  }

  /// The finished job's result (once; the worker is then free), or nullopt while it runs or when none was given.
  /// Rethrows what the job threw.
  std::optional<Result> poll() {
    const std::lock_guard lock(mutex_);
    if (error_) {
      std::exception_ptr e = error_;
      error_ = nullptr;
      std::rethrow_exception(e);
    }
    std::optional<Result> out = std::move(result_);
    result_.reset();
    return out;
  }

  /// Waits until the submitted job has finished (tests, and callers that want the synchronous behaviour).
  void wait() {
    std::unique_lock lock(mutex_);
    done_.wait(lock, [this] { return !job_ && !running_; });
  }

  /// Jobs submitted, and the compute time of the last finished one.
  [[nodiscard]] std::uint64_t submitted() const {
    const std::lock_guard lock(mutex_);
    return submitted_;
  }
  [[nodiscard]] std::chrono::nanoseconds last_duration() const {
    const std::lock_guard lock(mutex_);
    return last_duration_;
  }

 private:
  void run() {
    lower_priority_and_name(name_, nice_increment_);
    std::unique_lock lock(mutex_);
    while (true) {
      wake_.wait(lock, [this] { return stop_ || job_; });
      if (stop_) return;  // a job not yet started is dropped
      std::function<Result()> job = std::move(*job_);
      job_.reset();
      running_ = true;
      lock.unlock();
      const auto t0 = std::chrono::steady_clock::now();
      std::optional<Result> r;
      std::exception_ptr error;
      try {
        r = job();
      } catch (...) {
        error = std::current_exception();
      }
      const auto dt = std::chrono::steady_clock::now() - t0;
      lock.lock();
      running_ = false;
      result_ = std::move(r);
      error_ = error;
      last_duration_ = std::chrono::duration_cast<std::chrono::nanoseconds>(dt);
      done_.notify_all();
    }
  }

  std::string name_;
  int nice_increment_;
  mutable std::mutex mutex_;
  std::condition_variable wake_;
  std::condition_variable done_;
  std::optional<std::function<Result()>> job_;
  std::optional<Result> result_;
  std::exception_ptr error_;
  bool running_ = false;
  bool stop_ = false;
  std::uint64_t submitted_ = 0;
  std::chrono::nanoseconds last_duration_{0};
  std::thread thread_;
};

}  // namespace evpipe::runtime
