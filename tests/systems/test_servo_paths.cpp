// Custom stress paths (docs/physics.md section 6.1): the volume axes' rate against the integrator's
// length update, a custom path that restates a built-in one gives bitwise the same run, the
// undrained path holds eps_v = 0, the cyclic path reverses at its bounds and stops on its count.
#include "engine/world.hpp"
#include "support/scenes.hpp"
#include "systems/catalogue.hpp"
#include "systems/homogenizer.hpp"
#include "systems/servo.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <cstring>

using namespace sandcell;

namespace {

ServoSettings base_servo() {
  ServoSettings s;
  s.enabled = true;
  s.gain = 300.0;
  s.max_rate = 2.0;
  return s;
}

}  // namespace

TEST_CASE("custom path: the volume axes' rate brings the volume back to V0 after `interval` steps of L(1 + D dt)") {
  // The identity the rate is built on: with D_k = -rate_k, n steps of L_k <- L_k + L_k D_k dt
  // (integrate_initial) give V prod (1 + D_k dt)^n; the volume axes' common rate makes it V0.
  // Rounding: about 3 n roundings of relative 1.1e-16 each: 1e-13 relative bounds n = 50.
  PathInput in;
  in.dt = 1e-3;
  in.interval = 50;
  in.length0 = Vec3(1.0, 1.1, 0.9);
  in.length = Vec3(0.97, 1.12, 0.93);  // V / V0 = 1.0326...: a drift to correct, not only to hold
  PathTargets t;
  t.control = {AxisControl::strain, AxisControl::volume, AxisControl::volume};
  t.value = Vec3(0.7, 0.0, 0.0);
  const Vec3 rate = custom_strain_rates(base_servo(), t, in);
  CHECK(rate[0] == 0.7);
  CHECK(rate[1] == rate[2]);
  Vec3 length = in.length;
  for (int k = 0; k < in.interval; ++k) length += length.cwiseProduct(-rate) * in.dt;
  CHECK(std::abs(length.prod() / in.length0.prod() - 1.0) < 1e-13);
  // One volume axis next to a stress axis: the same identity.
  t.control = {AxisControl::stress, AxisControl::strain, AxisControl::volume};
  t.value = Vec3(1e5, -0.3, 0.0);
  in.stress = Mat3::Identity() * 9e4;
  const Vec3 r2 = custom_strain_rates(base_servo(), t, in);
  CHECK(r2[0] == 2.0);  // P law: g (1e5 - 9e4)/1e5 = 300 x 0.1 = 30, capped at max_rate = 2
  length = in.length;
  for (int k = 0; k < in.interval; ++k) length += length.cwiseProduct(-r2) * in.dt;
  CHECK(std::abs(length.prod() / in.length0.prod() - 1.0) < 1e-13);
}

TEST_CASE("custom path: a non-finite answer or an empty function is a clear error") {
  PathInput in;
  in.dt = 1e-3;
  PathTargets t;
  t.control = {AxisControl::strain, AxisControl::stress, AxisControl::stress};
  t.value = Vec3(1.0, std::nan(""), 1.0);
  CHECK_THROWS_WITH_AS(custom_strain_rates(base_servo(), t, in), doctest::Contains("value[1]"), std::invalid_argument);
  ServoSettings s = base_servo();
  s.path = StressPath::custom;
  CHECK_THROWS_WITH_AS(validate(s), doctest::Contains("servo.custom"), std::invalid_argument);
  s.path = StressPath::fixed;
  s.control = {AxisControl::volume, AxisControl::strain, AxisControl::strain};
  CHECK_THROWS_WITH_AS(validate(s), doctest::Contains("servo.control[0] = volume"), std::invalid_argument);
  CyclicSettings c;
  c.lower = 0.0;
  c.upper = -1.0;
  CHECK_THROWS_WITH_AS(CyclicPath{c}, doctest::Contains("cyclic.upper"), std::invalid_argument);
}

namespace {

struct Sample {
  Model model;
  State state;
};

// The small dense sample of test_servo.cpp (6^3 spheres), compressed isotropically to p0.
const Sample& compressed(double p0) {
  static const Sample sample = [&] {
    Sample s;
    Material mat;
    mat.friction = 0.3;
    s.model.materials = {mat};
    s.model.dt = 0.2 * rayleigh_time(0.9e-3, mat);
    s.model.contact.skin = 0.1e-3;
    s.state = test::jittered_lattice(s.model, 6, 2.0e-3, 0.9e-3, 1.0e-3, 0.0, 0.0, 0.0, 11);
    ServoSettings& v = s.model.servo;
    v = base_servo();
    v.path = StressPath::isotropic;
    v.control = {AxisControl::stress, AxisControl::stress, AxisControl::stress};
    v.p = p0;
    v.max_rate = 20.0;
    v.gain = 200.0;
    World world(s.model, std::move(s.state), systems_for(s.model), ExecutorConfig{Backend::tbb, 2});
    // Compressed until every normal stress has been within 1 % of p0 (test_servo.cpp's criterion)
    // at ten checks 1,000 steps apart. Not a fixed step count: this 216-sphere sample, loaded from a
    // loose cloud, buckles on the way (two axes fall to a few kPa from about step 19,000 to 37,000
    // while the third holds p0, then it re-jams: seen with the builds before and after the stress
    // was summed in the contact pass), and where a fixed count (40,000 before) ends relative to that
    // depends on the last bits of the trajectory. Ten, not three: a sample held for three checks
    // had only just re-jammed and lost its axis-3 stress in the cyclic test's first cycle.
    const auto within = [&] {
      const Measures m = measure(world.model(), world.state(), world.executor());
      bool ok = true;
      for (int k = 0; k < 3; ++k) ok = ok && std::abs(m.stress(k, k) - p0) < 0.01 * p0;
      return ok;
    };
    int held = 0;
    for (int chunk = 0; chunk < 100 && held < 10; ++chunk) {
      world.step(1000);
      held = within() ? held + 1 : 0;
    }
    REQUIRE(held == 10);
    s.state = world.state();
    s.state.cell.length0 = s.state.cell.length;
    s.state.clock = {};
    s.state.cell.servo_integral.setZero();
    s.state.cell.rate.setZero();  // each test's path sets the rates from its first servo update on
    return s;
  }();
  return sample;
}

bool same_bits(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(Vec3)) == 0;
}

}  // namespace

TEST_CASE("custom path: a function restating constant p / constant b runs bitwise as the built-in path") {
  const double p0 = 1e6;
  Sample s = compressed(p0);
  ServoSettings& v = s.model.servo;
  v = base_servo();
  v.path = StressPath::constant_p;
  v.control = {AxisControl::strain, AxisControl::stress, AxisControl::stress};
  v.strain_rate = Vec3(1.0, 0.0, 0.0);
  v.p = p0;
  v.b = 0.5;
  v.integral_time = 1000.0 * s.model.dt;
  v.interval = 3;
  s.state.cell.rate = Vec3(-1.0, 0.0, 0.0);
  World builtin(s.model, s.state, systems_for(s.model), ExecutorConfig{Backend::tbb, 2}, false);
  const ServoSettings reference = v;
  v.path = StressPath::custom;
  int calls = 0;
  v.custom = [&](const PathInput& in) {
    ++calls;
    PathTargets t;
    t.control = reference.control;
    t.value = path_targets(reference, in.stress(0, 0));
    t.value[0] = reference.strain_rate[0];
    return t;
  };
  World custom(s.model, s.state, systems_for(s.model), ExecutorConfig{Backend::tbb, 2}, false);
  builtin.step(3000);
  custom.step(3000);
  CHECK(calls == 1000);  // once per servo update (interval 3), never on other steps
  // The error floor differs (1e-3 p here, 1e-3 max(p, |sigma*|) there) but never binds: the
  // targets stay near p0, so every operation is the same and the results are bitwise equal.
  CHECK(same_bits(builtin.state().particles.position, custom.state().particles.position));
  CHECK(builtin.state().cell.length == custom.state().cell.length);
  CHECK(builtin.state().cell.servo_integral == custom.state().cell.servo_integral);
}

TEST_CASE("undrained path: eps_v stays 0 while the sample is sheared at constant volume") {
  const double p0 = 1e6;
  Sample s = compressed(p0);
  s.model.servo = base_servo();
  s.model.servo.path = StressPath::custom;
  s.model.servo.custom = undrained_path(2.0);
  s.model.servo.interval = 5;
  World world(s.model, s.state, systems_for(s.model), ExecutorConfig{Backend::tbb, 2}, false);
  double worst = 0.0, peak_q = 0.0;
  Measures m;
  for (int k = 0; k < 30; ++k) {
    world.step(1000);
    m = measure(world.model(), world.state(), world.executor());
    worst = std::max(worst, std::abs(m.eps_v));
    peak_q = std::max(peak_q, m.inv.q);
  }
  MESSAGE("undrained: eps1 = ", m.strain[0], ", worst |eps_v| = ", worst, ", p = ", m.inv.p, ", q = ", m.inv.q,
          ", peak q = ", peak_q);
  REQUIRE(m.strain[0] > 0.01);  // it was sheared (2/s for 30000 dt)
  // Between updates the volume axes hold V exactly up to rounding (the test above); the measured
  // eps_v = sum ln(L0/L) adds the rounding of three logarithms: 1e-12 is far above both, and far
  // below the 1e-4 a lateral rate 1 % off would give at this strain.
  CHECK(worst < 1e-12);
  CHECK(m.strain[1] == doctest::Approx(m.strain[2]).epsilon(1e-12));  // axisymmetric: one lateral rate
  // Compression loads axis 1: a deviator builds up. This sample is loose (compressed from a cloud),
  // so at constant volume it may then lose p and q (static liquefaction, as loose sand does
  // undrained): the peak, not the end, shows the loading.
  CHECK(peak_q > 0.05 * p0);
}

TEST_CASE("cyclic path: strain-controlled cycles reverse at the bounds and finish after the count") {
  const double p0 = 1e6;
  Sample s = compressed(p0);
  CyclicSettings c;
  c.axial = AxisControl::strain;
  c.lower = -1e-3;
  c.upper = 2e-3;
  c.rate = 1.0;
  c.sigma3 = p0;
  c.cycles = 2;
  const CyclicPath path(c);
  s.model.servo = base_servo();
  s.model.servo.path = StressPath::custom;
  s.model.servo.custom = path;
  s.model.servo.integral_time = 1000.0 * s.model.dt;
  World world(s.model, s.state, systems_for(s.model), ExecutorConfig{Backend::tbb, 2}, false);
  double lo = 0.0, hi = 0.0;
  const std::uint64_t done = world.step_until(200000, [&](Cell& cell, const Clock&) {
    const double eps1 = -std::log(cell.length[0] / cell.length0[0]);
    lo = std::min(lo, eps1);
    hi = std::max(hi, eps1);
    return path.finished();
  });
  MESSAGE("cyclic: ", done, " steps, reversals ", path.reversals(), ", eps1 in [", lo, ", ", hi, "]");
  CHECK(path.finished());
  CHECK(path.cycles() == 2);
  REQUIRE(path.reversals() == 4);
  // Each reversal happens at the first servo update past the bound: eps1 overshoots by at most one
  // update's strain, rate dt interval (interval 1), plus the step the new rate needs to act.
  const double slack = 2.0 * c.rate * s.model.dt;
  CHECK(hi <= c.upper + slack);
  CHECK(hi >= c.upper);
  CHECK(lo >= c.lower - slack);
  CHECK(lo <= c.lower);
  for (std::size_t k = 0; k < 4; ++k) {
    const double bound = k % 2 == 0 ? c.upper : c.lower;
    CHECK(std::abs(path.reversal_strains()[k] - bound) <= slack);
  }
  // Drained: sigma3 held at p0 by the servo.
  const Measures m = measure(world.model(), world.state(), world.executor());
  CHECK(std::abs(m.stress(2, 2) - p0) / p0 < 0.05);
}
