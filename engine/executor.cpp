#include "engine/executor.hpp"

#include "engine/assert.hpp"
#include "engine/build_arch.hpp"
#include "engine/executor_tbb.hpp"

#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/info.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/partitioner.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string>
#include <thread>

#ifdef __linux__
#include <sched.h>
#endif

namespace sandcell {

Executor::Executor(ExecutorConfig config)
    : backend_(config.backend),
      partition_(config.partition),
      visit_order_(config.visit_order),
      active_(config.partition == Partition::adaptive ? Partition::owner : config.partition),
      adaptive_(config.adaptive) {
  // Every world has an executor: this reference links engine/cpu_guard.cpp into every program, and
  // with it the startup check that stops a build for a newer CPU with a message (build_arch.hpp).
  static_cast<void>(build_arch());
  SANDCELL_CHECK(config.threads >= 0,
                 "threads must be >= 0 (0 = all hardware threads), got " + std::to_string(config.threads));
  if (config.partition == Partition::adaptive) {
    const AdaptiveSettings& a = config.adaptive;
    SANDCELL_CHECK(std::isfinite(a.batch_seconds) && a.batch_seconds >= 0,
                   "adaptive.batch_seconds must be finite and >= 0, got " + std::to_string(a.batch_seconds));
    SANDCELL_CHECK(a.batch_steps >= 2,
                   "adaptive.batch_steps must be >= 2 (the first step of a batch is not timed), got " +
                       std::to_string(a.batch_steps));
    SANDCELL_CHECK(std::isfinite(a.hold) && a.hold > 0,
                   "adaptive.hold must be finite and > 0, got " + std::to_string(a.hold));
  }
  if (backend_ == Backend::serial) {
    threads_ = 1;
    return;
  }
  threads_ = config.threads > 0 ? config.threads : available_cpus();
  impl_ = std::make_unique<Impl>(threads_);
  tuning_ = partition_ == Partition::adaptive && threads_ > 1;
  // The trial's step times, kept between trials (clear() keeps the capacity): no allocation in the
  // step loop unless a partition's two batches exceed this many steps (20 ms batches of steps
  // shorter than 0.08 ms).
  if (tuning_)
    for (auto& t : times_) t.reserve(512);
}

void Executor::record_step(double seconds) {
  if (!tuning_) return;
  const auto other = [](Partition p) { return p == Partition::owner ? Partition::dynamic : Partition::owner; };
  (active_ == Partition::owner ? steps_.owner : steps_.dynamic) += 1;
  const Partition before = active_;
  if (!in_trial_) {
    hold_left_ -= seconds;
    if (hold_left_ <= 0) {  // a new trial, starting with the partition in use (no switch)
      in_trial_ = true;
      batch_ = 0;
      first_ = active_;
      batch_steps_ = 0;
      batch_time_ = trial_time_ = 0;
      for (auto& t : times_) t.clear();
    }
    return;
  }
  trial_time_ += seconds;
  if (batch_steps_++ > 0) {  // the batch's first step is not counted
    times_[batch_ == 0 || batch_ == 3 ? 0 : 1].push_back(seconds);
    batch_time_ += seconds;
  }
  if (batch_steps_ < adaptive_.batch_steps || batch_time_ < adaptive_.batch_seconds) return;
  batch_steps_ = 0;
  batch_time_ = 0;
  if (++batch_ < 4) {
    active_ = batch_ == 3 ? first_ : other(first_);
  } else {
    // The faster by median step time; the one in use before the trial on a tie.
    const auto median = [](std::vector<double>& t) {
      std::nth_element(t.begin(), t.begin() + static_cast<std::ptrdiff_t>(t.size() / 2), t.end());
      return t[t.size() / 2];
    };
    active_ = median(times_[1]) < median(times_[0]) ? other(first_) : first_;
    in_trial_ = false;
    hold_left_ = adaptive_.hold * trial_time_;
    steps_.trials += 1;
  }
  if (active_ != before) steps_.switches += 1;
}

Executor::~Executor() = default;

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
  if (active_ == Partition::owner) {
    parallel_for_shares(shares(n, grain), grain, body);
    return;
  }
  impl_->arena.execute([&] {
    if (active_ == Partition::fixed)
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunks, 1), run, tbb::static_partitioner());
    else
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, chunks, 1), run, tbb::simple_partitioner());
  });
}

Executor::Shares Executor::shares(std::size_t n, std::size_t grain) const {
  const std::size_t align = std::clamp<std::size_t>(grain, 1, k_share_align);
  const std::size_t units = (n + align - 1) / align;
  Shares out;
  out.count = active_ == Partition::owner
                  ? std::max<std::size_t>(1, std::min({static_cast<std::size_t>(threads_), units, k_max_shares}))
                  : 1;
  for (std::size_t k = 0; k < out.count; ++k) out.bounds[k] = std::min(n, units * k / out.count * align);
  out.bounds[out.count] = n;
  return out;
}

namespace {

// A share's chunks not yet claimed: [front, back), both in one word so that the owner (from the
// front) and a thief (from the back) claim with one compare-exchange and never the same chunk.
// One cache line each: the owner claims every chunk of its own share, the others only read it
// until they run out of work.
struct alignas(64) ShareClaims {
  std::uint64_t word;  // not initialized: run_owned stores the shares it uses (no 16 KB cleared per pass)
  static constexpr std::uint64_t pack(std::uint32_t front, std::uint32_t back) {
    return std::uint64_t{back} << 32 | front;
  }
  static constexpr std::uint32_t front_of(std::uint64_t r) { return static_cast<std::uint32_t>(r); }
  static constexpr std::uint32_t back_of(std::uint64_t r) { return static_cast<std::uint32_t>(r >> 32); }
  std::atomic_ref<std::uint64_t> range() { return std::atomic_ref<std::uint64_t>(word); }
  // Claims the first (front) or last (back) chunk left; -1 when none is left.
  std::int64_t claim(bool from_front) {
    std::uint64_t r = range().load(std::memory_order_relaxed);
    for (;;) {
      const std::uint32_t front = front_of(r), back = back_of(r);
      if (front >= back) return -1;
      const std::uint64_t next = from_front ? pack(front + 1, back) : pack(front, back - 1);
      if (range().compare_exchange_weak(r, next, std::memory_order_relaxed)) return from_front ? front : back - 1;
    }
  }
  std::uint32_t left() {
    const std::uint64_t r = range().load(std::memory_order_relaxed);
    return front_of(r) < back_of(r) ? back_of(r) - front_of(r) : 0;
  }
};

}  // namespace

void Executor::run_owned(int t, const std::size_t* chunks, FunctionRef<void(int, std::size_t)> chunk) {
  // A task takes its own thread's share if no one has, else the first share left, and runs its
  // chunks from the front; then, while any share has chunks left, it claims the last chunk of the
  // share with the most left. A thread keeps its own particles and pairs every pass, and a thread
  // that starts late (a worker slow to wake, a vCPU the host took away) or a share heavier than the
  // others no longer holds the whole pass back: the others finish its tail. Every chunk runs once,
  // whoever runs it, with the same bounds: the results are the same.
  std::array<std::atomic<bool>, k_max_shares> taken{};
  std::array<ShareClaims, k_max_shares> claims;
  for (int k = 0; k < t; ++k)
    claims[static_cast<std::size_t>(k)].word = ShareClaims::pack(0, static_cast<std::uint32_t>(chunks[k]));
  impl_->arena.execute([&] {
    tbb::parallel_for(
        0, t,
        [&](int) {
          const int me = tbb::this_task_arena::current_thread_index();
          int own = -1;
          if (me >= 0 && me < t && !taken[static_cast<std::size_t>(me)].exchange(true))
            own = me;
          else
            for (int k = 0; k < t && own < 0; ++k)
              if (!taken[static_cast<std::size_t>(k)].exchange(true)) own = k;
          if (own >= 0)
            for (std::int64_t c; (c = claims[static_cast<std::size_t>(own)].claim(true)) >= 0;)
              chunk(own, static_cast<std::size_t>(c));
          for (;;) {
            int victim = -1;
            std::uint32_t most = 0;
            for (int k = 0; k < t; ++k)
              if (const std::uint32_t left = claims[static_cast<std::size_t>(k)].left(); left > most) {
                most = left;
                victim = k;
              }
            if (victim < 0) return;
            if (const std::int64_t c = claims[static_cast<std::size_t>(victim)].claim(false); c >= 0)
              chunk(victim, static_cast<std::size_t>(c));
          }
        },
        tbb::static_partitioner());
  });
}

void Executor::parallel_for_shares(const Shares& cut, std::size_t grain,
                                   FunctionRef<void(std::size_t, std::size_t)> body) {
  grain = std::max<std::size_t>(grain, 1);
  SANDCELL_ASSERT(cut.count >= 1 && cut.count <= k_max_shares, "parallel_for_shares: bad share count");
  const auto chunks_of = [&](std::size_t k) { return (cut.bounds[k + 1] - cut.bounds[k] + grain - 1) / grain; };
  if (active_ == Partition::owner && backend_ != Backend::serial && cut.count > 1) {
    std::array<std::size_t, k_max_shares> chunks;
    for (std::size_t k = 0; k < cut.count; ++k) chunks[k] = chunks_of(k);
    run_owned(static_cast<int>(cut.count), chunks.data(), [&](int k, std::size_t c) {
      const std::size_t b = cut.bounds[static_cast<std::size_t>(k)] + c * grain;
      body(b, std::min(cut.bounds[static_cast<std::size_t>(k) + 1], b + grain));
    });
    return;
  }
  // One pool of chunks: chunk c of the list is the c-th chunk counting share by share.
  std::array<std::size_t, k_max_shares + 1> first{};  // first chunk of each share
  for (std::size_t k = 0; k < cut.count; ++k) first[k + 1] = first[k] + chunks_of(k);
  const std::size_t chunks = first[cut.count];
  const auto run_chunk = [&](std::size_t c) {
    const std::size_t k =
        static_cast<std::size_t>(std::upper_bound(first.begin(), first.begin() + cut.count + 1, c) - first.begin()) - 1;
    const std::size_t b = cut.bounds[k] + (c - first[k]) * grain;
    body(b, std::min(cut.bounds[k + 1], b + grain));
  };
  if (backend_ == Backend::serial || chunks <= 1) {
    for (std::size_t c = 0; c < chunks; ++c) run_chunk(c);
    return;
  }
  impl_->arena.execute([&] {
    const auto run = [&](const tbb::blocked_range<std::size_t>& r) {
      for (std::size_t c = r.begin(); c < r.end(); ++c) run_chunk(c);
    };
    if (active_ == Partition::fixed)
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
