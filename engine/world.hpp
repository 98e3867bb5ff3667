#pragma once
// World: one scene = Model + State + Scratch + Executor + the step graph built from the systems the
// scene needs. The list of systems, in reference order, is made in one place: build_systems().
#include "engine/function_ref.hpp"
#include "engine/step_graph.hpp"

#include <cstdint>
#include <stdexcept>
#include <vector>

namespace sandcell {

/// The systems a scene needs, in reference order. Systems the model does not use are not listed
/// (and so neither scheduled nor allocated for).
std::vector<SystemSpec> build_systems(const Model& model);

/// Checks the model and the initial state; throws std::invalid_argument naming the offending value.
void validate(const Model& model, const State& state);

/// Checks the servo settings (docs/physics.md section 6); throws std::invalid_argument naming the key.
void validate(const ServoSettings& servo);

/// A run that cannot continue (cell too narrow, instability): the message names the step, the
/// particles and the quantity.
struct SimulationError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

class World {
 public:
  /// Builds the scene with build_systems(model). Unless `initial_forces` is false (a state that
  /// already holds its forces, e.g. from a checkpoint), the neighbour list and the forces of the
  /// initial configuration are computed first, without touching contact history.
  World(Model model, State state, ExecutorConfig exec = {}, bool initial_forces = true);
  /// Same, with an explicit system list (tests, custom scenes).
  World(Model model, State state, std::vector<SystemSpec> systems, ExecutorConfig exec = {},
        bool initial_forces = true);

  /// Advances n steps. Throws SimulationError when a system flags trouble; the state is then that
  /// of the end of the failed step.
  void step(std::uint64_t n = 1);
  /// Advances at most n steps, stopping after the first step for which stop(cell, clock) returns
  /// true; returns the number of steps done. The hook sees only the cell and the clock, and may
  /// set the cell's strain rate for the next step (e.g. a deformation at an engineering rate).
  /// Inside one call, the final half kick of each step is left to the next step's first pass
  /// (Scratch::defer_final_kick, when defers_final_kick()), which the particles' velocities are
  /// then waiting for: hence no hook on the particles. The state seen after the call is bitwise
  /// that of one step per call; the fewer calls, the fewer passes over the particles.
  std::uint64_t step_until(std::uint64_t n, FunctionRef<bool(Cell&, const Clock&)> stop);

  const Model& model() const { return model_; }
  State& state() { return state_; }
  const State& state() const { return state_; }
  const Scratch& scratch() const { return scratch_; }
  Executor& executor() { return exec_; }
  const StepGraph& graph() const { return graph_; }
  /// Whether step(n) leaves each final half kick but the last to the next step's first pass.
  bool defers_final_kick() const { return defer_kick_; }
  /// Zeroes the per-system timers (e.g. before a timed loop).
  void reset_timers() { graph_.reset_timers(); }

 private:
  void check_health() const;
  void finish_kick();
  static bool can_defer_kick(const StepGraph& graph);

  Model model_;
  State state_;
  Scratch scratch_;
  Executor exec_;
  StepGraph graph_;
  bool defer_kick_ = false;  // integrate_initial runs first and integrate_final last (can_defer_kick)
};

}  // namespace sandcell
