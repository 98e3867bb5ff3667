// Step graph: edges from declared access sets, execution order, and concurrency of independent systems.
#include "engine/step_graph.hpp"

#include <doctest/doctest.h>

#include <atomic>
#include <chrono>
#include <thread>

using namespace sandcell;

namespace {
// A global logical clock: each system takes a tick when it starts and when it ends.
std::atomic<int> g_tick{0};
struct Stamp {
  std::atomic<int> start{-1}, end{-1};
};
Stamp g_stamps[8];

SystemSpec stamped(int slot, const char* name, ComponentMask reads, ComponentMask writes) {
  return SystemSpec{name, reads, writes, [slot](const Model&, State&, Scratch&, Executor&) {
                      g_stamps[slot].start = g_tick++;
                      std::this_thread::sleep_for(std::chrono::milliseconds(2));
                      g_stamps[slot].end = g_tick++;
                    }};
}

using C = Component;
}  // namespace

TEST_CASE("conflicting systems are ordered, independent ones get no edge") {
  // a writes position; b reads position, writes force; c writes torque; d reads force and torque;
  // e writes force again (write-write with b, after d reads it).
  std::vector<SystemSpec> systems{
      stamped(0, "a", 0, mask_of(C::particle_position)),
      stamped(1, "b", mask_of(C::particle_position), mask_of(C::particle_force)),
      stamped(2, "c", 0, mask_of(C::particle_torque)),
      stamped(3, "d", mask_of({C::particle_force, C::particle_torque}), mask_of(C::particle_velocity)),
      stamped(4, "e", 0, mask_of(C::particle_force)),
  };
  for (int threads : {1, 2, 4}) {
    Executor exec({Backend::tbb, threads});
    StepGraph graph(systems, exec);
    CHECK(graph.has_edge(0, 1));        // read after write
    CHECK(graph.has_edge(1, 3));        // read after write
    CHECK(graph.has_edge(2, 3));        // read after write
    CHECK(graph.has_edge(3, 4));        // write after read
    CHECK_FALSE(graph.has_edge(1, 4));  // write-write, implied by 1 -> 3 -> 4: reduced away
    CHECK(graph.ordered(1, 4));
    CHECK(graph.ordered(0, 3));
    // Independent pairs: no edge and no path either way.
    for (auto [x, y] : {std::pair{0, 2}, std::pair{1, 2}}) {
      CHECK_FALSE(graph.has_edge(x, y));
      CHECK_FALSE(graph.ordered(x, y));
      CHECK_FALSE(graph.ordered(y, x));
    }
    CHECK(graph.edges().size() == 4);

    for (auto& s : g_stamps) s.start = s.end = -1;
    Model model;
    State state;
    Scratch scratch;
    graph.run(model, state, scratch);
    for (auto [x, y] : graph.edges()) {
      INFO("edge " << graph.system(x).name << " -> " << graph.system(y).name);
      CHECK(g_stamps[x].end < g_stamps[y].start);
    }
    for (int k = 0; k < 5; ++k) CHECK(g_stamps[k].end >= 0);
  }
}

TEST_CASE("independent systems run concurrently with two or more threads") {
  // x and y touch disjoint components. Each announces its start, then waits (up to 10 s) for the
  // other to start: they can both see each other only if the graph runs them at the same time.
  std::atomic<int> started{0};
  std::atomic<int> saw_other{0};
  auto waiter = [&](const Model&, State&, Scratch&, Executor&) {
    ++started;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (started.load() < 2 && std::chrono::steady_clock::now() < deadline) std::this_thread::yield();
    if (started.load() >= 2) ++saw_other;
  };
  std::vector<SystemSpec> systems{
      SystemSpec{"x", 0, mask_of(C::particle_force), waiter},
      SystemSpec{"y", 0, mask_of(C::particle_torque), waiter},
  };
  Executor exec({Backend::tbb, 2});
  StepGraph graph(systems, exec);
  CHECK(graph.edges().empty());
  Model model;
  State state;
  Scratch scratch;
  graph.run(model, state, scratch);
  CHECK(saw_other.load() == 2);
}

TEST_CASE("serial backend runs the systems in reference order") {
  std::vector<int> order;
  std::vector<SystemSpec> systems;
  for (int k = 0; k < 4; ++k)
    systems.push_back(SystemSpec{"s" + std::to_string(k), 0, mask_of(C::particle_force),
                                 [&order, k](const Model&, State&, Scratch&, Executor&) { order.push_back(k); }});
  Executor exec({Backend::serial, 1});
  StepGraph graph(systems, exec);
  Model model;
  State state;
  Scratch scratch;
  graph.run(model, state, scratch);
  CHECK(order == std::vector<int>{0, 1, 2, 3});
  // A write-write chain: consecutive edges only.
  CHECK(graph.edges().size() == 3);
  CHECK(graph.describe().find("s3  after: s2") != std::string::npos);
}
