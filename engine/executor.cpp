#include "engine/executor.hpp"

#include "engine/assert.hpp"
#include "engine/build_arch.hpp"
#include "engine/executor_tbb.hpp"

#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/info.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/partitioner.h>

#include <string>

namespace sandcell {

Executor::Executor(ExecutorConfig config) : backend_(config.backend) {
  // Every world has an executor: this reference links engine/cpu_guard.cpp into every program, and
  // with it the startup check that stops a build for a newer CPU with a message (build_arch.hpp).
  static_cast<void>(build_arch());
  SANDCELL_CHECK(config.threads >= 0, "threads must be >= 0 (0 = all hardware threads), got " +
                                          std::to_string(config.threads));
  if (backend_ == Backend::serial) {
    threads_ = 1;
    return;
  }
  threads_ = config.threads > 0 ? config.threads : tbb::info::default_concurrency();
  impl_ = std::make_unique<Impl>(threads_);
}

Executor::~Executor() = default;

void Executor::parallel_for(std::size_t n, std::size_t grain,
                            FunctionRef<void(std::size_t, std::size_t)> body) {
  grain = std::max<std::size_t>(grain, 1);
  const std::size_t chunks = (n + grain - 1) / grain;
  if (chunks == 0) return;
  if (backend_ == Backend::serial || chunks == 1) {
    for (std::size_t c = 0; c < chunks; ++c) body(c * grain, std::min(n, (c + 1) * grain));
    return;
  }
  impl_->arena.execute([&] {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, chunks, 1),
        [&](const tbb::blocked_range<std::size_t>& r) {
          for (std::size_t c = r.begin(); c < r.end(); ++c) body(c * grain, std::min(n, (c + 1) * grain));
        },
        tbb::simple_partitioner());
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
