#include "engine/step_graph.hpp"

#include "engine/executor_tbb.hpp"

#include <oneapi/tbb/flow_graph.h>

#include <chrono>

namespace sandcell {

namespace {
// Runs system k with its access scope and adds its wall time to seconds[k].
void timed_run(const SystemRun& run, const AccessSets& access, double& seconds, const Model& model, State& state,
               Scratch& scratch, Executor& exec) {
  const auto t0 = std::chrono::steady_clock::now();
  {
    AccessScope scope(access);
    run(model, state, scratch, exec);
  }
  seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

bool conflict(const SystemSpec& a, const SystemSpec& b) {
  return (a.writes & (b.reads | b.writes)) != 0 || (a.reads & b.writes) != 0;
}
}  // namespace

struct StepGraph::Flow {
  tbb::flow::graph graph;
  tbb::flow::broadcast_node<tbb::flow::continue_msg> start{graph};
  std::vector<std::unique_ptr<tbb::flow::continue_node<tbb::flow::continue_msg>>> nodes;
  // Arguments of the step being run; set before start.try_put.
  const Model* model = nullptr;
  State* state = nullptr;
  Scratch* scratch = nullptr;
};

StepGraph::StepGraph(std::vector<SystemSpec> systems, Executor& exec) : systems_(std::move(systems)), exec_(exec) {
  const std::size_t n = systems_.size();
  access_.resize(n);
  seconds_.assign(n, 0.0);
  for (std::size_t k = 0; k < n; ++k) access_[k] = AccessSets{systems_[k].name, systems_[k].reads, systems_[k].writes};

  // Conflict edges, then the transitive closure (in reference order, a DAG by construction).
  std::vector<std::vector<bool>> direct(n, std::vector<bool>(n, false));
  reach_.assign(n, std::vector<bool>(n, false));
  for (std::size_t b = 0; b < n; ++b)
    for (std::size_t a = 0; a < b; ++a)
      if (conflict(systems_[a], systems_[b])) direct[a][b] = true;
  for (std::size_t b = 0; b < n; ++b)
    for (std::size_t a = b; a-- > 0;)
      if (direct[a][b]) {
        reach_[a][b] = true;
        for (std::size_t c = 0; c < a; ++c)
          if (reach_[c][a]) reach_[c][b] = true;
      }
  // Transitive reduction: keep a -> b unless some a -> c -> b exists.
  for (std::size_t a = 0; a < n; ++a)
    for (std::size_t b = a + 1; b < n; ++b) {
      if (!direct[a][b]) continue;
      bool implied = false;
      for (std::size_t c = a + 1; c < b && !implied; ++c) implied = reach_[a][c] && reach_[c][b];
      if (!implied) edges_.emplace_back(a, b);
    }

  if (exec_.backend() == Backend::serial) return;
  // The flow graph belongs to the arena it is built in: build it inside the executor's arena.
  exec_.impl()->arena.execute([&] {
    flow_ = std::make_unique<Flow>();
    for (std::size_t k = 0; k < n; ++k) {
      flow_->nodes.push_back(std::make_unique<tbb::flow::continue_node<tbb::flow::continue_msg>>(
          flow_->graph, [this, k](const tbb::flow::continue_msg&) {
            timed_run(systems_[k].run, access_[k], seconds_[k], *flow_->model, *flow_->state, *flow_->scratch, exec_);
          }));
    }
    std::vector<bool> has_pred(n, false);
    for (auto [a, b] : edges_) {
      tbb::flow::make_edge(*flow_->nodes[a], *flow_->nodes[b]);
      has_pred[b] = true;
    }
    for (std::size_t k = 0; k < n; ++k)
      if (!has_pred[k]) tbb::flow::make_edge(flow_->start, *flow_->nodes[k]);
  });
}

StepGraph::~StepGraph() = default;

void StepGraph::run(const Model& model, State& state, Scratch& scratch) {
  if (!flow_) {
    for (std::size_t k = 0; k < systems_.size(); ++k)
      timed_run(systems_[k].run, access_[k], seconds_[k], model, state, scratch, exec_);
    return;
  }
  flow_->model = &model;
  flow_->state = &state;
  flow_->scratch = &scratch;
  exec_.impl()->arena.execute([&] {
    flow_->start.try_put(tbb::flow::continue_msg());
    flow_->graph.wait_for_all();
  });
}

void StepGraph::run_one(std::size_t k, const Model& model, State& state, Scratch& scratch) {
  timed_run(systems_[k].run, access_[k], seconds_[k], model, state, scratch, exec_);
}

void StepGraph::run_hook(std::size_t k, const SystemRun& hook, const Model& model, State& state, Scratch& scratch) {
  timed_run(hook, access_[k], seconds_[k], model, state, scratch, exec_);
}

std::size_t StepGraph::find(std::string_view name) const {
  for (std::size_t k = 0; k < systems_.size(); ++k)
    if (systems_[k].name == name) return k;
  return systems_.size();
}

bool StepGraph::has_edge(std::size_t from, std::size_t to) const {
  for (auto [a, b] : edges_)
    if (a == from && b == to) return true;
  return false;
}

bool StepGraph::ordered(std::size_t from, std::size_t to) const { return reach_[from][to]; }

std::string StepGraph::describe() const {
  std::string out;
  for (std::size_t b = 0; b < systems_.size(); ++b) {
    out += systems_[b].name;
    std::string after;
    for (auto [a, bb] : edges_)
      if (bb == b) after += (after.empty() ? "" : ", ") + systems_[a].name;
    out += after.empty() ? "  (first)" : "  after: " + after;
    out += '\n';
  }
  return out;
}

void run_system(const SystemSpec& system, const Model& model, State& state, Scratch& scratch, Executor& exec) {
  run_hook(system, system.run, model, state, scratch, exec);
}

void run_hook(const SystemSpec& system, const SystemRun& hook, const Model& model, State& state, Scratch& scratch,
              Executor& exec) {
  const AccessSets sets{system.name, system.reads, system.writes};
  AccessScope scope(sets);
  hook(model, state, scratch, exec);
}

}  // namespace sandcell
