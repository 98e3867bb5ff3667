#pragma once
// For the tests of the default thread count: while alive, the process may run on one CPU (the
// first of its mask, as `taskset -c K` would leave it) and SLURM_CPUS_PER_TASK is unset; the mask
// and the variable are restored after.
#include <sched.h>

#include <cstdlib>
#include <string>

namespace sandcell::test {

class OneCpu {
 public:
  OneCpu() {
    ok_ = sched_getaffinity(0, sizeof saved_, &saved_) == 0;
    const char* slurm = std::getenv("SLURM_CPUS_PER_TASK");
    had_slurm_ = slurm != nullptr;
    if (slurm) slurm_ = slurm;
    ::unsetenv("SLURM_CPUS_PER_TASK");
    int first = 0;
    while (ok_ && !CPU_ISSET(first, &saved_)) ++first;
    cpu_set_t one;
    CPU_ZERO(&one);
    CPU_SET(first, &one);
    ok_ = ok_ && sched_setaffinity(0, sizeof one, &one) == 0;
  }
  ~OneCpu() {
    sched_setaffinity(0, sizeof saved_, &saved_);
    if (had_slurm_)
      ::setenv("SLURM_CPUS_PER_TASK", slurm_.c_str(), 1);
    else
      ::unsetenv("SLURM_CPUS_PER_TASK");
  }
  OneCpu(const OneCpu&) = delete;
  OneCpu& operator=(const OneCpu&) = delete;
  bool ok() const { return ok_; }  // the mask was narrowed
  int cpus_before() const { return CPU_COUNT(&saved_); }

 private:
  cpu_set_t saved_;
  bool ok_ = false;
  bool had_slurm_ = false;
  std::string slurm_;
};

}  // namespace sandcell::test
