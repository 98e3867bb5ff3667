#include "probe.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <fstream>
#include <limits>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace sandcell::bench {

namespace {

// A chain of dependent multiply-adds and a division on registers: about 4 ns per iteration on a
// 2.6 GHz core, nothing in memory. The result is returned so the loop is not removed.
double alu_chain(long iterations) {
  double a = 1.0, b = 0.999999, c = 1e-9;
  for (long k = 0; k < iterations; ++k) {
    a = a * b + c;
    b = b + c * a;
    c = c / (1.0 + 1e-12 * a);
  }
  return a + b + c;
}

bool pin_to(int cpu) {
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  return pthread_setaffinity_np(pthread_self(), sizeof(set), &set) == 0;
}

}  // namespace

double alu_rate(int threads, double seconds) {
  // Calibrate one thread's iterations for `seconds`, then time `threads` of them at once.
  long iterations = 1 << 20;
  for (;;) {
    const auto t0 = std::chrono::steady_clock::now();
    volatile double sink = alu_chain(iterations);
    (void)sink;
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (s > 0.02 || iterations > (1L << 40)) {
      iterations = static_cast<long>(double(iterations) * seconds / s);
      break;
    }
    iterations *= 4;
  }
  std::vector<std::thread> run;
  std::atomic<int> ready{0};
  std::atomic<bool> go{false};
  for (int t = 0; t < threads; ++t)
    run.emplace_back([&] {
      ready.fetch_add(1);
      while (!go.load(std::memory_order_acquire)) {
      }
      volatile double sink = alu_chain(iterations);
      (void)sink;
    });
  while (ready.load() < threads) {
  }
  const auto start = std::chrono::steady_clock::now();
  go.store(true, std::memory_order_release);
  for (auto& t : run) t.join();
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return double(threads) * double(iterations) / wall;
}

double pingpong_ns(int samples) {
  if (std::thread::hardware_concurrency() < 2) return std::numeric_limits<double>::quiet_NaN();
  constexpr long k_trips = 20000;
  alignas(64) std::atomic<long> flag{0};
  std::vector<double> ns;
  for (int s = 0; s < samples; ++s) {
    flag.store(0);
    std::atomic<bool> pinned{true};
    std::thread other([&] {
      if (!pin_to(1)) pinned = false;
      for (long k = 0; k < k_trips; ++k) {
        while (flag.load(std::memory_order_acquire) != 2 * k + 1) {
        }
        flag.store(2 * k + 2, std::memory_order_release);
      }
    });
    std::thread self([&] {
      if (!pin_to(0)) pinned = false;
      const auto t0 = std::chrono::steady_clock::now();
      for (long k = 0; k < k_trips; ++k) {
        flag.store(2 * k + 1, std::memory_order_release);
        while (flag.load(std::memory_order_acquire) != 2 * k + 2) {
        }
      }
      ns.push_back(std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count() /
                   (2.0 * k_trips));
    });
    self.join();
    other.join();
    if (!pinned) return std::numeric_limits<double>::quiet_NaN();
  }
  std::sort(ns.begin(), ns.end());
  return ns[ns.size() / 2];
}

double chase_ns(std::size_t bytes, int samples) {
  // One link per 64-byte line; the lines linked in one cycle through all of them in a shuffled
  // order, so that neither the hardware prefetchers nor the neighbouring line help.
  constexpr std::size_t k_stride = 64 / sizeof(std::size_t);  // one link per line
  const std::size_t lines = std::max<std::size_t>(bytes / 64, 2);
  std::vector<std::size_t> order(lines);
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::mt19937_64 rng(12345);
  for (std::size_t k = lines - 1; k > 0; --k) std::swap(order[k], order[rng() % k]);
  std::vector<std::size_t> next(lines * k_stride, 0);
  for (std::size_t k = 0; k < lines; ++k) next[order[k] * k_stride] = order[(k + 1) % lines] * k_stride;
  std::size_t at = 0;
  for (std::size_t k = 0; k < lines; ++k) at = next[at];  // one lap untimed: the pages touched
  constexpr long k_hops = 200000;                         // ~10-40 ms
  std::vector<double> ns;
  for (int s = 0; s < samples; ++s) {
    const auto t0 = std::chrono::steady_clock::now();
    for (long h = 0; h < k_hops; ++h) at = next[at];
    ns.push_back(std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count() /
                 double(k_hops));
  }
  volatile std::size_t sink = at;  // the chain's end is used, so the loop is not removed
  (void)sink;
  std::sort(ns.begin(), ns.end());
  return ns[ns.size() / 2];
}

double stream_gbs(std::size_t bytes, int samples) {
  std::vector<double> a(std::max<std::size_t>(bytes / sizeof(double), 1), 1.0);
  double sum = 0.0;
  std::vector<double> gbs;
  for (int s = 0; s <= samples; ++s) {
    const auto t0 = std::chrono::steady_clock::now();
    // Four running sums, so that the adds' latency does not bound the loop.
    double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    const std::size_t n4 = a.size() / 4 * 4;
    for (std::size_t k = 0; k < n4; k += 4) {
      s0 += a[k];
      s1 += a[k + 1];
      s2 += a[k + 2];
      s3 += a[k + 3];
    }
    sum += s0 + s1 + s2 + s3;
    const double t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (s > 0) gbs.push_back(double(n4 * sizeof(double)) / t / 1e9);  // the first pass touches the pages
  }
  volatile double sink = sum;
  (void)sink;
  std::sort(gbs.begin(), gbs.end());
  return gbs[gbs.size() / 2];
}

CpuAccount::CpuAccount() : start_(take()) {}

CpuAccount::Sample CpuAccount::take() {
  Sample s;
  s.t = std::chrono::steady_clock::now();
  std::ifstream in("/proc/stat");
  std::string line;
  if (std::getline(in, line) && line.rfind("cpu ", 0) == 0) {
    std::istringstream fields(line.substr(4));
    std::uint64_t v[8] = {0, 0, 0, 0, 0, 0, 0, 0};  // user nice system idle iowait irq softirq steal
    for (auto& x : v) fields >> x;
    s.steal = v[7];
    s.total = v[0] + v[1] + v[2] + v[3] + v[4] + v[5] + v[6] + v[7];
    s.busy = v[0] + v[1] + v[2] + v[5] + v[6];
  }
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  s.own_cpu_s = double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
  return s;
}

double CpuAccount::steal_fraction() const {
  const Sample now = take();
  const double total = double(now.total - start_.total);
  return total > 0.0 ? double(now.steal - start_.steal) / total : 0.0;
}

double CpuAccount::foreign_cpus() const {
  const Sample now = take();
  const double tick = double(sysconf(_SC_CLK_TCK));
  const double wall = std::chrono::duration<double>(now.t - start_.t).count();
  if (!(wall > 0.0)) return 0.0;
  const double busy_s = double(now.busy - start_.busy) / tick;
  return std::max(0.0, busy_s - (now.own_cpu_s - start_.own_cpu_s)) / wall;
}

}  // namespace sandcell::bench
