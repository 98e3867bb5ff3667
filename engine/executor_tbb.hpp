#pragma once
// Internal: the TBB side of the executor, for engine sources only (not installed, not for systems).
#include "engine/executor.hpp"

#include <oneapi/tbb/global_control.h>
#include <oneapi/tbb/info.h>
#include <oneapi/tbb/task_arena.h>
#include <oneapi/tbb/task_scheduler_observer.h>

#include <memory>
#include <vector>

namespace sandcell {

// Pins each worker thread entering the arena to one CPU of the process's affinity mask, by its
// arena slot (slot k -> the k-th allowed CPU, modulo their number). The calling (external) thread,
// slot 0, is left as it is: its affinity is the caller's business.
class PinningObserver : public tbb::task_scheduler_observer {
 public:
  PinningObserver(tbb::task_arena& arena, std::vector<int> cpus)
      : tbb::task_scheduler_observer(arena), cpus_(std::move(cpus)) {
    observe(true);
  }
  ~PinningObserver() override { observe(false); }
  void on_scheduler_entry(bool worker) override;

 private:
  std::vector<int> cpus_;
};

struct Executor::Impl {
  // TBB caps its worker pool at the hardware concurrency; an executor asking for more threads
  // (e.g. 8 on a 2-core machine, to test determinism) raises the cap while it lives.
  std::unique_ptr<tbb::global_control> limit;
  tbb::task_arena arena;
  explicit Impl(int threads)
      : limit(threads > tbb::info::default_concurrency()
                  ? std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, threads)
                  : nullptr),
        arena(threads) {
    arena.initialize();
  }
  std::unique_ptr<PinningObserver> pinning;  // Partition::owner only
};

}  // namespace sandcell
