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
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string_view>
#include <vector>

namespace sandcell {

enum class Backend { serial, tbb };

/// How parallel_for hands its chunks to the threads (every result is the same either way).
enum class Partition {
  owner,     // the range cut into one contiguous share per thread (Executor::shares), share k
             // run from its front by the arena's thread k whenever it is there to take it (the others
             // take what is left), and a thread done with its share takes the last chunks of the
             // share with the most left: every pass, a thread keeps the same particles and the pairs
             // of those particles, what crosses between shares goes through the contact pass's halo
             // (systems/halo.hpp), so a core reads another's data only as packed copies, and a late
             // or slow thread's tail is finished by the others
  dynamic,   // work stealing, one chunk at a time: balances uneven chunks and a core slowed by others,
             // but a thread's particles and pairs change from pass to pass
  fixed,     // TBB's static_partitioner over the chunks (no halo)
  adaptive,  // default: owner or dynamic, whichever ran the world's steps faster in the last
             // trial: the two are timed against each other in short batches (owner, dynamic,
             // dynamic, owner, so that a steady drift of the host's speed favours neither), the
             // faster then runs for a while, and the trial is repeated; on one thread, owner. Every
             // result is the same whichever runs, so the choice costs no determinism
};

/// The partitions' names, indexed by the enum's value: what dem-bench --partition, triaxial
/// --thread-partition and the Python World's `partition` take.
inline constexpr std::array<std::string_view, 4> k_partition_names{"owner", "dynamic", "fixed", "adaptive"};
inline std::string_view partition_name(Partition p) { return k_partition_names[static_cast<std::size_t>(p)]; }
/// The enum value whose name is `name` (exactly) in a table of names indexed by the enum's values,
/// or none: k_partition_names, k_visit_order_names.
template <class Enum, std::size_t N>
std::optional<Enum> from_name(const std::array<std::string_view, N>& names, std::string_view name) {
  for (std::size_t k = 0; k < N; ++k)
    if (names[k] == name) return static_cast<Enum>(k);
  return std::nullopt;
}
/// The partition named `name` (exactly, as in k_partition_names), or none.
inline std::optional<Partition> partition_from_name(std::string_view name) {
  return from_name<Partition>(k_partition_names, name);
}

/// The trials of Partition::adaptive. Each of the four batches of a trial runs at least
/// `batch_steps` steps and `batch_seconds` of step time; its first step (after a switch: the
/// halo's rebuild, cold caches) is not counted. The faster partition, by the median step time over
/// its two batches (a median, so that a list rebuild or a vCPU taken away for one step does not
/// decide), then runs for `hold` times the trial's duration before the next trial. Half a trial
/// runs the slower one, so the trials cost less than 1 / (2 hold) of the run (1.7 % at 30), and
/// far less where the two are close.
struct AdaptiveSettings {
  double batch_seconds = 0.02;
  std::uint32_t batch_steps = 16;
  double hold = 30.0;
};

/// The order in which a per-particle pass over scattered pair data (the force gather,
/// systems/force_gather.hpp) visits the particles. Every sum is the same in each; only the speed
/// differs, and which is faster depends on whether the pair data the pass reads stays in cache.
enum class VisitOrder {
  sorted,    // within blocks of 128 particles by their pair counts: the loops' exits are predicted
             // (dense-20k on the 2-core host: 1.16x the array order's throughput on 1 thread)
  array,     // the array order, the scattered reads asked for a few particles ahead: the streams a
             // hardware prefetcher follows (the 160,000-sphere scene: 1.13x the sorted order's)
  adaptive,  // default: the faster of the two, timed against each other call by call (force_gather.cpp)
};
inline constexpr std::array<std::string_view, 3> k_visit_order_names{"sorted", "array", "adaptive"};
inline std::string_view visit_order_name(VisitOrder v) { return k_visit_order_names[static_cast<std::size_t>(v)]; }
inline std::optional<VisitOrder> visit_order_from_name(std::string_view name) {
  return from_name<VisitOrder>(k_visit_order_names, name);
}

struct ExecutorConfig {
  Backend backend = Backend::tbb;
  int threads = 0;  // 0: available_cpus(); ignored by the serial backend (always 1)
  Partition partition = Partition::adaptive;
  AdaptiveSettings adaptive{};
  VisitOrder visit_order = VisitOrder::adaptive;
};

/// Steps run under each partition, and the switches between them (Partition::adaptive).
struct PartitionSteps {
  std::uint64_t owner = 0, dynamic = 0, switches = 0, trials = 0;
};

/// The CPUs this process may use: SLURM_CPUS_PER_TASK inside a Slurm job step when it is a positive
/// integer, else the CPUs of the process's affinity mask (sched_getaffinity: taskset, cgroups
/// cpusets, a scheduler's binding), else std::thread::hardware_concurrency(); at least 1.
int available_cpus();

class Executor {
 public:
  explicit Executor(ExecutorConfig config = {});
  ~Executor();
  Executor(const Executor&) = delete;
  Executor& operator=(const Executor&) = delete;

  Backend backend() const { return backend_; }
  /// The partition asked for; under Partition::adaptive, active_partition() is the one in use.
  Partition partition() const { return partition_; }
  Partition active_partition() const { return active_; }
  /// The visiting order asked for (VisitOrder; adaptive: the pass chooses).
  VisitOrder visit_order() const { return visit_order_; }
  int threads() const { return threads_; }

  /// Around each step of a world (World::step_until): under Partition::adaptive the executor times
  /// the steps and switches between owner and dynamic between them (never inside a step); under the
  /// others, nothing.
  void begin_step() {
    if (tuning_) step_start_ = std::chrono::steady_clock::now();
  }
  void end_step() {
    if (tuning_) record_step(std::chrono::duration<double>(std::chrono::steady_clock::now() - step_start_).count());
  }
  /// What end_step does with a step's duration: the trial's bookkeeping and, at a batch's end, the
  /// switch (public for the tests, which feed chosen durations). Nothing unless adaptive.
  void record_step(double seconds);
  /// Steps run under each partition, the switches and the trials done: zeros but under
  /// Partition::adaptive on more than one thread.
  const PartitionSteps& partition_steps() const { return steps_; }

  /// Calls body(begin, end) for consecutive chunks of `grain` indices covering [0, n).
  void parallel_for(std::size_t n, std::size_t grain, FunctionRef<void(std::size_t, std::size_t)> body);

  /// Most shares the owner partition cuts (more threads than this: the others take what is left).
  static constexpr std::size_t k_max_shares = 256;
  /// The owner partition cuts its shares at multiples of min(grain, k_share_align), so that the
  /// particle passes of different grains (256, 1024) cut the particles in the same places, and the
  /// shares differ by less than k_share_align items.
  static constexpr std::size_t k_share_align = 128;

  /// Contiguous shares of an index range, one per thread: share k is [bounds[k], bounds[k+1]).
  struct Shares {
    std::size_t count = 0;
    std::array<std::size_t, k_max_shares + 1> bounds{};
  };

  /// The shares in which the owner partition's parallel_for(n, grain) cuts [0, n): one per thread,
  /// equal to within min(grain, k_share_align), each cut into chunks of `grain` from its own start.
  /// Under the other partitions, one share (under adaptive: those of the partition in use, so a
  /// pass that keeps state cut by the shares, like the contact pass's halo, checks them every step).
  /// A pass over another index space (pairs listed by their first particle) can map these bounds
  /// into its own and run them with parallel_for_shares, so that a thread keeps the particles it
  /// integrates and the pairs of those particles on its own core.
  Shares shares(std::size_t n, std::size_t grain) const;

  /// Like parallel_for, over the shares of `shares` (ascending bounds), each cut into chunks of
  /// `grain` counted from its own first index. Under Partition::owner (or adaptive running owner)
  /// share k runs on thread k; under the others every chunk goes to the common pool. The chunk
  /// boundaries depend on the shares: a body whose result per index does not depend on where its
  /// chunk begins gives the same results whatever the shares.
  void parallel_for_shares(const Shares& shares, std::size_t grain, FunctionRef<void(std::size_t, std::size_t)> body);

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
  Partition partition_ = Partition::owner;
  VisitOrder visit_order_ = VisitOrder::adaptive;
  Partition active_ = Partition::owner;  // what parallel_for runs: partition_, or adaptive's choice
  int threads_;
  std::unique_ptr<Impl> impl_;
  // Partition::adaptive: the state of the trial (record_step).
  bool tuning_ = false;
  AdaptiveSettings adaptive_;
  PartitionSteps steps_;
  std::chrono::steady_clock::time_point step_start_{};
  bool in_trial_ = true;
  int batch_ = 0;  // trial batch 0..3: first, other, other, first partition
  Partition first_ = Partition::owner;
  std::uint32_t batch_steps_ = 0;  // steps of this batch so far (its first not timed)
  double batch_time_ = 0, trial_time_ = 0, hold_left_ = 0;
  std::array<std::vector<double>, 2> times_;  // the trial's timed steps, [first, other]
  // Runs chunk(k, c) for every chunk c < chunks[k] of every share k < t under the owner partition:
  // share k from its front on the arena's thread k when it comes to take it, the last chunks left
  // by whichever thread has run out of its own; each chunk exactly once.
  void run_owned(int t, const std::size_t* chunks, FunctionRef<void(int, std::size_t)> chunk);
};

}  // namespace sandcell
