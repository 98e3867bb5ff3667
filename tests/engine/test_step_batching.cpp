// World::step(n) leaves the final half kick of each step but the last to the next step's
// integrate_initial (Scratch::defer_final_kick). That is an optimization, not a change of the
// scheme: n steps in one call must give bitwise the state of n calls of step(1), in every scene
// the deferral applies to, and it must not apply where a system reads the velocities between the
// two kicks.
#include "engine/world.hpp"
#include "systems/catalogue.hpp"
#include "support/scenes.hpp"
#include "systems/integrate.hpp"

#include <doctest/doctest.h>

using namespace sandcell;

namespace {

State stepped(const Model& model, const State& s, const std::vector<std::uint64_t>& calls, int threads,
              bool* deferred = nullptr) {
  World w(model, s, systems_for(model), ExecutorConfig{Backend::tbb, threads});
  if (deferred) *deferred = w.defers_work();
  for (std::uint64_t n : calls) {
    w.step(n);
    CHECK_FALSE(kick_pending(w.scratch()));  // never left pending between calls
  }
  return w.state();
}

void check_same(const State& a, const State& b) {
  CHECK(first_difference(a.particles, b.particles) == "");
  CHECK(first_difference(a.contacts, b.contacts) == "");
  CHECK(a.cell.length == b.cell.length);
  CHECK(a.cell.rate == b.cell.rate);
  CHECK(a.clock.step == b.clock.step);
}

// A system that records the kinetic energy at the end of each step: it must see end-of-step
// velocities, so integrate_final must kick before it.
std::vector<double> energy;
struct Observer {
  static constexpr std::string_view name = "observer";
  static constexpr ComponentMask reads = mask_of({Component::particle_velocity, Component::particle_mass});
  static constexpr ComponentMask writes = 0;
  static void run(const Model&, State& state, Scratch&, Executor&) {
    const auto& v = state.read<Component::particle_velocity>();
    const auto& m = state.read<Component::particle_mass>();
    double e = 0.0;
    for (std::size_t k = 0; k < v.size(); ++k) e += 0.5 * m[k] * v[k].squaredNorm();
    energy.push_back(e);
  }
};

}  // namespace

TEST_CASE(
    "step(n) in one call is bitwise n calls of step(1): contacts with rolling, deforming cell, servo with kinetic stress") {
  struct Config {
    const char* name;
    bool servo;
    int sort_interval;
  };
  const Config configs[] = {{"contacts, fixed strain rate", false, 0},
                            {"contacts, servo measuring every 3rd step with the kinetic part, spatial sort", true, 50}};
  for (const Config& c : configs) {
    INFO(c.name);
    Model model = test::quartz_model(1e-7, 0.3e-3);
    model.contact.sort_interval = c.sort_interval;
    // Random velocities and spins, so the kicks and the kinetic stress are not trivially zero.
    State s = test::jittered_lattice(model, 10, 2e-3, 1.00e-3, 1.03e-3, 0.02e-3, 1.0, 500.0, 7);
    if (c.servo) {
      model.servo.enabled = true;
      model.servo.path = StressPath::constant_p;
      model.servo.control = {AxisControl::strain, AxisControl::stress, AxisControl::stress};
      model.servo.strain_rate = Vec3(20.0, 0.0, 0.0);
      model.servo.p = 1e6;
      model.servo.b = 0.5;
      model.servo.gain = 200.0;
      model.servo.max_rate = 50.0;
      model.servo.interval = 3;
      model.servo.kinetic_stress = true;
    } else {
      s.cell.rate = Vec3(-30.0, 15.0, 15.0);
    }
    bool deferred = false;
    const State one_call = stepped(model, s, {300}, 2, &deferred);
    CHECK(deferred);  // the scenes build_systems makes all defer
    // The reference: one step per call, so no kick is ever deferred.
    std::vector<std::uint64_t> singles(300, 1);
    const State single_steps = stepped(model, s, singles, 2);
    CHECK(one_call.particles.velocity != s.particles.velocity);
    check_same(one_call, single_steps);
    // Uneven batches, another thread count and the serial backend.
    check_same(stepped(model, s, {7, 1, 100, 2, 190}, 3), single_steps);
    World serial(model, s, systems_for(model), ExecutorConfig{Backend::serial});
    serial.step(300);
    check_same(serial.state(), single_steps);
  }
}

TEST_CASE("the final kick is not deferred when a system after integrate_final reads the velocities") {
  Model model;
  model.dt = 1e-5;
  model.materials.push_back(Material{});
  model.contact.enabled = false;
  const State s = test::random_gas(model, 50, 0.2, 1e-3, 2e-3, 1.0, 50.0, 3);
  State forced = s;
  for (std::size_t k = 0; k < forced.particles.size(); ++k) forced.particles.force[k] = Vec3(1e-3, -2e-3, 0.5e-3);
  auto run = [&](std::uint64_t calls, std::uint64_t per_call) {
    energy.clear();
    World w(model, forced, {make_system<IntegrateInitial>(), make_system<IntegrateFinal>(), make_system<Observer>()},
            ExecutorConfig{Backend::tbb, 2});
    CHECK_FALSE(w.defers_work());
    for (std::uint64_t c = 0; c < calls; ++c) w.step(per_call);
    return energy;
  };
  const std::vector<double> batched = run(1, 20);
  const std::vector<double> single = run(20, 1);
  REQUIRE(batched.size() == 20);
  CHECK(batched == single);
  // The forces accelerate every sphere, so each step's energy differs from the last: an observer
  // that saw half-kicked velocities would have recorded other values.
  for (std::size_t k = 1; k < batched.size(); ++k) CHECK(batched[k] != batched[k - 1]);
}
