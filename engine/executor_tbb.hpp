#pragma once
// Internal: the TBB side of the executor, for engine sources only (not installed, not for systems).
#include "engine/executor.hpp"

#include <oneapi/tbb/task_arena.h>

namespace sandcell {

struct Executor::Impl {
  tbb::task_arena arena;
  explicit Impl(int threads) : arena(threads) { arena.initialize(); }
};

}  // namespace sandcell
