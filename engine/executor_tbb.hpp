#pragma once
// Internal: the TBB side of the executor, for engine sources only (not installed, not for systems).
#include "engine/executor.hpp"

#include <oneapi/tbb/global_control.h>
#include <oneapi/tbb/info.h>
#include <oneapi/tbb/task_arena.h>

#include <memory>

namespace sandcell {

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
};

}  // namespace sandcell
