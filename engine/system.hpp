#pragma once
// What a system is, to the engine: a name, declared read and write sets, one entry point per step
//   static void run(const Model&, State&, Scratch&, Executor&);
// and, optionally, its part in the rest of World's protocol (all static members, detected by
// make_system(); a system without them takes no part):
//   static void check(const Model&);                     refuse settings of the system's own (invalid_argument)
//   static void prepare(const Model&, State&);          allocate what the model needs in the state
//                                                      (e.g. a contact law's history), before anything runs
//   static void setup(const Model&, State&, Scratch&, Executor&);
//                                                      the forces of the initial configuration, history
//                                                      frozen (LAMMPS `setup`), in reference order
//   static void restore(const Model&, State&, Scratch&); rebuild its scratch from a state that already
//                                                      holds its list and forces (a checkpoint)
//   static void flush(const Model&, State&, Scratch&, Executor&);
//                                                      finish work left for the next step (below)
//   static constexpr std::string_view deferred_to = "..."; with flush: the system may leave its work
//                                                      to that system's next run (see World::step_until)
//   static double stable_step(const Model&, const State&);
//   static constexpr ComponentMask stable_step_reads = ...;
//                                                      the largest step its physics allows now, before
//                                                      the safety factor (s; +inf: no bound), for an
//                                                      adaptive time step (Model::time_step); serial,
//                                                      from the state only, under its own read set
// The setup, restore and flush hooks run under the system's access sets like `run`.
// A system type provides `name`, `reads`, `writes` (initializer-list masks) and `run`;
// make_system() turns it into the type-erased record the step graph schedules.
#include "engine/access.hpp"
#include "engine/executor.hpp"
#include "engine/model.hpp"
#include "engine/scratch.hpp"
#include "engine/state.hpp"

#include <functional>
#include <string>
#include <string_view>
#include <utility>

namespace sandcell {

using SystemRun = std::function<void(const Model&, State&, Scratch&, Executor&)>;

struct SystemSpec {
  SystemSpec() = default;
  SystemSpec(std::string name_, ComponentMask reads_, ComponentMask writes_, SystemRun run_)
      : name(std::move(name_)), reads(reads_), writes(writes_), run(std::move(run_)) {}

  std::string name;
  ComponentMask reads = 0;
  ComponentMask writes = 0;
  SystemRun run;
  // Optional parts of World's protocol (engine/system.hpp above); empty: none.
  std::function<void(const Model&)> check;
  std::function<void(const Model&, State&)> prepare;
  SystemRun setup;
  std::function<void(const Model&, State&, Scratch&)> restore;
  SystemRun flush;
  std::string deferred_to;  // with flush: the system whose next run absorbs this one's pending work
  std::function<double(const Model&, const State&)> stable_step;  // s, the step its physics allows (+inf: none)
  ComponentMask stable_step_reads = 0;                            // what stable_step reads (enforced)
};

template <class S>
SystemSpec make_system() {
  SystemSpec spec(std::string(S::name), S::reads, S::writes, &S::run);
  if constexpr (requires { &S::check; }) spec.check = &S::check;
  if constexpr (requires { &S::prepare; }) spec.prepare = &S::prepare;
  if constexpr (requires { &S::setup; }) spec.setup = &S::setup;
  if constexpr (requires { &S::restore; }) spec.restore = &S::restore;
  if constexpr (requires { &S::stable_step; }) {
    spec.stable_step = &S::stable_step;
    spec.stable_step_reads = S::stable_step_reads;
  }
  if constexpr (requires { &S::flush; }) {
    spec.flush = &S::flush;
    spec.deferred_to = std::string(S::deferred_to);
  }
  return spec;
}

/// Runs one system outside a graph, with its access sets enforced (for tests and tools).
void run_system(const SystemSpec& system, const Model& model, State& state, Scratch& scratch, Executor& exec);
/// Runs `hook` of `system` with the system's access sets enforced.
void run_hook(const SystemSpec& system, const SystemRun& hook, const Model& model, State& state, Scratch& scratch,
              Executor& exec);

}  // namespace sandcell
