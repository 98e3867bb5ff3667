// Model only what a scene requires: the step graph holds exactly the systems the model asks for,
// optional arrays are not allocated, and optional measures (the kinetic stress) are not computed
// unless asked.
#include "engine/world.hpp"
#include "systems/catalogue.hpp"
#include "support/scenes.hpp"
#include "systems/homogenizer.hpp"

#include <doctest/doctest.h>

#include <set>
#include <string>

using namespace sandcell;

namespace {

Model base_model() { return test::quartz_model(2e-8, 0.05e-3); }

std::set<std::string> scheduled(const World& world) {
  std::set<std::string> names;
  for (std::size_t k = 0; k < world.graph().size(); ++k) names.insert(std::string(world.graph().system(k).name));
  return names;
}

// A dense jittered lattice (every lattice neighbour touching), moving and spinning.
State dense(const Model& model) {
  return test::jittered_lattice(model, 4, 2e-3, 1.01e-3, 1.03e-3, 0.02e-3, 0.5, 50.0, 3);
}

}  // namespace

TEST_CASE("scene: free flight schedules no contact system and allocates no pair arrays") {
  Model model = base_model();
  model.contact.enabled = false;
  World world(model, dense(model), systems_for(model), ExecutorConfig{Backend::serial});
  world.step(5);
  CHECK(scheduled(world) == std::set<std::string>{"integrate_initial", "wrap", "integrate_final"});
  CHECK(world.state().contacts.size() == 0);
  CHECK(world.state().contacts.forces.force.empty());
  CHECK(world.state().contacts.tangential.empty());
  CHECK(world.state().contacts.rolling.empty());
  CHECK_FALSE(world.state().contacts.has_rolling);
}

TEST_CASE("scene: contacts without rolling, servo or sorting schedule only the contact systems") {
  Model model = base_model();
  model.contact.rolling = RollingModel::none;
  World world(model, dense(model), systems_for(model), ExecutorConfig{Backend::serial});
  world.step(5);
  CHECK(scheduled(world) ==
        std::set<std::string>{"integrate_initial", "broadphase", "contact", "force_gather", "integrate_final"});
  REQUIRE(world.state().contacts.size() > 0);
  CHECK(world.state().contacts.tangential.size() == world.state().contacts.size());
  CHECK(world.state().contacts.rolling.empty());  // no rolling history for a scene without rolling
}

TEST_CASE("scene: each option adds exactly its system") {
  const std::set<std::string> contact = {"integrate_initial", "broadphase", "contact", "force_gather",
                                         "integrate_final"};
  Model model = base_model();
  SUBCASE("rolling resistance: evaluated in the contact pass (no system of its own), history allocated") {
    model.contact.rolling = RollingModel::epsd2;
    World world(model, dense(model), systems_for(model), ExecutorConfig{Backend::serial});
    world.step(5);
    CHECK(scheduled(world) == contact);
    CHECK(world.state().contacts.rolling.size() == world.state().contacts.size());
  }
  SUBCASE("rolling resistance cdt: no stored moment, so no rolling history allocated") {
    model.contact.rolling = RollingModel::cdt;
    World world(model, dense(model), systems_for(model), ExecutorConfig{Backend::serial});
    world.step(5);
    CHECK(scheduled(world) == contact);
    CHECK(world.state().contacts.size() > 0);
    CHECK(world.state().contacts.rolling.empty());
  }
  SUBCASE("spatial sorting") {
    model.contact.sort_interval = 10;
    World world(model, dense(model), systems_for(model), ExecutorConfig{Backend::serial});
    std::set<std::string> expected = contact;
    expected.insert("spatial_sort");
    CHECK(scheduled(world) == expected);
  }
  SUBCASE("the servo brings the homogenizer with it") {
    model.servo.enabled = true;
    model.servo.path = StressPath::isotropic;
    model.servo.control = {AxisControl::stress, AxisControl::stress, AxisControl::stress};
    model.servo.p = 1e6;
    model.servo.gain = 10.0;
    model.servo.max_rate = 1.0;
    World world(model, dense(model), systems_for(model), ExecutorConfig{Backend::serial});
    std::set<std::string> expected = contact;
    expected.insert({"homogenizer", "servo"});
    CHECK(scheduled(world) == expected);
  }
}

TEST_CASE("scene: the kinetic stress is computed only when the servo asks for it") {
  // Fast-moving spheres (100 m/s) make the kinetic part sum m v~ (x) v~ / V a visible share of the
  // stress. The homogenizer measures after the contact law, on the step's positions and forces
  // (which measure() sees unchanged after the step) and the half-step velocities. Without
  // servo.kinetic_stress the measured stress is the contact stress alone.
  for (bool kinetic : {false, true}) {
    CAPTURE(kinetic);
    Model model = base_model();
    model.servo.enabled = true;
    model.servo.path = StressPath::fixed;
    model.servo.kinetic_stress = kinetic;
    model.servo.gain = 10.0;  // every axis strain-controlled (at rate 0): the servo changes nothing
    model.servo.max_rate = 1.0;
    State s = test::jittered_lattice(model, 4, 2e-3, 1.01e-3, 1.03e-3, 0.02e-3, 100.0, 0.0, 5);
    World world(model, std::move(s), systems_for(model), ExecutorConfig{Backend::serial});
    world.step(1);
    REQUIRE(world.scratch().own<MeasuredStress>().step == 0);
    const Mat3 measured = world.scratch().own<MeasuredStress>().stress;
    const Measures contact_only = measure(world.model(), world.state(), world.executor());
    // The kinetic part at the half-step velocities the homogenizer saw: integrate_final has since
    // added F dt / (2m) to each.
    const Particles& p = world.state().particles;
    Mat3 kinetic_part = Mat3::Zero();
    for (std::size_t k = 0; k < p.size(); ++k) {
      const Vec3 v_half = p.velocity[k] - p.force[k] * (0.5 * model.dt / p.mass[k]);
      kinetic_part += p.mass[k] * v_half * v_half.transpose();
    }
    kinetic_part /= world.state().cell.volume();
    REQUIRE(kinetic_part.trace() > 1e-2 * contact_only.stress.trace());  // large enough to see
    // Either way the terms are summed in another order than here (symmetrize, then divide by V, or
    // the reverse; blocked reduction): round-off, 1e-12 of the trace.
    const Mat3 extra = measured - contact_only.stress;
    const Mat3 expected = kinetic ? kinetic_part : Mat3(Mat3::Zero());
    CHECK((extra - expected).cwiseAbs().maxCoeff() < 1e-12 * measured.trace());
  }
}
