#pragma once
// The step graph: built once per scene from the systems' declared access sets, run once per step.
//
// Systems are listed in a reference order (the order a serial step would run them). For i < j,
// system j must follow system i when they conflict: both write a component, or one writes what the
// other reads. Those orderings, with transitive ones dropped, are the graph's edges; systems with
// no path between them may run concurrently. With the TBB backend the graph is a
// tbb::flow::graph of named continue nodes; with the serial backend the systems run in the
// reference order, which is a topological order of the same graph.
#include "engine/system.hpp"

#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace sandcell {

class StepGraph {
 public:
  StepGraph(std::vector<SystemSpec> systems, Executor& exec);
  ~StepGraph();
  StepGraph(const StepGraph&) = delete;
  StepGraph& operator=(const StepGraph&) = delete;

  /// Runs every system once, respecting the edges.
  void run(const Model& model, State& state, Scratch& scratch);
  /// Runs system k alone (its time counted in timers()), e.g. a kick left over from the last step.
  void run_one(std::size_t k, const Model& model, State& state, Scratch& scratch);
  /// Runs `hook` of system k (e.g. its flush) under its access sets, its time counted in timers().
  void run_hook(std::size_t k, const SystemRun& hook, const Model& model, State& state, Scratch& scratch);

  std::size_t size() const { return systems_.size(); }
  const SystemSpec& system(std::size_t k) const { return systems_[k]; }
  /// Index of the system with this name, or size() if none.
  std::size_t find(std::string_view name) const;

  /// A direct edge of the (transitively reduced) graph.
  bool has_edge(std::size_t from, std::size_t to) const;
  /// Whether `to` must run after `from` (a path from one to the other).
  bool ordered(std::size_t from, std::size_t to) const;
  const std::vector<std::pair<std::size_t, std::size_t>>& edges() const { return edges_; }

  /// Wall time spent in each system since construction (or reset_timers), s. Systems that run
  /// concurrently each count their own time.
  const std::vector<double>& timers() const { return seconds_; }
  void reset_timers() { seconds_.assign(systems_.size(), 0.0); }

  /// The graph as text: one line per system with what it waits for.
  std::string describe() const;

 private:
  struct Flow;
  std::vector<SystemSpec> systems_;
  std::vector<AccessSets> access_;
  std::vector<std::vector<bool>> reach_;  // reach_[a][b]: b runs after a
  std::vector<std::pair<std::size_t, std::size_t>> edges_;
  std::vector<double> seconds_;
  Executor& exec_;
  std::unique_ptr<Flow> flow_;
};

}  // namespace sandcell
