// dem-bench: throughput and physics check on fixed scenes, with the settings the established codes
// ran (apps/dem-bench/scenes/: the scenes and the settings, docs/performance.md: the figures).
//
//   dem-bench [--scene FILE] [--tile K] [--steps N] [--threads T] [--deform RATE] [--shear RATE] [--rolling MODEL]
//             [--tangential MODEL] [--compat] [--sort STEPS] [--skin M] [--serial] [--json]
// --sort STEPS: spatial sort interval (default 1000; 0 = never).
//
//   dem-bench --costs [--scene FILE] [--steps N] [--threads T] [--rounds R]
// The cost of each optional system: the benchmark scene stepped with one option changed at a time
// (no rolling, LIGGGHTS-compatible velocities, incremental tangential history, the servo with its
// homogenizer, the servo with the kinetic stress), R rounds interleaved so that machine noise
// falls on every variant alike; prints the median throughput of each and its ratio to the default.
//
//   dem-bench --scaling [--scene FILE] [--steps N] [--threads T] [--rounds R] [--deform RATE] [--partition P] [--probe] [--json]
// Thread scaling from 1 to T threads (default: all hardware threads): a 1-thread and a T-thread
// world of the same scene advanced alternately, N steps at a time, R times; prints the median
// throughput of each, the median of the R ratios, two references measured in the same rounds (T
// independent 1-thread worlds at once, and a streaming pass on both executors), and whether all
// the worlds' final states are bitwise equal (exit 1 if not).
//
// Scene A: fixed periodic box. Scene B (--deform RATE): box shortened along z at a constant
// engineering strain rate RATE (1/s), x and y fixed, as LIGGGHTS `fix deform ... erate -RATE`.
// A shearing cell (--shear RATE): simple shear, L_xz = RATE (1/s, the tilt xz growing as LAMMPS's
// `fix deform ... xz erate RATE`, flipped past half a length): from the first step every pass takes
// its tilted-cell form, so its cost beside scene A or B is the cost of a tilted cell.
// Prints particles, steps, threads, wall seconds of the step loop, particle-steps per second, mean
// contacts per particle, neighbour-list builds, peak memory, the final contact stress tensor, and
// the share of the step loop spent in each system (the engine's own timers), and a digest of the
// final state (FNV-1a over the bytes of ids, positions, velocities, spins, contact histories and the
// cell): equal digests mean bitwise equal runs, across thread counts, machines or versions.
#include "engine/build_arch.hpp"
#include "engine/fnv1a.hpp"
#include "engine/packing.hpp"
#include "engine/world.hpp"
#include "systems/contact_pass.hpp"
#include "systems/broadphase.hpp"
#include "systems/catalogue.hpp"
#include "systems/force_gather.hpp"
#include "systems/homogenizer.hpp"
#include "systems/stress.hpp"

#include "probe.hpp"

#include <CLI/CLI.hpp>

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <memory>
#include <optional>
#include <thread>
#include <vector>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <string_view>

#ifndef SANDCELL_BENCH_SCENE_DIR
#define SANDCELL_BENCH_SCENE_DIR "."
#endif

using namespace sandcell;

namespace {
[[noreturn]] void usage_error(const std::string& message) {
  std::fprintf(stderr, "dem-bench: %s\n", message.c_str());
  std::exit(2);
}

// FNV-1a (engine/fnv1a.hpp) over the raw bytes of the state arrays in array order.
std::uint64_t state_digest(const State& s) {
  Fnv1a f;
  f.array(s.particles.id);
  f.array(s.particles.position);
  f.array(s.particles.velocity);
  f.array(s.particles.angular_velocity);
  f.array(s.contacts.pairs.id_i);
  f.array(s.contacts.pairs.id_j);
  f.array(s.contacts.tangential);
  f.array(s.contacts.rolling);
  f.bytes(s.cell.length.data(), sizeof(double) * 3);
  if (!s.cell.plain()) {  // a shearing cell's tilts and flips too (an orthorhombic digest is unchanged)
    f.bytes(s.cell.tilt.data(), sizeof(double) * 3);
    f.bytes(s.cell.flip.data(), sizeof(double) * 3);
  }
  return f.h;
}

// How the scene's cell moves: scene B's engineering rate (z), simple shear (L_xz).
struct Drive {
  double deform = 0.0;  // 1/s
  double shear = 0.0;   // 1/s
};

// Steps the scene: scene B (deform > 0) shortens z at the engineering rate RATE: L_z(t) =
// L_z0 (1 - RATE t), so D_zz = dL_z/dt / L_z = -RATE L_z0 / L_z, set before each step from the
// current length. One step_until call for all the steps (World::step_until).
void advance(World& world, long steps, const Drive& drive, double lz0) {
  const double deform = drive.deform;
  if (drive.shear != 0.0) world.state().cell.shear_rate = Vec3(0.0, drive.shear, 0.0);
  const auto set_rate = [&](Cell& cell) {
    if (deform > 0.0) cell.rate = Vec3(0.0, 0.0, -deform * lz0 / cell.length[2]);
  };
  set_rate(world.state().cell);
  world.step_until(static_cast<std::uint64_t>(steps), [&](Cell& cell, const Clock&) {
    set_rate(cell);
    return false;
  });
}

double median(std::vector<double> x) {
  std::sort(x.begin(), x.end());
  return x.size() % 2 ? x[x.size() / 2] : 0.5 * (x[x.size() / 2 - 1] + x[x.size() / 2]);
}

// The q-quantile (0 <= q <= 1) by linear interpolation between order statistics (numpy's default):
// a noisy machine is described by its p10 and p90 next to the median, not by its best round.
double quantile(std::vector<double> x, double q) {
  std::sort(x.begin(), x.end());
  const double pos = q * double(x.size() - 1);
  const std::size_t lo = static_cast<std::size_t>(pos);
  const std::size_t hi = std::min(lo + 1, x.size() - 1);
  return x[lo] + (pos - double(lo)) * (x[hi] - x[lo]);
}

// The machine's own 1 -> T scaling for a pass that streams through the shared cache, as the
// integrator and the gather do: y += a x over two arrays of 4 MiB (8 MiB in all, about twice what
// the integrator's pass moves on dense-20k, and four times one core's L2), `passes` times on
// `exec`. Returns element updates per second; only the ratio of two such rates is used.
double stream_rate(Executor& exec, std::vector<double>& x, std::vector<double>& y, int passes) {
  double* __restrict px = x.data();
  double* __restrict py = y.data();
  const auto t0 = std::chrono::steady_clock::now();
  for (int p = 0; p < passes; ++p)
    exec.parallel_for(x.size(), 8192, [&](std::size_t b, std::size_t e) {
      for (std::size_t k = b; k < e; ++k) py[k] += 1e-9 * px[k];
    });
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return double(x.size()) * passes / wall;
}

// --scaling: two worlds of the same scene, one on 1 thread and one on T, advanced alternately by
// blocks of `steps` steps, `rounds` times. Each pair of blocks runs seconds apart, on the same
// stretch of the trajectory (the two worlds stay bitwise equal), so the per-round ratios see the
// machine in the same state; the median of them is the scaling figure. Each round also times two
// references of what the machine allows at that moment:
// - the streaming pass above on both executors. When its ratio is itself well below T, the
//   machine limits every pass that streams at that moment; when it is near T and the engine's is
//   lower, the gap is the engine's;
// - T more 1-thread worlds of the same scene, stepped at once from T threads of their own (the
//   same workload sharing nothing: a sweep of runs launched as separate jobs). Their throughput
//   over the 1-thread world's is the practical ceiling of the T-thread world on this machine at
//   that moment: it pays the machine's contention between busy cores (shared cache, memory, power,
//   other tenants) but nothing of the engine's (synchronization, imbalance, data written by one
//   core and read by another). The two ratios' difference is what sharing one world costs.
//   Each of these worlds steps the same trajectory as the others, so they end bitwise equal to
//   the 1-thread world (checked).
// It also prints the engine's per-system timers of the 1- and T-thread worlds summed over the
// rounds: which pass loses what, measured in the same rounds.
int run_scaling(const Model& model, const Packing& packing, long steps, int threads, int rounds, const Drive& drive,
                bool json, bool probe, Partition partition) {
  const double deform = drive.deform;
  // T = 0: all hardware threads, as the executor counts them (TBB's default concurrency).
  World many(model, make_state(model, packing), systems_for(model), ExecutorConfig{Backend::tbb, threads, partition});
  threads = many.executor().threads();
  if (threads < 2) usage_error("--scaling needs --threads T >= 2 (got " + std::to_string(threads) + ")");
  World one(model, make_state(model, packing), systems_for(model), ExecutorConfig{Backend::tbb, 1});
  const double lz0 = one.state().cell.length[2];
  const double n = double(one.state().particles.size());
  std::vector<double> rate_one, rate_many, ratio;
  // Particle-steps per second of `worlds` worlds advanced by one block in `run`.
  const auto rate = [&](std::size_t worlds, auto&& run) {
    const auto t0 = std::chrono::steady_clock::now();
    run();
    return double(worlds) * n * double(steps) /
           std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  const auto timed = [&](World& w) { return rate(1, [&] { advance(w, steps, drive, lz0); }); };
  std::vector<std::unique_ptr<World>> jobs;
  for (int t = 0; t < threads; ++t)
    jobs.push_back(std::make_unique<World>(model, make_state(model, packing), systems_for(model),
                                           ExecutorConfig{Backend::tbb, 1}));
  std::vector<double> jobs_ratio;
  const auto timed_jobs = [&] {
    return rate(jobs.size(), [&] {
      std::vector<std::thread> run;
      for (auto& w : jobs) run.emplace_back([&, world = w.get()] { advance(*world, steps, drive, lz0); });
      for (auto& t : run) t.join();
    });
  };
  std::vector<double> sx(std::size_t{1} << 19, 1.0), sy(std::size_t{1} << 19, 0.0), stream_ratio;
  constexpr int k_stream_passes = 400;  // ~0.1 s per executor per round at ~40 GB/s
  // What the machine allowed in each round, measured without the engine (probe.hpp).
  std::vector<double> alu_ratio, pingpong, steal, foreign;
  for (int r = 0; r < rounds; ++r) {
    const bench::CpuAccount account;
    rate_one.push_back(timed(one));
    rate_many.push_back(timed(many));
    ratio.push_back(rate_many.back() / rate_one.back());
    jobs_ratio.push_back(timed_jobs() / rate_one.back());
    const double s1 = stream_rate(one.executor(), sx, sy, k_stream_passes);
    stream_ratio.push_back(stream_rate(many.executor(), sx, sy, k_stream_passes) / s1);
    if (probe) {
      const double a1 = bench::alu_rate(1, 0.1);
      alu_ratio.push_back(bench::alu_rate(threads, 0.1) / a1);
      pingpong.push_back(bench::pingpong_ns(3));
      steal.push_back(account.steal_fraction());
      foreign.push_back(account.foreign_cpus());
    }
  }
  const std::uint64_t digest = state_digest(one.state());
  bool same = state_digest(many.state()) == digest;
  for (const auto& w : jobs) same = same && state_digest(w->state()) == digest;
  if (json) {
    std::printf(
        "{\"particles\": %.0f, \"steps_per_round\": %ld, \"rounds\": %d, \"threads\": %d, \"deform\": %.9g, "
        "\"median_one\": %.6g, \"median_many\": %.6g, \"median_ratio\": %.6g, \"ratios\": [",
        n, steps, rounds, threads, deform, median(rate_one), median(rate_many), median(ratio));
    for (std::size_t k = 0; k < ratio.size(); ++k) std::printf("%s%.6g", k ? ", " : "", ratio[k]);
    std::printf(
        "], \"p10_one\": %.6g, \"p90_one\": %.6g, \"p10_many\": %.6g, \"p90_many\": %.6g, \"p10_ratio\": %.6g, "
        "\"p90_ratio\": %.6g, \"p10_many_over_median_one\": %.6g",
        quantile(rate_one, 0.1), quantile(rate_one, 0.9), quantile(rate_many, 0.1), quantile(rate_many, 0.9),
        quantile(ratio, 0.1), quantile(ratio, 0.9), quantile(rate_many, 0.1) / median(rate_one));
    std::printf(", \"jobs_median_ratio\": %.6g, \"stream_median_ratio\": %.6g", median(jobs_ratio),
                median(stream_ratio));
    // Every round's figures side by side (--probe adds the machine's, probe.hpp).
    std::printf(", \"rounds_detail\": [");
    for (std::size_t k = 0; k < ratio.size(); ++k) {
      std::printf("%s{\"one\": %.6g, \"many\": %.6g, \"jobs_ratio\": %.6g, \"stream_ratio\": %.6g", k ? ", " : "",
                  rate_one[k], rate_many[k], jobs_ratio[k], stream_ratio[k]);
      if (probe)
        std::printf(", \"alu_ratio\": %.6g, \"pingpong_ns\": %.6g, \"steal\": %.6g, \"foreign_cpus\": %.6g",
                    alu_ratio[k], pingpong[k], steal[k], foreign[k]);
      std::printf("}");
    }
    std::printf("], \"systems\": {");
    for (std::size_t k = 0; k < one.graph().size(); ++k)
      std::printf("%s\"%s\": [%.6f, %.6f]", k ? ", " : "", one.graph().system(k).name.c_str(), one.graph().timers()[k],
                  many.graph().timers()[k]);
    std::printf("}, \"digests_equal\": %s}\n", same ? "true" : "false");
  } else {
    std::printf("thread scaling: %.0f particles, %ld steps x %d rounds, 1 and %d threads alternating%s\n", n, steps,
                rounds, threads, deform > 0.0 ? " (scene B)" : "");
    std::printf("  1 thread    p10 / median / p90 %8.3f / %8.3f / %8.3f M particle-steps/s\n",
                quantile(rate_one, 0.1) / 1e6, median(rate_one) / 1e6, quantile(rate_one, 0.9) / 1e6);
    std::printf("  %d threads   p10 / median / p90 %8.3f / %8.3f / %8.3f M particle-steps/s\n", threads,
                quantile(rate_many, 0.1) / 1e6, median(rate_many) / 1e6, quantile(rate_many, 0.9) / 1e6);
    std::printf("  %d-thread p10 / 1-thread median %.3f\n", threads, quantile(rate_many, 0.1) / median(rate_one));
    std::printf("  ratio       p10 / median / p90 of the rounds' ratios %.3f / %.3f / %.3f (", quantile(ratio, 0.1),
                median(ratio), quantile(ratio, 0.9));
    for (std::size_t k = 0; k < ratio.size(); ++k) std::printf("%s%.3f", k ? ", " : "", ratio[k]);
    std::printf(")\n  jobs        %d 1-thread worlds at once, against 1 alone, in the same rounds: median ratio %.3f\n",
                threads, median(jobs_ratio));
    std::printf("  machine     y += a x over 2 x 4 MiB, 1 -> %d threads in the same rounds: median ratio %.3f\n",
                threads, median(stream_ratio));
    if (probe) {
      std::printf(
          "  rounds      1-thread, %d-thread M/s, ratio; without the engine: %d worlds at once, streaming, "
          "register-only (ratios); ping-pong ns; steal; other processes (CPUs)\n",
          threads, threads);
      for (std::size_t k = 0; k < ratio.size(); ++k)
        std::printf("    %3zu  %7.3f %7.3f %5.2f   %5.2f %5.2f %5.2f   %7.1f  %5.3f  %5.2f\n", k + 1, rate_one[k] / 1e6,
                    rate_many[k] / 1e6, ratio[k], jobs_ratio[k], stream_ratio[k], alu_ratio[k], pingpong[k], steal[k],
                    foreign[k]);
    }
    std::printf("  per system  seconds over all rounds, 1 -> %d threads (ratio):\n", threads);
    for (std::size_t k = 0; k < one.graph().size(); ++k) {
      const double a = one.graph().timers()[k], b = many.graph().timers()[k];
      std::printf("    %-18s %8.3f -> %8.3f s", one.graph().system(k).name.c_str(), a, b);
      if (b > 0.0 && a >= 0.01) std::printf("  (%.2f)", a / b);
      std::printf("\n");
    }
    std::printf("  final states bitwise equal (all %d worlds): %s\n", threads + 2, same ? "yes" : "NO");
  }
  return same ? 0 : 1;
}

// One variant of the benchmark model for --costs.
struct Variant {
  const char* name;
  std::function<void(Model&)> change;
};

int run_costs(const Model& base, const Packing& packing, long steps, int threads, int rounds) {
  const auto servo = [](Model& m, bool kinetic) {
    m.servo.enabled = true;  // every axis strain-controlled at rate 0: the cost of measuring, no motion
    m.servo.path = StressPath::fixed;
    m.servo.gain = 1.0;
    m.servo.max_rate = 1.0;
    m.servo.kinetic_stress = kinetic;
  };
  const std::vector<Variant> variants = {
      {"default (epsd2, history, affine)", [](Model&) {}},
      {"rolling none", [](Model& m) { m.contact.rolling = RollingModel::none; }},
      {"liggghts_compat on", [](Model& m) { m.contact.liggghts_compat = true; }},
      {"tangential incremental", [](Model& m) { m.contact.tangential = TangentialModel::incremental; }},
      {"servo + homogenizer", [&](Model& m) { servo(m, false); }},
      {"servo + kinetic stress", [&](Model& m) { servo(m, true); }},
  };
  std::vector<std::vector<double>> rates(variants.size());
  for (int r = 0; r < rounds; ++r)
    for (std::size_t v = 0; v < variants.size(); ++v) {
      Model model = base;
      variants[v].change(model);
      World world(model, make_state(model, packing), systems_for(model), ExecutorConfig{Backend::tbb, threads});
      const auto t0 = std::chrono::steady_clock::now();
      world.step(static_cast<std::uint64_t>(steps));
      const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      rates[v].push_back(double(world.state().particles.size()) * double(steps) / wall);
    }
  std::printf("cost of optional systems: %zu particles, %ld steps x %d rounds (interleaved), %d threads\n",
              packing.radius.size(), steps, rounds, threads);
  std::printf("  %-34s %12s %8s\n", "variant", "M p-steps/s", "ratio");
  double base_rate = 0.0;
  for (std::size_t v = 0; v < variants.size(); ++v) {
    const double m = median(rates[v]);
    if (v == 0) base_rate = m;
    std::printf("  %-34s %12.3f %8.3f\n", variants[v].name, m / 1e6, m / base_rate);
  }
  return 0;
}

// The command line (CLI11, as the triaxial app): every option checked as it is parsed; bad input is
// one line naming the option and the value, exit 2. Numbers are read as strtod reads them, and the
// counts (steps, threads, rounds, sort) are truncated to integers, as before CLI11.
struct Options {
  std::string scene = std::string(SANDCELL_BENCH_SCENE_DIR) + "/dense-20k.txt";
  double steps = 2000, threads = 0, rounds = 3, sort_interval = 1000;  // threads 0: all hardware threads
  double tile = 1;  // --tile K: the scene repeated K x K x K times
  double deform = 0.0, vchar = 0.0, shear = 0.0, skin = 0.3e-3;
  bool json = false, serial = false, costs = false, scaling = false, probe = false, compat = false;
  bool servo = false;  // --servo: the stress servo and its homogenizer every step (every axis held at rate 0)
  std::string visit_order = "adaptive";  // --visit-order: the force gather's (Executor::visit_order)
  std::string partition = "adaptive", rolling = "epsd2", tangential = "history", normal;
  std::string time_step = "fixed";  // --time-step: fixed (0.2 t_R) or stiffness (Model::time_step)
  double safety = 0.8, interval = 100;
  std::vector<std::string> params;  // --param NAME=VALUE: a normal law's parameter (the law registry's)
};

// A number in [lo, hi].
CLI::Validator number_in(double lo, double hi) {
  char text[64];
  std::snprintf(text, sizeof text, "[%g, %g]", lo, hi);
  const std::string range = text;
  return CLI::Validator(
      [lo, hi, range](std::string& value) -> std::string {
        char* end = nullptr;
        const double v = std::strtod(value.c_str(), &end);
        if (end == value.c_str() || *end != '\0' || !(v >= lo && v <= hi))
          return "'" + value + "': must be a number in " + range;
        return {};
      },
      "in " + range);
}

// Returns the exit code when the process ends here (--help: 0; bad input: 2), else nothing.
std::optional<int> parse_command_line(int argc, char** argv, Options& o, Model& model) {
  CLI::App app{
      "dem-bench: throughput and physics check of sandcell on the benchmark scenes (scene A: fixed "
      "box; scene B: --deform 0.9391)"};
  app.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);  // a repeated option: the last
  app.footer(
      "usage: dem-bench [--scene FILE] [--tile K] [--steps N] [--threads T] [--deform RATE] [--rolling none|epsd2|epsd|cdt]\n"
      "                 [--tangential history|incremental] [--normal hertz|hooke [--vchar V]] [--compat]\n"
      "                 [--sort STEPS] [--skin M] [--serial] [--partition adaptive|owner|dynamic|fixed]\n"
      "                 [--visit-order adaptive|sorted|array] [--json]\n"
      "       dem-bench --costs [--scene FILE] [--steps N] [--threads T] [--rounds R]\n"
      "       dem-bench --probe [--threads T]   (the machine alone: register-only scaling, ping-pong, memory)\n"
      "       dem-bench --scaling [--scene FILE] [--steps N] [--threads T] [--rounds R] [--deform RATE]\n"
      "                 [--partition P] [--probe] [--json]");
  app.add_option("--scene", o.scene, "packing file (default: scenes/dense-20k.txt)")->type_name("FILE");
  app.add_option("--steps", o.steps, "steps of the run (of each block with --scaling, --costs)")
      ->type_name("N")
      ->check(number_in(0, 1e9));
  app.add_option("--threads", o.threads, "threads (default: all hardware threads)")
      ->type_name("T")
      ->check(number_in(1, 1024));
  app.add_option("--shear", o.shear, "simple shear: L_xz = RATE (1/s), the cell tilting and flipping")
      ->type_name("RATE")
      ->check(CLI::Range(-1e6, 1e6));
  app.add_option("--deform", o.deform, "scene B: z shortened at this engineering strain rate, 1/s")
      ->type_name("RATE")
      ->check(number_in(0, 1e6));
  app.add_option("--skin", o.skin, "the neighbour list's Verlet skin, m (default 3e-4, as the established codes' runs)")
      ->type_name("M")
      ->check(number_in(1e-6, 1e-2));
  app.add_flag("--compat", o.compat, "leave the affine term out of the contact velocities, as LIGGGHTS does");
  app.add_option("--sort", o.sort_interval, "spatial sort interval in steps (default 1000; 0: never)")
      ->type_name("STEPS")
      ->check(number_in(0, 1e9));
  app.add_flag("--serial", o.serial, "serial executor instead of TBB");
  app.add_flag("--json", o.json, "machine-readable output");
  app.add_flag("--costs", o.costs, "the cost of each optional system, variants interleaved");
  app.add_flag("--scaling", o.scaling, "a 1-thread and a T-thread world alternating: the thread scaling");
  app.add_flag("--probe", o.probe, "the machine alone (with --scaling: in every round)");
  app.add_option("--partition", o.partition, "how the threads share each pass (default adaptive)")
      ->type_name("P")
      ->check(CLI::IsMember(std::vector<std::string>{"adaptive", "dynamic", "fixed", "owner"}));
  app.add_flag("--servo", o.servo,
               "the stress servo on every step (every axis strain-controlled at rate 0: the cell does not move), "
               "with the homogenizer that measures the stress for it: what stress control costs");
  app.add_option("--visit-order", o.visit_order,
                 "the order in which the force gather visits the particles: sorted, array or adaptive (the default: "
                 "the faster of the two, tried as it runs); every result is the same")
      ->type_name("V")
      ->check(CLI::IsMember(std::vector<std::string>(k_visit_order_names.begin(), k_visit_order_names.end())));
  app.add_option("--tile", o.tile,
                 "the scene repeated K x K x K times in a K times larger box (2: 160,000 spheres from dense-20k, "
                 "4: 1,280,000): the same density, contacts per sphere and stress")
      ->type_name("K")
      ->check(number_in(1, 8));
  app.add_option("--rounds", o.rounds, "rounds of --scaling and --costs (default 3)")
      ->type_name("R")
      ->check(number_in(1, 1000));
  app.add_option("--rolling", o.rolling, "rolling resistance (default epsd2)")
      ->type_name("MODEL")
      ->check(CLI::IsMember(rolling_law_names()));
  app.add_option("--tangential", o.tangential, "tangential history (default history)")
      ->type_name("MODEL")
      ->check(CLI::IsMember(tangential_law_names()));
  // The normal law by its registered name (hertz, hooke); hooke takes --vchar. The engine checks
  // both when the world is built and refuses an unknown name, listing the registered ones.
  app.add_option("--normal", o.normal, "normal contact law by its registered name (default hertz)")->type_name("LAW");
  app.add_option("--vchar", o.vchar, "hooke's characteristic velocity, m/s (as --param characteristic_velocity=V)")
      ->type_name("V")
      ->check(number_in(1e-9, 1e6));
  // A normal law's parameter by its registered name, range checked from the registry.
  std::string param_names;
  for (const NormalLawInfo& law : normal_laws())
    for (const LawParameter& q : law.parameters) param_names += (param_names.empty() ? "" : ", ") + std::string(q.name);
  app.add_option("--time-step", o.time_step, "fixed (0.2 Rayleigh times, the default) or stiffness (from the contacts)")
      ->check(CLI::IsMember({"fixed", "stiffness"}));
  app.add_option("--safety", o.safety, "the stiffness step's safety factor (default 0.8; with --time-step stiffness)")
      ->check(number_in(1e-3, 1.4142135623730951));
  app.add_option("--interval", o.interval, "steps between updates of the stiffness step (default 100)")
      ->check(number_in(1, 1e6));
  app.add_option("--param", o.params, "a normal law's parameter NAME=VALUE (" + param_names + "), repeatable")
      ->type_name("NAME=VALUE")
      ->check(CLI::Validator(
          [](std::string& text) -> std::string {
            const std::size_t eq = text.find('=');
            const std::string name = text.substr(0, eq);
            for (const NormalLawInfo& law : normal_laws())
              for (const LawParameter& q : law.parameters)
                if (q.name == name) {
                  char* end = nullptr;
                  const std::string value = eq == std::string::npos ? "" : text.substr(eq + 1);
                  const double v = std::strtod(value.c_str(), &end);
                  if (value.empty() || *end != '\0' || !(v >= q.lo && v <= q.hi))
                  {
                    char range[96];
                    std::snprintf(range, sizeof range, "[%g, %g]", q.lo, q.hi);
                    return text + ": allowed: " + name + " in " + range + " " + std::string(q.units);
                  }
                  return "";
                }
            return text + ": not a parameter of a registered normal law";
          },
          "NAME=VALUE"));
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp&) {
    std::printf("%s", app.help().c_str());
    return 0;
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "dem-bench: %s (see --help)\n", e.what());
    return 2;
  }
  // What is not given keeps the Model's default. A setting that would have no effect is an error.
  for (const auto& [flag, value] : {std::pair{"--safety", o.safety}, std::pair{"--interval", o.interval}})
    if (o.time_step != "stiffness" && app.count(flag) > 0) {
      std::fprintf(stderr, "dem-bench: %s %g: acts only with --time-step stiffness\n", flag, value);
      return 2;
    }
  if (o.interval != std::floor(o.interval)) {
    std::fprintf(stderr, "dem-bench: --interval %g: must be a whole number of steps\n", o.interval);
    return 2;
  }
  if (o.compat) model.contact.liggghts_compat = true;
  // The laws by their registered names (CLI11 let only those through).
  if (app.count("--rolling") > 0) model.contact.rolling = rolling_law(o.rolling).value();
  if (app.count("--tangential") > 0) model.contact.tangential = tangential_law(o.tangential).value();
  if (app.count("--normal") > 0) model.contact.normal = o.normal;
  if (app.count("--vchar") > 0) model.contact.parameters["characteristic_velocity"] = o.vchar;
  for (const std::string& p : o.params)
    model.contact.parameters[p.substr(0, p.find('='))] = std::strtod(p.substr(p.find('=') + 1).c_str(), nullptr);
  return std::nullopt;
}

}  // namespace

static int bench_main(int argc, char** argv) {
  Options o;
  Model model;
  if (const std::optional<int> code = parse_command_line(argc, argv, o, model)) return *code;
  const std::string& scene = o.scene;
  const long steps = static_cast<long>(o.steps);
  const int threads = static_cast<int>(o.threads);
  const double deform = o.deform;
  const Drive drive{o.deform, o.shear};
  const bool json = o.json, serial = o.serial, costs = o.costs, scaling = o.scaling, probe = o.probe;
  const Partition partition = *partition_from_name(o.partition);
  const int rounds = static_cast<int>(o.rounds);

  // The benchmark material and settings (identical in every code).
  model.dt = 5.324636531947874e-07;  // s, 0.2 x Rayleigh time of the smallest (d = 5 mm) sphere
  model.materials.push_back(Material{2650.0, 70e9, 0.3, 0.5, 0.5, 0.1});
  model.contact.skin = o.skin;  // m
  model.contact.sort_interval = static_cast<int>(o.sort_interval);
  if (o.servo) {  // as --costs' "servo + homogenizer" variant
    if (o.deform > 0 || o.shear != 0) usage_error("--servo: not with --deform or --shear (the servo holds the cell)");
    model.servo.enabled = true;
    model.servo.path = StressPath::fixed;
    model.servo.gain = 1.0;
    model.servo.max_rate = 1.0;
  }
  if (o.time_step == "stiffness")  // bounded by one Rayleigh time (5 x the fixed 0.2 t_R)
    model.time_step = TimeStepSettings{TimeStepRule::stiffness, o.safety, static_cast<int>(o.interval), 5.0 * model.dt};

  Packing packing;
  try {
    packing = read_packing(scene);
  } catch (const std::exception& e) {
    usage_error(e.what());
  }
  if (o.tile != std::floor(o.tile)) usage_error("--tile " + std::to_string(o.tile) + ": must be an integer in [1, 8]");
  if (o.tile > 1) packing = tile_packing(packing, static_cast<int>(o.tile));
  // Options the --costs, --scaling and --probe runs would ignore are refused, not dropped.
  if (o.visit_order != "adaptive" && (costs || scaling || probe))
    usage_error("--visit-order " + o.visit_order + ": only for a plain run (not with --costs, --scaling or --probe)");
  if (o.servo && (costs || (probe && !scaling)))
    usage_error("--servo: not with --costs (its variants add the servo themselves) or --probe");
  if (costs) return run_costs(model, packing, steps, threads, rounds);
  if (scaling) return run_scaling(model, packing, steps, threads, rounds, drive, json, probe, partition);
  if (probe) {  // the machine alone (probe.hpp), for scripts that time other programs in the same rounds
    const int t = threads > 0 ? threads : available_cpus();
    const double a1 = bench::alu_rate(1, 0.2);
    std::printf(
        "{\"threads\": %d, \"alu_one\": %.6g, \"alu_ratio\": %.6g, \"pingpong_ns\": %.6g, "
        "\"chase_ns\": %.6g, \"stream_gbs\": %.6g}\n",
        t, a1, bench::alu_rate(t, 0.2) / a1, bench::pingpong_ns(5), bench::chase_ns(std::size_t{16} << 20),
        bench::stream_gbs(std::size_t{64} << 20));
    return 0;
  }
  ExecutorConfig exec{serial ? Backend::serial : Backend::tbb, threads, partition};
  exec.visit_order = *visit_order_from_name(o.visit_order);
  World world(model, make_state(model, packing), systems_for(model), exec);
  const std::size_t n = world.state().particles.size();
  const double lz0 = world.state().cell.length[2];
  const Mat3 s0 = contact_stress(world.state(), world.executor());
  const std::size_t c0 = count_touching(world.state());
  const std::uint64_t builds0 = list_builds(world.scratch());

  world.reset_timers();
  const auto t0 = std::chrono::steady_clock::now();
  advance(world, steps, drive, lz0);
  const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();

  const Mat3 s1 = contact_stress(world.state(), world.executor());
  const std::size_t c1 = count_touching(world.state());
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  const double peak_mib = usage.ru_maxrss / 1024.0;
  const double rate = wall > 0 ? double(n) * double(steps) / wall : 0.0;
  const std::uint64_t builds = list_builds(world.scratch()) - builds0;
  const auto& graph = world.graph();
  const unsigned long long digest = state_digest(world.state());
  // With --servo, the bits of the stress the servo read last (the contact pass's block sums): the
  // servo holds the cell, so the state digest does not see them.
  std::string servo_stress = "none";
  if (model.servo.enabled) {
    Fnv1a f;
    f.bytes(world.scratch().own<MeasuredStress>().stress.data(), sizeof(double) * 9);
    servo_stress = hex_digest(f.h);
  }
  const PartitionSteps& ps = world.executor().partition_steps();
  const GatherTrials& gt = world.scratch().own<GatherTrials>();  // counts from the world's setup on
  const std::string partition_used{serial ? std::string_view("serial") : partition_name(partition)};

  if (json) {
    std::printf(
        "{\"scene\": \"%s\", \"arch\": \"%s\", \"particles\": %zu, \"steps\": %ld, \"threads\": %d, \"backend\": \"%s\",\n"
        " \"deform\": %.6g, \"shear\": %.6g, \"compat\": %s, \"wall_s\": %.6f, \"particle_steps_per_s\": %.6e,\n"
        " \"contacts_per_particle_start\": %.6f, \"contacts_per_particle\": %.6f, \"rebuilds\": %llu,\n"
        " \"peak_mib\": %.1f, \"mean_stress_start_pa\": %.6e, \"mean_stress_pa\": %.6e,\n"
        " \"stress_pa\": [%.6e, %.6e, %.6e, %.6e, %.6e, %.6e], \"lz\": %.9f, \"digest\": \"%016llx\",\n"
        " \"servo_stress_digest\": \"%s\","
        " \"time_step\": \"%s\", \"dt_s\": %.9e, \"simulated_s\": %.9e,\n"
        " \"partition\": \"%s\", \"partition_steps\": {\"owner\": %llu, \"dynamic\": %llu, \"switches\": %llu, "
        "\"trials\": %llu},\n"
        " \"visit_order\": \"%s\", \"gather_calls\": {\"sorted\": %llu, \"array\": %llu, \"trials\": %llu},\n"
        " \"system_s\": {",
        scene.c_str(), std::string(build_arch()).c_str(), n, steps, world.executor().threads(),
        serial ? "serial" : "tbb", deform, drive.shear, model.contact.liggghts_compat ? "true" : "false", wall, rate, 2.0 * c0 / n,
        2.0 * c1 / n, static_cast<unsigned long long>(builds), peak_mib, s0.trace() / 3, s1.trace() / 3, s1(0, 0),
        s1(1, 1), s1(2, 2), s1(0, 1), s1(0, 2), s1(1, 2), world.state().cell.length[2], digest, servo_stress.c_str(),
        model.time_step.rule == TimeStepRule::stiffness ? "stiffness" : "fixed", world.model().dt,
        world.state().clock.time, partition_used.c_str(),
        static_cast<unsigned long long>(ps.owner), static_cast<unsigned long long>(ps.dynamic),
        static_cast<unsigned long long>(ps.switches), static_cast<unsigned long long>(ps.trials),
        o.visit_order.c_str(), static_cast<unsigned long long>(gt.sorted_calls),
        static_cast<unsigned long long>(gt.array_calls), static_cast<unsigned long long>(gt.trials));
    for (std::size_t k = 0; k < graph.size(); ++k)
      std::printf("%s\"%s\": %.6f", k ? ", " : "", graph.system(k).name.c_str(), graph.timers()[k]);
    std::printf("}}\n");
    return 0;
  }
  std::printf("scene            %s%s%s\n", scene.c_str(), deform > 0 ? " (deforming, scene B)" : " (fixed box, scene A)",
              drive.shear != 0.0 ? ", simple shear (a tilted cell)" : "");
  std::printf("particles        %zu\n", n);
  std::printf("steps            %ld\n", steps);
  std::printf("threads          %d (%s)\n", world.executor().threads(), serial ? "serial backend" : "tbb");
  std::printf("partition        %s", partition_used.c_str());
  if (ps.trials > 0)
    std::printf(" (steps: %llu owner, %llu dynamic; trials %llu, switches %llu)",
                static_cast<unsigned long long>(ps.owner), static_cast<unsigned long long>(ps.dynamic),
                static_cast<unsigned long long>(ps.trials), static_cast<unsigned long long>(ps.switches));
  std::printf("\n");
  std::printf("gather order     %s (calls: %llu sorted, %llu array; %llu trials)\n", o.visit_order.c_str(),
              static_cast<unsigned long long>(gt.sorted_calls), static_cast<unsigned long long>(gt.array_calls),
              static_cast<unsigned long long>(gt.trials));
  std::printf("build arch       %s (SANDCELL_ARCH; results are bitwise the same for every value)\n",
              std::string(build_arch()).c_str());
  std::printf("wall (step loop) %.3f s\n", wall);
  std::printf("throughput       %.3f M particle-steps/s\n", rate / 1e6);
  std::printf("time step        %s, dt %.4g s at the end, %.4g s simulated (%.4g s of simulated time per wall second)\n",
              model.time_step.rule == TimeStepRule::stiffness ? "stiffness" : "fixed 0.2 t_R", world.model().dt,
              world.state().clock.time, world.state().clock.time / wall);
  std::printf("contacts/particle %.4f at start, %.4f at end\n", 2.0 * c0 / n, 2.0 * c1 / n);
  std::printf("rebuilds         %llu (%zu candidate pairs in the list)\n", static_cast<unsigned long long>(builds),
              world.state().contacts.size());
  std::printf("peak memory      %.1f MiB\n", peak_mib);
  std::printf("mean stress      %.6g MPa at start, %.6g MPa at end (contacts, compression positive)\n",
              s0.trace() / 3e6, s1.trace() / 3e6);
  std::printf("stress (MPa)     xx %.6g yy %.6g zz %.6g xy %.4g xz %.4g yz %.4g\n", s1(0, 0) / 1e6, s1(1, 1) / 1e6,
              s1(2, 2) / 1e6, s1(0, 1) / 1e6, s1(0, 2) / 1e6, s1(1, 2) / 1e6);
  std::printf("state digest     %016llx (FNV-1a of the final state; equal digests = bitwise equal runs)\n", digest);
  if (model.servo.enabled) std::printf("servo stress     %s (FNV-1a of the stress the servo read last)\n", servo_stress.c_str());
  std::printf("time per system (share of the step loop):\n");
  for (std::size_t k = 0; k < graph.size(); ++k)
    std::printf("  %-18s %8.3f s  %5.1f %%\n", graph.system(k).name.c_str(), graph.timers()[k],
                wall > 0 ? 100.0 * graph.timers()[k] / wall : 0.0);
  return 0;
}

int main(int argc, char** argv) {
  // A model the engine refuses (an unregistered law, a law without its parameter): one line, exit 2.
  try {
    return bench_main(argc, argv);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "dem-bench: %s\n", e.what());
    return 2;
  }
}
