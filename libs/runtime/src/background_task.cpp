#include "evpipe/runtime/background_task.hpp"

#include <pthread.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>

namespace evpipe::runtime {

void lower_priority_and_name(const std::string& name, int nice_increment) noexcept {
  (void)pthread_setname_np(pthread_self(), name.substr(0, 15).c_str());
  if (nice_increment <= 0) return;
  // On Linux a nice value belongs to the thread (its tid), not to the whole process.
  const auto tid = static_cast<id_t>(syscall(SYS_gettid));
  errno = 0;
  const int current = getpriority(PRIO_PROCESS, tid);
  if (errno != 0) return;
  (void)setpriority(PRIO_PROCESS, tid, current + nice_increment);
}

}  // namespace evpipe::runtime
