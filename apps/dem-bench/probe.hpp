#pragma once
// What the machine allows at a given moment, measured without the engine (dem-bench --scaling,
// per round): is a second thread a second core right now?
//   - alu_ratio: T threads each running a chain of dependent floating-point operations on
//     registers only (no memory, nothing shared) against one thread alone. On T free cores it is
//     T; where the host runs two of the guest's vCPUs on the two hardware threads of one core, or
//     time-slices them on one, it falls toward 1, whatever any program does.
//   - pingpong_ns: one cache-line transfer between threads pinned to vCPU 0 and vCPU 1 (half a
//     round trip of a flag). Its size tells where the host put the two vCPUs: hardware threads of
//     one core share their L1 (a few tens of ns), cores of one L3 pay the L3 (~50-100 ns), farther
//     more; a vCPU descheduled by the host shows as microseconds.
//   - steal and foreign: from /proc/stat over the round, the fraction of the machine's time the
//     hypervisor reports as stolen, and the CPUs' worth of busy time of other processes of the
//     guest (a build beside the benchmark shows here).
#include <chrono>
#include <cstdint>

namespace sandcell::bench {

/// Operations per second of `threads` threads each running the register-only chain for about
/// `seconds`, at once (threads = 1: one alone).
double alu_rate(int threads, double seconds);

/// Nanoseconds per one-way cache-line transfer between threads pinned to vCPUs 0 and 1 (NaN with
/// fewer than 2 CPUs or where pinning fails), median of `samples` batches.
double pingpong_ns(int samples = 5);

/// The machine's CPU accounting between two points in time (/proc/stat and getrusage).
class CpuAccount {
 public:
  CpuAccount();
  /// Since construction: the fraction of all CPU time the hypervisor reports as stolen.
  double steal_fraction() const;
  /// Since construction: other processes' busy CPU time per wall second (in CPUs).
  double foreign_cpus() const;

 private:
  struct Sample {
    std::uint64_t busy = 0, steal = 0, total = 0;  // clock ticks over all CPUs
    double own_cpu_s = 0.0;                        // this process, user + system
    std::chrono::steady_clock::time_point t;
  };
  static Sample take();
  Sample start_;
};

}  // namespace sandcell::bench
