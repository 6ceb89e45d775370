#pragma once
// Worker threads that run the tasks of one call together: the denoise stage spreads one
// block of the curvature filter over cores with it. run(n, task) runs task(0) on the calling thread and the others
// on the workers (and on the caller again when there are more tasks than threads), and returns once all have
// returned, rethrowing the first exception. One caller at a time; the destructor joins the workers (never
// while a run() is in progress: the owner's thread is the caller).

#include <condition_variable>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace evpipe::runtime {

/// Runs task(0) ... task(count - 1) and returns when all have returned: the type of denoise::TaskRunner.
using TaskRunner = std::function<void(int count, const std::function<void(int)>& task)>;

class TaskPool {
 public:
  /// Starts `workers` threads named `name`0, `name`1, ... (workers may be 0: run() then runs every task itself).
  TaskPool(int workers, const std::string& name);
  ~TaskPool();
  TaskPool(const TaskPool&) = delete;
  TaskPool& operator=(const TaskPool&) = delete;

  void run(int count, const std::function<void(int)>& task);
  /// A runner (e.g. for denoise::Filter::set_parallelism); valid while the pool lives.
  [[nodiscard]] TaskRunner runner() {
    return [this](int count, const std::function<void(int)>& task) { run(count, task); };
  }
  /// Threads that take part in a run(): the workers and the caller.
  [[nodiscard]] int threads() const noexcept { return static_cast<int>(threads_.size()) + 1; }

 private:
  void work(int index, const std::string& name);
  /// Claims and runs tasks of the current generation until none is left (mutex held on entry and exit).
  void drain(std::unique_lock<std::mutex>& lock);

  std::mutex mutex_;
  std::condition_variable work_cv_;
  std::condition_variable done_cv_;
  const std::function<void(int)>* task_ = nullptr;
  int count_ = 0;
  int next_ = 0;     // next task to claim
  int running_ = 0;  // claimed and not yet returned
  bool stop_ = false;
  std::exception_ptr error_;
  std::vector<std::thread> threads_;
};

}  // namespace evpipe::runtime
