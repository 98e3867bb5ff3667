#pragma once
// force_gather: per-particle sums of the pair slots in a fixed order: first the pairs where the
// particle is i (a contiguous run, since the list is sorted by i), then those where it is j (from
// the gather index, ascending). F_k = sum(F on i, k is i) - sum(F on i, k is j); torques from the
// torque_i / torque_j slots. No atomics; the order of every sum is fixed by the pair list, so the
// result is bitwise the same for any thread count. Reads contact_forces and gather_index; writes
// particle forces and torques (all of them: a particle without contacts gets zero).
// The visiting order changes no sum, only the speed (Executor::visit_order, engine/executor.hpp):
// - sorted: GatherIndex::visit (by pair counts within blocks of 128), so the branch predictor learns
//   the loops' trip counts: the faster while the pair arrays stay in the last-level cache;
// - array: particle order, the pair slots of the j entries asked for 8 particles ahead: the faster
//   when the pair arrays stream from memory (the contact pass wrote them past the cache);
// - adaptive (default): alternates the two call by call for a trial of 2 x 16 calls, runs the one
//   with the smaller median time for the next 2,048 calls, then tries again.
// docs/performance.md gives the measured effects.
#include "engine/system.hpp"

#include <array>
#include <cstdint>

namespace sandcell {

/// The gather's own scratch: the state of VisitOrder::adaptive's trials, and the calls run in each
/// order (dem-bench reports them). A trial alternates the orders call by call (sorted first), 16
/// calls each; the order with the smaller median time then runs for 2,048 calls, and a new trial
/// starts. The bookkeeping is here, apart from the clock, so that a test can feed it chosen times.
struct GatherTrials {
  static constexpr std::uint32_t k_trial = 16;   // calls per order in a trial
  static constexpr std::uint32_t k_hold = 2048;  // calls run in the faster order before the next trial
  bool in_trial = true;
  bool array = false;      // the order in use between trials
  std::uint32_t call = 0;  // calls into the trial (< 2 k_trial: even sorted, odd array) or the hold
  std::array<double, k_trial> sorted_seconds{}, array_seconds{};
  std::uint64_t sorted_calls = 0, array_calls = 0, trials = 0;

  /// Whether the next adaptive call runs the array order.
  bool next_array() const { return in_trial ? call % 2 == 1 : array; }
  /// Counts a call in the order it ran (any VisitOrder).
  void count(bool ran_array) { ++(ran_array ? array_calls : sorted_calls); }
  /// An adaptive call's time, in the order next_array() gave it (counted with count()).
  void record(double seconds);
};

struct ForceGather {
  static constexpr std::string_view name = "force_gather";
  static constexpr ComponentMask reads =
      mask_of({Component::contact_forces, Component::gather_index, Component::halo});
  static constexpr ComponentMask writes = mask_of({Component::particle_force, Component::particle_torque});
  static void run(const Model& model, State& state, Scratch& scratch, Executor& exec);
  /// The sums of the initial configuration's forces (the same pass).
  static void setup(const Model& model, State& state, Scratch& scratch, Executor& exec) {
    run(model, state, scratch, exec);
  }
};

}  // namespace sandcell
