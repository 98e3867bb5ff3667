#pragma once
// What the machine allows at a given moment, measured without the engine (dem-bench --scaling,
// per round): is a second thread a second core right now?
//   - alu_one: one thread's rate on that chain alone (iterations per second): the core's own speed
//     (clock, a sibling hardware thread busy, time taken by the host), without memory.
//   - alu_ratio: T threads each running a chain of dependent floating-point operations on
//     registers only (no memory, nothing shared) against one thread alone. On T free cores it is
//     T; where the host runs two of the guest's vCPUs on the two hardware threads of one core, or
//     time-slices them on one, it falls toward 1, whatever any program does.
//   - pingpong_ns: one cache-line transfer between threads pinned to vCPU 0 and vCPU 1 (half a
//     round trip of a flag). Its size tells where the host put the two vCPUs: hardware threads of
//     one core share their L1 (a few tens of ns), cores of one L3 pay the L3 (~50-100 ns), farther
//     more; a vCPU descheduled by the host shows as microseconds.
//   - chase_ns and stream_gbs: one thread alone against memory. chase_ns: the latency of one
//     dependent load, following a random cycle through 16 MiB (the order of the engine's working set
//     on dem-bench's 20,000-sphere scene): a few tens of ns where the host leaves the guest its
//     last-level cache, a DRAM access (~100-200 ns) where other guests have taken it. stream_gbs:
//     one thread's read bandwidth over 64 MiB, summed in order. A memory-bound program's speed
//     follows these whatever its own code does.
//   - steal and foreign: from /proc/stat over the round, the fraction of the machine's time the
//     hypervisor reports as stolen, and the CPUs' worth of busy time of other processes of the
//     guest (a build beside the benchmark shows here).
#include <chrono>
#include <cstddef>
#include <cstdint>

namespace sandcell::bench {

/// Operations per second of `threads` threads each running the register-only chain for about
/// `seconds`, at once (threads = 1: one alone).
double alu_rate(int threads, double seconds);

/// Nanoseconds per one-way cache-line transfer between threads pinned to vCPUs 0 and 1 (NaN with
/// fewer than 2 CPUs or where pinning fails), median of `samples` batches.
double pingpong_ns(int samples = 5);

/// Nanoseconds per dependent load of one thread following a random cycle through `bytes` of memory
/// (one load per 64-byte line), median of `samples` batches of about 30 ms.
double chase_ns(std::size_t bytes, int samples = 5);

/// One thread's read bandwidth in GB/s, summing `bytes` of doubles in order, median of `samples`
/// passes (after one untimed pass that touches the pages).
double stream_gbs(std::size_t bytes, int samples = 5);

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
