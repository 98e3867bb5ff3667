// Executor seam: coverage of parallel_for and bitwise determinism of deterministic_reduce.
#include "engine/assert.hpp"
#include "engine/executor.hpp"
#include "support/affinity.hpp"
#include "support/scenes.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>

#include <sched.h>
#include <random>
#include <vector>

using namespace sandcell;

TEST_CASE("parallel_for visits every index exactly once, in chunks of the grain within each share") {
  // (Partition::adaptive runs as owner until its first batch ends: covered below.)
  for (Partition partition : {Partition::dynamic, Partition::fixed, Partition::owner})
    for (int threads : {1, 2, 3, 8}) {
      CAPTURE(static_cast<int>(partition));
      CAPTURE(threads);
      Executor exec({Backend::tbb, threads, partition});
      for (std::size_t n : {0u, 1u, 7u, 1000u, 4097u}) {
        const Executor::Shares shares = exec.shares(n, 64);
        // One share but under the owner partition, where there is one per thread (at most one per
        // 64 indices), ascending, on multiples of the grain (64 < k_share_align), equal to within it.
        const std::size_t expected =
            partition == Partition::owner ? std::max<std::size_t>(1, std::min<std::size_t>(threads, (n + 63) / 64)) : 1;
        CHECK(shares.count == expected);
        CHECK(shares.bounds[0] == 0);
        CHECK(shares.bounds[shares.count] == n);
        for (std::size_t k = 0; k < shares.count; ++k) {
          CHECK(shares.bounds[k] <= shares.bounds[k + 1]);
          CHECK(shares.bounds[k] % 64 == 0);
          CHECK(shares.bounds[k + 1] - shares.bounds[k] <= ((n + 63) / 64 / shares.count + 1) * 64);
        }
        std::vector<int> hits(n, 0);
        exec.parallel_for(n, 64, [&](std::size_t b, std::size_t e) {
          // A chunk is the grain, or what is left of its share.
          bool share_end = false;
          for (std::size_t k = 1; k <= shares.count; ++k) share_end |= e == shares.bounds[k];
          CHECK(b % 64 == 0);
          CHECK((e - b == 64 || share_end));
          for (std::size_t k = b; k < e; ++k) ++hits[k];
        });
        for (std::size_t k = 0; k < n; ++k) REQUIRE(hits[k] == 1);
      }
    }
}

TEST_CASE("parallel_for_shares visits every index of any ascending shares once, chunked from each share's start") {
  Executor::Shares shares;
  shares.count = 4;
  shares.bounds[0] = 0;
  shares.bounds[1] = 5;  // a share shorter than the grain
  shares.bounds[2] = 5;  // an empty share
  shares.bounds[3] = 300;
  shares.bounds[4] = 1001;
  for (Partition partition : {Partition::dynamic, Partition::fixed, Partition::owner})
    for (int threads : {1, 2, 4, 8}) {
      CAPTURE(static_cast<int>(partition));
      CAPTURE(threads);
      Executor exec({Backend::tbb, threads, partition});
      std::vector<int> hits(1001, 0);
      exec.parallel_for_shares(shares, 100, [&](std::size_t b, std::size_t e) {
        std::size_t k = 0;
        while (!(b >= shares.bounds[k] && b < shares.bounds[k + 1])) ++k;
        CHECK((b - shares.bounds[k]) % 100 == 0);
        CHECK(e == std::min(shares.bounds[k + 1], b + 100));
        for (std::size_t q = b; q < e; ++q) ++hits[q];
      });
      for (std::size_t q = 0; q < hits.size(); ++q) REQUIRE(hits[q] == 1);
    }
  Executor serial({Backend::serial, 1});
  std::size_t visited = 0;
  serial.parallel_for_shares(shares, 100, [&](std::size_t b, std::size_t e) { visited += e - b; });
  CHECK(visited == 1001);
}

TEST_CASE("owner partition: a thread done with its share finishes the tail of a share whose thread is held up") {
  // Share 0's first chunk blocks its thread until every other chunk of share 0 has run, which only
  // the owner partition's stealing from the back lets other threads do: without it the pass would
  // wait for the whole share on the held-up thread, and this test fails at the deadline. The chunks
  // stay those of the shares: each index once, each chunk at the grain from its share's start.
  for (int threads : {2, 3}) {
    CAPTURE(threads);
    Executor exec({Backend::tbb, threads, Partition::owner});
    const std::size_t n = 64 * 40;
    const Executor::Shares shares = exec.shares(n, 64);
    REQUIRE(shares.count == static_cast<std::size_t>(threads));
    const std::size_t first_chunks = (shares.bounds[1] + 63) / 64;
    REQUIRE(first_chunks > 2);
    std::vector<std::atomic<int>> hits(n);
    std::atomic<std::size_t> done_in_first{0};
    bool in_time = true;
    exec.parallel_for(n, 64, [&](std::size_t b, std::size_t e) {
      CHECK(b % 64 == 0);
      for (std::size_t q = b; q < e; ++q) hits[q].fetch_add(1);
      if (b == 0) {
        const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
        while (done_in_first.load() < first_chunks - 1 && std::chrono::steady_clock::now() < deadline)
          std::this_thread::yield();
        in_time = done_in_first.load() == first_chunks - 1;
      } else if (b < shares.bounds[1]) {
        done_in_first.fetch_add(1);
      }
    });
    CHECK(in_time);
    for (std::size_t q = 0; q < n; ++q) REQUIRE(hits[q].load() == 1);
  }
}

TEST_CASE("deterministic_reduce gives the same bits for the serial backend and 1, 2, 3, 8 threads, any partition") {
  // Values spanning 12 orders of magnitude: a sum whose rounding depends on the association order,
  // so any thread-dependent order would show in the bits.
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-6.0, 6.0);
  std::vector<double> values(100003);
  for (double& v : values) v = std::pow(10.0, u(rng)) * (u(rng) > 0 ? 1 : -1);

  auto sum_with = [&](Executor& exec) {
    return exec.deterministic_reduce(
        values.size(), 1000, 0.0,
        [&](std::size_t b, std::size_t e) {
          double s = 0.0;
          for (std::size_t k = b; k < e; ++k) s += values[k];
          return s;
        },
        [](double a, double b) { return a + b; });
  };
  Executor serial({Backend::serial, 1});
  const double reference = sum_with(serial);
  // Independent re-computation of the documented association: chunk partials folded left to right.
  const std::size_t chunk = Executor::reduce_chunk(values.size(), 1000);
  double expected = 0.0;
  for (std::size_t b = 0; b < values.size(); b += chunk) {
    double s = 0.0;
    for (std::size_t k = b; k < std::min(values.size(), b + chunk); ++k) s += values[k];
    expected += s;
  }
  CHECK(std::memcmp(&reference, &expected, sizeof(double)) == 0);
  for (Partition partition : {Partition::dynamic, Partition::fixed, Partition::owner})
    for (int threads : {1, 2, 3, 8}) {
      Executor exec({Backend::tbb, threads, partition});
      for (int repeat = 0; repeat < 5; ++repeat) {
        const double s = sum_with(exec);
        CHECK(std::memcmp(&s, &reference, sizeof(double)) == 0);
      }
    }
}

namespace {
// Feeds `steps` step durations to exec (owner's or dynamic's, by the partition in use, the n-th
// step of dynamic `spike` seconds instead when n is spike_at) and returns the partitions in use, one
// letter per step: o owner, d dynamic.
std::string feed(Executor& exec, int steps, double owner_s, double dynamic_s, int spike_at = -1, double spike = 0) {
  std::string used;
  int dynamic_steps = 0;
  for (int k = 0; k < steps; ++k) {
    const bool owner = exec.active_partition() == Partition::owner;
    used += owner ? 'o' : 'd';
    exec.record_step(owner ? owner_s : (dynamic_steps++ == spike_at ? spike : dynamic_s));
  }
  return used;
}
}  // namespace

TEST_CASE("partition names: each partition's name gives it back, and nothing else is a name") {
  for (const Partition p : {Partition::owner, Partition::dynamic, Partition::fixed, Partition::adaptive}) {
    CAPTURE(partition_name(p));
    CHECK(partition_from_name(partition_name(p)) == p);
  }
  CHECK(partition_name(Partition::adaptive) == "adaptive");
  for (const char* bad : {"", "static", "Owner", "owner ", "serial"}) CHECK(!partition_from_name(bad));
}

TEST_CASE("adaptive partition: a trial runs owner, dynamic, dynamic, owner, then holds the faster by median") {
  // Batches of 3 steps (the first of each not timed), no time floor; the hold is 2x the trial.
  // Durations are powers of two (ms and 2 ms, about), so that the hold's countdown is exact.
  const AdaptiveSettings fast{0.0, 3, 2.0};
  const double ms = 0x1p-10, two_ms = 0x1p-9;
  SUBCASE("dynamic faster: held for 2x the trial, and the next trial starts from it") {
    Executor exec({Backend::tbb, 2, Partition::adaptive, fast});
    CHECK(exec.partition() == Partition::adaptive);
    // The trial: 6 owner steps of 2 ms and 6 dynamic of 1 ms, 18 ms; the hold 36 ms = 36 dynamic
    // steps; the next trial: dynamic, owner, owner, dynamic, 3 steps each; then dynamic again.
    const std::string used = feed(exec, 12 + 36 + 12 + 2, two_ms, ms);
    CHECK(used == "oooddddddooo" + std::string(36, 'd') + "dddooooooddd" + "dd");
    const PartitionSteps& st = exec.partition_steps();
    CHECK(st.trials == 2);
    CHECK(st.owner == 12);
    CHECK(st.dynamic == 62 - 12);
    CHECK(st.switches == 5);  // first trial: to dynamic, back to owner, to dynamic (held); second
                              // trial: to owner and back to dynamic (held: no switch)
  }
  SUBCASE("one slow step does not decide: the median, not the mean") {
    Executor exec({Backend::tbb, 2, Partition::adaptive, fast});
    // Dynamic's second step (timed) takes 1 s: its mean over the trial would lose to owner's
    // 2 ms, its median (1 ms) wins.
    const std::string used = feed(exec, 14, two_ms, ms, 1, 1.0);
    CHECK(used == "oooddddddooodd");
  }
  SUBCASE("owner faster, or a tie: owner kept, no switch after the trial") {
    for (const double dynamic_s : {2 * two_ms, two_ms}) {
      Executor exec({Backend::tbb, 2, Partition::adaptive, fast});
      const std::string used = feed(exec, 14, two_ms, dynamic_s);
      CHECK(used == "oooddddddooooo");
      CHECK(exec.partition_steps().switches == 2);
    }
  }
  SUBCASE("parallel_for follows the partition in use: one share per thread under owner, one under dynamic") {
    Executor exec({Backend::tbb, 2, Partition::adaptive, fast});
    CHECK(exec.shares(4096, 64).count == 2);
    feed(exec, 3, two_ms, ms);
    REQUIRE(exec.active_partition() == Partition::dynamic);
    CHECK(exec.shares(4096, 64).count == 1);
    std::vector<int> hits(4096, 0);
    exec.parallel_for(4096, 64, [&](std::size_t b, std::size_t e) {
      for (std::size_t k = b; k < e; ++k) ++hits[k];
    });
    CHECK(std::count(hits.begin(), hits.end(), 1) == 4096);
  }
  SUBCASE("settings out of range are refused, naming the setting and the value") {
    const AssertHandler previous = set_assert_handler(&test::throwing_assert_handler);
    for (const AdaptiveSettings bad : {AdaptiveSettings{-1.0, 16, 30.0}, AdaptiveSettings{0.02, 1, 30.0},
                                       AdaptiveSettings{0.02, 16, 0.0}, AdaptiveSettings{0.02, 16, NAN}}) {
      CAPTURE(bad.batch_seconds);
      CHECK_THROWS_WITH_AS(Executor({Backend::tbb, 2, Partition::adaptive, bad}), doctest::Contains("adaptive."),
                           test::AssertionError);
    }
    CHECK_NOTHROW(Executor({Backend::tbb, 2, Partition::owner, AdaptiveSettings{-1.0, 0, 0.0}}));  // unused
    set_assert_handler(previous);
  }
  SUBCASE("one thread or the serial backend: no trial, owner") {
    for (const ExecutorConfig cfg : {ExecutorConfig{Backend::tbb, 1, Partition::adaptive, fast},
                                     ExecutorConfig{Backend::serial, 4, Partition::adaptive, fast}}) {
      Executor exec(cfg);
      CHECK(feed(exec, 20, two_ms, ms) == std::string(20, 'o'));
      CHECK(exec.partition_steps().trials == 0);
      CHECK(exec.partition_steps().owner == 0);
    }
  }
}

TEST_CASE("executor reports its thread count") {
  CHECK(Executor({Backend::serial, 8}).threads() == 1);
  CHECK(Executor({Backend::tbb, 3}).threads() == 3);
  CHECK(Executor({Backend::tbb, 0}).threads() >= 1);
}

TEST_CASE("available_cpus follows the affinity mask, and SLURM_CPUS_PER_TASK inside a Slurm job") {
  // The count is what a scheduler grants, not what the machine has: under `taskset -c K` (one CPU)
  // a default executor must run one thread.
  int before = 0;
  {
    test::OneCpu one;
    REQUIRE(one.ok());
    before = one.cpus_before();
    CHECK(available_cpus() == 1);
    CHECK(Executor({Backend::tbb, 0}).threads() == 1);
    ::setenv("SLURM_CPUS_PER_TASK", "3", 1);
    CHECK(available_cpus() == 3);  // the allocation's own count wins inside a job
    ::setenv("SLURM_CPUS_PER_TASK", "bogus", 1);
    CHECK(available_cpus() == 1);  // not a positive integer: ignored
  }
  CHECK(available_cpus() == before);  // the whole mask again
}
