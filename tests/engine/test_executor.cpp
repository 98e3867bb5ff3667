// Executor seam: coverage of parallel_for and bitwise determinism of deterministic_reduce.
#include "engine/executor.hpp"
#include "support/affinity.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string>

#include <sched.h>
#include <random>
#include <vector>

using namespace sandcell;

TEST_CASE("parallel_for visits every index exactly once, in chunks fixed by n and grain") {
  for (Partition partition : {Partition::dynamic, Partition::fixed, Partition::owner})
    for (int threads : {1, 2, 3, 8}) {
      CAPTURE(static_cast<int>(partition));
      Executor exec({Backend::tbb, threads, partition});
      for (std::size_t n : {0u, 1u, 7u, 1000u, 4097u}) {
        std::vector<int> hits(n, 0);
        exec.parallel_for(n, 64, [&](std::size_t b, std::size_t e) {
          // Chunk boundaries are multiples of the grain, whatever the thread count.
          CHECK(b % 64 == 0);
          CHECK((e == n || e - b == 64));
          for (std::size_t k = b; k < e; ++k) ++hits[k];
        });
        for (std::size_t k = 0; k < n; ++k) REQUIRE(hits[k] == 1);
      }
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
