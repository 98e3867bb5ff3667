#pragma once
// What a system is, to the engine: a name, declared read and write sets, and one entry point
//   static void run(const Model&, State&, Scratch&, Executor&);
// A system type provides `name`, `reads`, `writes` (initializer-list masks) and `run`;
// make_system() turns it into the type-erased record the step graph schedules.
#include "engine/access.hpp"
#include "engine/executor.hpp"
#include "engine/model.hpp"
#include "engine/scratch.hpp"
#include "engine/state.hpp"

#include <functional>
#include <string>

namespace sandcell {

struct SystemSpec {
  std::string name;
  ComponentMask reads = 0;
  ComponentMask writes = 0;
  std::function<void(const Model&, State&, Scratch&, Executor&)> run;
};

template <class S>
SystemSpec make_system() {
  return SystemSpec{std::string(S::name), S::reads, S::writes, &S::run};
}

/// Runs one system outside a graph, with its access sets enforced (for tests and tools).
void run_system(const SystemSpec& system, const Model& model, State& state, Scratch& scratch, Executor& exec);

}  // namespace sandcell
