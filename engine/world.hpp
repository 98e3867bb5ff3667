#pragma once
// World: one scene = Model + State + Scratch + Executor + the step graph built from the list of
// systems it is given (systems/catalogue.hpp makes the list a model needs). The engine knows the
// systems only through SystemSpec: their access sets, their step, and their optional part in
// scene setup, restore and deferred work (engine/system.hpp).
#include "engine/function_ref.hpp"
#include "engine/step_graph.hpp"

#include <cstdint>
#include <memory>
#include <stdexcept>
#include <vector>

namespace sandcell {

/// Checks the model and the initial state; throws std::invalid_argument naming the offending value.
void validate(const Model& model, const State& state);

/// A run that cannot continue (cell too narrow, instability): the message names the step, the
/// particles and the quantity.
struct SimulationError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class World {
 public:
  /// Builds the scene from `systems`, in reference order (systems/catalogue.hpp: the list a model
  /// needs). Each system's `prepare` hook runs first. Unless `initial_forces` is false (a state that
  /// already holds its forces, e.g. from a checkpoint, whose systems then `restore` their scratch),
  /// the systems' `setup` hooks compute the forces of the initial configuration (the neighbour list,
  /// the contact forces and their sums) without touching contact history.
  World(Model model, State state, std::vector<SystemSpec> systems, ExecutorConfig exec = {},
        bool initial_forces = true);

  /// Advances n steps. Throws SimulationError when a system flags trouble; the state is then that
  /// of the end of the failed step.
  void step(std::uint64_t n = 1);
  /// Advances at most n steps, stopping after the first step for which stop(cell, clock) returns
  /// true; returns the number of steps done. The hook sees only the cell and the clock, and may
  /// set the cell's strain rate for the next step (e.g. a deformation at an engineering rate).
  /// Inside one call, a system that declares `deferred_to` may leave its work to the next step
  /// (Scratch::batching, when defers_work()): the integrator's final half kick is applied by the
  /// next step's first pass, which the particles' velocities are then waiting for: hence no hook
  /// on the particles. Before returning, World calls the `flush` of such systems, so the state seen
  /// after the call is bitwise that of one step per call; the fewer calls, the fewer passes.
  std::uint64_t step_until(std::uint64_t n, FunctionRef<bool(Cell&, const Clock&)> stop);
  /// Puts the scene back at `state`, a copy of this World's state taken between calls (or a
  /// checkpoint of it), e.g. after an exception that interrupted a step: arrays of the same size
  /// are assigned in place (their data stay where they are), and the scratch is rebuilt from it
  /// as World(model, state, systems, exec, false) builds it, so continuing is bitwise as
  /// continuing from that state.
  void reset(const State& state);

  /// The model; under an adaptive time step (Model::time_step) its dt is the step in effect.
  const Model& model() const { return model_; }
  State& state() { return state_; }
  const State& state() const { return state_; }
  const Scratch& scratch() const { return *scratch_; }
  Executor& executor() { return exec_; }
  const StepGraph& graph() const { return graph_; }
  /// Whether step(n) lets systems leave work to the next step (each final half kick but the
  /// last, with the catalogue's integrator).
  bool defers_work() const { return batching_; }
  /// Zeroes the per-system timers (e.g. before a timed loop).
  void reset_timers() { graph_.reset_timers(); }

 private:
  void check_health() const;
  void flush();
  void update_time_step();
  void first_time_step();
  void restore();
  static bool can_batch(const StepGraph& graph);

  Model model_;
  State state_;
  std::unique_ptr<Scratch> scratch_ = std::make_unique<Scratch>();  // replaced by reset()
  Executor exec_;
  StepGraph graph_;
  bool batching_ = false;  // every deferring system runs last and the one it defers to first (can_batch)
};

}  // namespace sandcell
