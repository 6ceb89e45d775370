#include "evpipe/runtime/task_pool.hpp"

#include <stdexcept>
#include <utility>

#include "evpipe/runtime/background_task.hpp"

namespace evpipe::runtime {

TaskPool::TaskPool(int workers, const std::string& name) {
  if (workers < 0) throw std::invalid_argument("TaskPool: workers must be >= 0");
  threads_.reserve(static_cast<std::size_t>(workers));
  try {
    for (int k = 0; k < workers; ++k) threads_.emplace_back([this, k, name] { work(k, name); });
  } catch (...) {  // a thread could not be created: stop the ones that were
    {
      const std::lock_guard lock(mutex_);
      stop_ = true;
    }
    work_cv_.notify_all();
    for (auto& t : threads_) t.join();
    throw;
  }
}

TaskPool::~TaskPool() {
  {
    const std::lock_guard lock(mutex_);
    stop_ = true;
  }
  work_cv_.notify_all();
  for (auto& t : threads_) t.join();
}

void TaskPool::drain(std::unique_lock<std::mutex>& lock) {
  while (next_ < count_) {
    const int k = next_++;
    ++running_;
    const auto* task = task_;
    lock.unlock();
    std::exception_ptr error;
    try {
      (*task)(k);
    } catch (...) {
      error = std::current_exception();
    }
    lock.lock();
    if (error && !error_) error_ = error;
    if (--running_ == 0 && next_ >= count_) done_cv_.notify_all();
  }
}

void TaskPool::run(int count, const std::function<void(int)>& task) {
  if (count <= 0) return;
  std::unique_lock lock(mutex_);
  task_ = &task;
  count_ = count;
  next_ = 0;
  running_ = 0;
  error_ = nullptr;
  if (count > 1 && !threads_.empty()) work_cv_.notify_all();
  drain(lock);  // the caller works too; the last task to return wakes it
  done_cv_.wait(lock, [this] { return running_ == 0; });
  task_ = nullptr;
  count_ = 0;
  if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
}

void TaskPool::work(int index, const std::string& name) {
  lower_priority_and_name(name + std::to_string(index), 0);
  std::unique_lock lock(mutex_);
  for (;;) {
    work_cv_.wait(lock, [this] { return stop_ || next_ < count_; });  // a task left to claim
    if (stop_) return;
    drain(lock);
  }
}

}  // namespace evpipe::runtime
