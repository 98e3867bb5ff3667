#include "engine/executor.hpp"

#include "engine/assert.hpp"
#include "engine/build_arch.hpp"
#include "engine/executor_tbb.hpp"

#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/info.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/partitioner.h>

#include <array>
#include <atomic>
#include <memory>
#include <cstdlib>
#include <vector>
#include <string>
#include <thread>

#ifdef __linux__
#include <sched.h>
#endif

namespace sandcell {

Executor::Executor(ExecutorConfig config) : backend_(config.backend), partition_(config.partition) {
  // Every world has an executor: this reference links engine/cpu_guard.cpp into every program, and
  // with it the startup check that stops a build for a newer CPU with a message (build_arch.hpp).
  static_cast<void>(build_arch());
  SANDCELL_CHECK(config.threads >= 0,
                 "threads must be >= 0 (0 = all hardware threads), got " + std::to_string(config.threads));
  if (backend_ == Backend::serial) {
    threads_ = 1;
    return;
  }
  threads_ = config.threads > 0 ? config.threads : available_cpus();
  impl_ = std::make_unique<Impl>(threads_);
  if (partition_ == Partition::owner) impl_->cpus = allowed_cpus();
}

Executor::~Executor() = default;

std::vector<int> allowed_cpus() {
  std::vector<int> cpus;
#ifdef __linux__
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) == 0)
    for (int c = 0; c < CPU_SETSIZE; ++c)
      if (CPU_ISSET(c, &set)) cpus.push_back(c);
#endif
  return cpus;
}

namespace {
// Pins the calling worker thread to `cpu`, once per thread and CPU (a thread-local remembers it): the
// first task a worker runs in an owner-partitioned pass pins it. Best effort: a refusal leaves it
// unpinned. The calling (external) thread, arena slot 0, is never pinned: its affinity is the
// caller's business.
void pin_worker(int cpu) {
#ifdef __linux__
  thread_local int pinned = -1;
  if (pinned == cpu) return;
  cpu_set_t set;
  CPU_ZERO(&set);
  CPU_SET(cpu, &set);
  if (sched_setaffinity(0, sizeof set, &set) == 0) pinned = cpu;
#else
  static_cast<void>(cpu);
#endif
}
}  // namespace

int available_cpus() {
  if (const char* slurm = std::getenv("SLURM_CPUS_PER_TASK"); slurm && *slurm) {
    char* end = nullptr;
    const long n = std::strtol(slurm, &end, 10);
    if (end && *end == '\0' && n > 0 && n <= 1 << 20) return static_cast<int>(n);
  }
#ifdef __linux__
  cpu_set_t set;
  CPU_ZERO(&set);
  if (sched_getaffinity(0, sizeof set, &set) == 0) {
    const int n = CPU_COUNT(&set);
    if (n > 0) return n;
  }
#endif
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

void Executor::parallel_for(std::size_t n, std::size_t grain, FunctionRef<void(std::size_t, std::size_t)> body) {
  grain = std::max<std::size_t>(grain, 1);
  const std::size_t chunks = (n + grain - 1) / grain;
  if (chunks == 0) return;
  if (backend_ == Backend::serial || chunks == 1) {
    for (std::size_t c = 0; c < chunks; ++c) body(c * grain, std::min(n, (c + 1) * grain));
    return;
  }
  const auto run = [&](const tbb::blocked_range<std::size_t>& r) {
    for (std::size_t c = r.begin(); c < r.end(); ++c) body(c * grain, std::min(n, (c + 1) * grain));
  };
  if (partition_ == Partition::owner) {
    // One share of chunks per thread; a task runs its own thread's share if no one has, else the
    // first share left. Every share runs once, whoever runs it: the chunks, and so the results,
    // are the same.
    const int t = std::min<int>(threads_, static_cast<int>(chunks));
    // Claims on the stack up to 64 threads (no allocation per pass); more threads, on the heap.
    std::array<std::atomic<bool>, 64> small{};
    std::unique_ptr<std::atomic<bool>[]> large;
    if (t > 64) large = std::make_unique<std::atomic<bool>[]>(static_cast<std::size_t>(t));
    std::atomic<bool>* taken = large ? large.get() : small.data();
    const auto share = [&](int k) {
      const std::size_t c0 = chunks * static_cast<std::size_t>(k) / static_cast<std::size_t>(t);
      const std::size_t c1 = chunks * static_cast<std::size_t>(k + 1) / static_cast<std::size_t>(t);
      for (std::size_t c = c0; c < c1; ++c) body(c * grain, std::min(n, (c + 1) * grain));
    };
    impl_->arena.execute([&] {
      tbb::parallel_for(
          0, t,
          [&](int) {
            const int me = tbb::this_task_arena::current_thread_index();
            if (me > 0 && !impl_->cpus.empty())
              pin_worker(impl_->cpus[static_cast<std::size_t>(me) % impl_->cpus.size()]);
            if (me >= 0 && me < t && !taken[static_cast<std::size_t>(me)].exchange(true)) return share(me);
            for (int k = 0; k < t; ++k)
              if (!taken[static_cast<std::size_t>(k)].exchange(true)) return share(k);
          },
          tbb::static_partitioner());
    });
    return;
  }
  impl_->arena.execute([&] {
    if (partition_ == Partition::fixed)
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunks, 1), run, tbb::static_partitioner());
    else
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunks, 1), run, tbb::simple_partitioner());
  });
}

void Executor::execute(FunctionRef<void()> fn) {
  if (backend_ == Backend::serial) {
    fn();
    return;
  }
  impl_->arena.execute([&] { fn(); });
}

}  // namespace sandcell
