#pragma once
// The executor seam: the only way systems run work in parallel. Systems never include TBB.
//
// parallel_for cuts [0, n) into chunks whose boundaries depend only on n and the grain, never on
// the thread count, and each chunk writes its own slots. deterministic_reduce computes one
// partial per chunk and folds the partials serially in chunk order, so a sum is bitwise the same
// for 1 or N threads and for the serial backend.
#include "engine/function_ref.hpp"

#include <algorithm>
#include <array>
#include <cstddef>
#include <memory>
#include <vector>

namespace sandcell {

enum class Backend { serial, tbb };

/// How parallel_for hands its chunks to the threads (the chunks themselves, and so every result,
/// are the same either way).
enum class Partition {
  dynamic,  // work stealing, one chunk at a time: balances uneven chunks and a core slowed by others
  fixed,    // each thread takes the same contiguous share of the chunks every pass (TBB
            // static_partitioner): a thread keeps working on the same particles and pairs
  owner,    // the chunks cut into one contiguous share per thread, share k run by the arena's thread k
            // whenever it is there to take it (the others take what is left), and the worker threads
            // pinned each to one CPU of the process's mask: every pass, a thread and its core keep the
            // same particles and pairs, so only the boundary between shares moves between caches
};

struct ExecutorConfig {
  Backend backend = Backend::tbb;
  int threads = 0;  // 0: available_cpus(); ignored by the serial backend (always 1)
  Partition partition = Partition::dynamic;
};

/// The CPUs this process may use: SLURM_CPUS_PER_TASK inside a Slurm job step when it is a positive
/// integer, else the CPUs of the process's affinity mask (sched_getaffinity: taskset, cgroups
/// cpusets, a scheduler's binding), else std::thread::hardware_concurrency(); at least 1.
int available_cpus();
/// The CPUs of the process's affinity mask, ascending (empty where it cannot be read).
std::vector<int> allowed_cpus();

class Executor {
 public:
  explicit Executor(ExecutorConfig config = {});
  ~Executor();
  Executor(const Executor&) = delete;
  Executor& operator=(const Executor&) = delete;

  Backend backend() const { return backend_; }
  Partition partition() const { return partition_; }
  int threads() const { return threads_; }

  /// Calls body(begin, end) for consecutive chunks of `grain` indices covering [0, n).
  void parallel_for(std::size_t n, std::size_t grain, FunctionRef<void(std::size_t, std::size_t)> body);

  /// Maximum number of partials of a reduction; the chunk size grows past `grain` to respect it.
  static constexpr std::size_t k_max_partials = 128;

  /// Deterministic reduction: map(begin, end) -> T per chunk, then join(acc, partial) in chunk order
  /// starting from `identity`. Chunking depends only on n and grain.
  template <class T, class Map, class Join>
  T deterministic_reduce(std::size_t n, std::size_t grain, T identity, Map&& map, Join&& join) {
    const std::size_t chunk = reduce_chunk(n, grain);
    const std::size_t chunks = n == 0 ? 0 : (n + chunk - 1) / chunk;
    std::array<T, k_max_partials> partial;
    parallel_for(chunks, 1, [&](std::size_t c0, std::size_t c1) {
      for (std::size_t c = c0; c < c1; ++c) partial[c] = map(c * chunk, std::min(n, (c + 1) * chunk));
    });
    T acc = identity;
    for (std::size_t c = 0; c < chunks; ++c) acc = join(acc, partial[c]);
    return acc;
  }

  static std::size_t reduce_chunk(std::size_t n, std::size_t grain) {
    grain = std::max<std::size_t>(grain, 1);
    return std::max(grain, (n + k_max_partials - 1) / k_max_partials);
  }

  /// Runs fn inside this executor's thread pool (TBB arena), so that work it spawns uses exactly
  /// this executor's threads. With the serial backend, calls fn directly.
  void execute(FunctionRef<void()> fn);

  struct Impl;
  Impl* impl() { return impl_.get(); }

 private:
  Backend backend_;
  Partition partition_ = Partition::dynamic;
  int threads_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace sandcell
