// The adaptive time step (Model::time_step, rule stiffness; docs/physics.md section 4.1): the
// contacts' bound against its analytic value, the leapfrog's stability limit where the bound says,
// and bitwise determinism for any chunking, thread count and restart.
#include "engine/checkpoint.hpp"
#include "engine/world.hpp"
#include "support/scenes.hpp"
#include "support/two_sphere.hpp"
#include "systems/catalogue.hpp"
#include "systems/contact_pass.hpp"
#include "systems/servo.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <numbers>

using namespace sandcell;

namespace {

void check_same(const State& a, const State& b) {
  CHECK(first_difference(a.particles, b.particles) == "");
  CHECK(first_difference(a.contacts, b.contacts) == "");
  CHECK(a.cell.length == b.cell.length);
  CHECK(a.clock.step == b.clock.step);
  CHECK(a.clock.time == b.clock.time);
  CHECK(a.clock.dt == b.clock.dt);
}

// E* and G* of one material with itself (docs/physics.md section 2).
double e_star(const Material& m) { return m.young / (2.0 * (1.0 - m.poisson * m.poisson)); }
double g_star(const Material& m) { return m.young / (2.0 * (1.0 + m.poisson)) / (2.0 * (2.0 - m.poisson)); }

// Four equal spheres on a ring along x (a periodic cell 4 (2R - delta) long), each overlapping its
// two neighbours by delta, the linear (hooke) law without damping (restitution 1) or friction:
// a chain of masses m and springs k whose fastest mode (neighbours in antiphase) has omega^2 = 4 k / m.
// The contacts' bound is sqrt(m / 2k) (each sphere's two springs), and the leapfrog is stable for
// omega dt < 2, i.e. dt < sqrt(m / k) = sqrt 2 x the bound: the Gershgorin estimate is attained.
struct Ring {
  Model model;
  State state;
  double k = 0.0, m = 0.0;
};
Ring ring(double velocity) {
  test::TwoSphere s;
  s.restitution = 1.0;
  s.friction = 0.0;
  Ring r;
  r.model = test::two_sphere_model(s);
  const double delta = 1e-3 * s.radius;
  const double pitch = 2.0 * s.radius - delta;
  r.state.cell.length = r.state.cell.length0 = Vec3(4.0 * pitch, 20.0 * s.radius, 20.0 * s.radius);
  for (int k = 0; k < 4; ++k) {
    add_sphere(r.state, r.model, static_cast<ParticleId>(k), Vec3((k + 0.5) * pitch, 10.0 * s.radius, 10.0 * s.radius),
               s.radius, 0);
    r.state.particles.velocity[k] = Vec3(k % 2 == 0 ? velocity : -velocity, 0.0, 0.0);  // the antiphase mode
  }
  r.m = r.state.particles.mass[0];
  const Material& mat = r.model.materials[0];
  const double r_star = 0.5 * s.radius, m_star = 0.5 * r.m;
  const double sqrt_r = std::sqrt(r_star);  // hooke.hpp: k_n at the characteristic velocity
  r.k = 16.0 / 15.0 * sqrt_r * e_star(mat) *
        std::pow(15.0 * m_star * s.v_char * s.v_char / (16.0 * sqrt_r * e_star(mat)), 0.2);
  return r;
}

// The largest kinetic energy over n steps, relative to the first.
double kinetic_growth(World& w, int n) {
  const auto kinetic = [&] {
    double e = 0.0;
    for (std::size_t k = 0; k < w.state().particles.size(); ++k)
      e += 0.5 * w.state().particles.mass[k] * w.state().particles.velocity[k].squaredNorm();
    return e;
  };
  const double e0 = kinetic();
  double worst = 0.0;
  for (int k = 0; k < n; ++k) {
    try {
      w.step(1);
    } catch (const SimulationError&) {  // blown up so far that a system stopped it
      return HUGE_VAL;
    }
    worst = std::max(worst, kinetic() / e0);
  }
  return worst;
}

Model lattice_model(int interval) {
  Model model = test::quartz_model(1e-7, 0.3e-3);
  model.time_step = TimeStepSettings{TimeStepRule::stiffness, 0.8, interval, 1e-6};
  model.servo.enabled = true;
  model.servo.path = StressPath::constant_p;
  model.servo.control = {AxisControl::strain, AxisControl::stress, AxisControl::stress};
  model.servo.strain_rate = Vec3(20.0, 0.0, 0.0);
  model.servo.p = 1e6;
  model.servo.b = 0.5;
  model.servo.gain = 200.0;
  model.servo.max_rate = 50.0;
  model.servo.interval = 3;
  model.servo.gain_time = 2e-8;  // below the step: the gain follows it
  return model;
}

State stepped(const Model& model, const State& s, const std::vector<std::uint64_t>& calls, ExecutorConfig exec) {
  World w(model, s, systems_for(model), exec);
  for (std::uint64_t n : calls) w.step(n);
  return w.state();
}

}  // namespace

TEST_CASE("the contacts' stable step of two touching Hertz spheres is the analytic sqrt(m / k') or sqrt(I / k_t r^2)") {
  test::TwoSphere s;
  s.normal = "hertz";
  s.v_n = 0.0;
  const double delta = 2e-3 * s.radius;
  s.gap = -delta;  // overlapping by delta, at rest
  for (const double friction : {0.0, 0.5}) {
    INFO("friction " << friction);
    s.friction = friction;
    const Model model = test::two_sphere_model(s);
    World w(model, test::two_sphere_state(model, s), systems_for(model), ExecutorConfig{Backend::serial});
    const StableStepBound b = contact_stable_step(w.model(), w.state());
    const Material& mat = model.materials[0];
    const double m = w.state().particles.mass[0];
    const double a = std::sqrt(0.5 * s.radius * delta);  // contact radius sqrt(R* delta), R* = R / 2
    const double k_normal = 2.0 * e_star(mat) * a;        // dF_n / d delta of F_n = 4/3 E* sqrt(R*) delta^1.5
    const double k_t = 8.0 * g_star(mat) * a;
    // Frictionless: only the normal spring, along x (K_x = k'). With friction the tangential spring
    // acts on the rotation about y and z with lever R: K_rot = k_t R^2 against I = 2/5 m R^2, which
    // beats the normal mode (k_t / k' = 4 G* / E* = 0.82 at nu = 0.3, and 0.4 / 0.82 < 1).
    const double expected = friction == 0.0 ? std::sqrt(m / k_normal) : std::sqrt(0.4 * m / k_t);
    // Same formula, other order of operations: rounding only (1e-12).
    CHECK(b.step == doctest::Approx(expected).epsilon(1e-12));
    CHECK(b.rotational == (friction > 0.0));
  }
}

TEST_CASE("the leapfrog is stable below sqrt 2 x the contacts' bound and unstable above it (linear ring)") {
  const Ring r = ring(1e-4);
  Model adaptive = r.model;
  adaptive.time_step = TimeStepSettings{TimeStepRule::stiffness, 1.3, 10, 1.0};
  World w(adaptive, r.state, systems_for(adaptive), ExecutorConfig{Backend::serial});
  // The bound is sqrt(m / 2k) (rounding: the overlap comes from positions, 1e-9 of it from its
  // subtraction at this delta; k_n does not depend on it for hooke).
  const double bound = std::sqrt(r.m / (2.0 * r.k));
  CHECK(w.model().dt == doctest::Approx(1.3 * bound).epsilon(1e-9));
  CHECK(w.state().clock.dt == w.model().dt);
  // omega dt = 2 x 1.3 / sqrt 2 = 1.84 < 2: bounded. The kinetic energy of an undamped stable
  // leapfrog oscillation returns to (never exceeds by more than rounding) its value at the node.
  CHECK(kinetic_growth(w, 2000) < 1.0 + 1e-6);
  // A fixed step 5 % above sqrt 2 x the bound: |lambda| = 1.4 per step, so 200 steps amplify the
  // energy by more than 1e20 unless the contacts open first (they do: the spheres then fly apart
  // with more energy than they started with).
  Model fixed = r.model;
  fixed.dt = 1.05 * std::sqrt(2.0) * bound;
  World u(fixed, r.state, systems_for(fixed), ExecutorConfig{Backend::serial});
  CHECK(kinetic_growth(u, 200) > 10.0);
  // And 5 % below it stays bounded (the limit is where the bound puts it, not lower).
  fixed.dt = 0.95 * std::sqrt(2.0) * bound;
  World v(fixed, r.state, systems_for(fixed), ExecutorConfig{Backend::serial});
  CHECK(kinetic_growth(v, 2000) < 1.0 + 1e-6);
}

TEST_CASE("the stiffness step is bitwise the same for any chunking of the calls, thread count and backend") {
  const Model model = lattice_model(7);
  const State s = test::jittered_lattice(model, 10, 2e-3, 1.00e-3, 1.03e-3, 0.02e-3, 1.0, 500.0, 7);
  const State one = stepped(model, s, {300}, ExecutorConfig{Backend::tbb, 2});
  std::vector<std::uint64_t> singles(300, 1);
  check_same(one, stepped(model, s, singles, ExecutorConfig{Backend::tbb, 2}));
  check_same(one, stepped(model, s, {7, 1, 100, 2, 190}, ExecutorConfig{Backend::tbb, 3}));
  check_same(one, stepped(model, s, {300}, ExecutorConfig{Backend::serial}));
  // It did adapt: the step moved away from the cap and from its first value as the lattice sheared.
  World w(model, s, systems_for(model), ExecutorConfig{Backend::serial});
  const double first = w.model().dt;
  CHECK(first < model.time_step.max_dt);
  w.step(300);
  CHECK(w.model().dt != first);
  CHECK(w.model().dt == one.clock.dt);
}

TEST_CASE("a run restarted between updates of the stiffness step continues bitwise (state and checkpoint)") {
  const Model model = lattice_model(20);
  const State s = test::jittered_lattice(model, 8, 2e-3, 1.00e-3, 1.03e-3, 0.02e-3, 1.0, 500.0, 11);
  const State straight = stepped(model, s, {153}, ExecutorConfig{Backend::tbb, 2});
  World first(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
  first.step(53);  // the step in effect was set at step 40, the next update is at 60
  const auto path = std::filesystem::temp_directory_path() / "sandcell_test_time_step.h5";
  write_checkpoint(path, first.state());
  const State back = read_checkpoint(path);
  std::filesystem::remove(path);
  CHECK(back.clock.dt == first.state().clock.dt);
  World second(model, back, systems_for(model), ExecutorConfig{Backend::tbb, 1}, false);
  CHECK(second.model().dt == first.model().dt);
  second.step(100);
  check_same(second.state(), straight);
}

TEST_CASE("the adaptive step's settings are checked, naming the key") {
  test::TwoSphere s;
  const Model base = test::two_sphere_model(s);
  const State state = test::two_sphere_state(base, s);
  const auto message = [&](const Model& m) {
    try {
      World w(m, state, systems_for(m), ExecutorConfig{Backend::serial});
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  Model m = base;
  m.time_step = TimeStepSettings{TimeStepRule::stiffness, 1.5, 10, 1e-6};
  CHECK(message(m).find("time_step.safety = 1.5") != std::string::npos);
  m.time_step = TimeStepSettings{TimeStepRule::stiffness, 0.8, 0, 1e-6};
  CHECK(message(m).find("time_step.interval = 0") != std::string::npos);
  m.time_step = TimeStepSettings{TimeStepRule::stiffness, 0.8, 10, 0.0};
  CHECK(message(m).find("time_step.max_dt") != std::string::npos);
  m.time_step = TimeStepSettings{TimeStepRule::stiffness, 0.8, 10, 1e-6};
  m.contact.enabled = false;  // nothing bounds the step
  CHECK(message(m).find("no scheduled system bounds the step") != std::string::npos);
  m = base;
  m.time_step = TimeStepSettings{TimeStepRule::stiffness, 0.8, 10, 1e-6};
  CHECK(message(m) == "");
  // Apart (the spheres start 0 apart, approaching): no contact bounds the step, so it is the cap.
  World w(m, state, systems_for(m), ExecutorConfig{Backend::serial});
  CHECK(w.model().dt == 1e-6);
}

TEST_CASE("the servo's gain follows a step longer than gain_time (loop gain per step g x gain_time)") {
  ServoSettings servo;
  servo.enabled = true;
  servo.path = StressPath::constant_p;
  servo.control = {AxisControl::strain, AxisControl::stress, AxisControl::stress};
  servo.p = 1e6;
  servo.b = 0.0;
  servo.gain = 100.0;
  servo.max_rate = 1e9;
  Mat3 stress = Mat3::Zero();
  stress.diagonal() = Vec3(1.2e6, 0.9e6, 0.9e6);
  const double dt = 1e-6;
  const Vec3 plain = servo_rates(servo, stress, nullptr, dt).axial;
  servo.gain_time = 2e-6;  // above the step: no change, bitwise
  CHECK(servo_rates(servo, stress, nullptr, dt).axial == plain);
  servo.gain_time = 0.25e-6;  // a quarter of the step: a quarter of the rates (the P law is linear in g)
  const Vec3 scaled = servo_rates(servo, stress, nullptr, dt).axial;
  for (int k = 1; k < 3; ++k) CHECK(scaled[k] == doctest::Approx(0.25 * plain[k]).epsilon(1e-14));
}
