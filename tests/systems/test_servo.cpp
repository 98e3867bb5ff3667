// Periodic servo (docs/physics.md section 6): path target formulas against hand-computed values, the control law,
// and closed-loop runs on a small dense sample: isotropic to p0, constant p / constant b, constant
// sigma3 / constant b.
#include "engine/world.hpp"
#include "systems/catalogue.hpp"
#include "support/scenes.hpp"
#include "systems/homogenizer.hpp"
#include "systems/servo.hpp"

#include <doctest/doctest.h>

#include <cmath>

using namespace sandcell;

TEST_CASE("servo path targets: constant p, constant b by hand") {
  ServoSettings s;
  s.path = StressPath::constant_p;
  s.p = 100.0;
  // b = 0 (triaxial compression): s2 = s3 = (3p - s1)/2. With s1 = 160: s2 = s3 = 70.
  s.b = 0.0;
  Vec3 t = path_targets(s, 160.0);
  CHECK(t[1] == 70.0);
  CHECK(t[2] == 70.0);
  // b = 0.5: s3 = (300 - 1.5*160)/1.5 = 40, s2 = (150 + 0)/1.5 = 100; check p = 100 and b = 0.5.
  s.b = 0.5;
  t = path_targets(s, 160.0);
  CHECK(t[2] == doctest::Approx(40.0).epsilon(1e-15));
  CHECK(t[1] == doctest::Approx(100.0).epsilon(1e-15));
  // b = 1 (extension): s2 = s1 = 160, s3 = 300 - 320 = -20: p = (160 + 160 - 20)/3 = 100.
  s.b = 1.0;
  t = path_targets(s, 160.0);
  CHECK(t[1] == doctest::Approx(160.0).epsilon(1e-15));
  CHECK(t[2] == doctest::Approx(-20.0).epsilon(1e-15));
}

TEST_CASE("servo path targets: constant sigma3, constant b by hand") {
  ServoSettings s;
  s.path = StressPath::constant_sigma3;
  s.sigma3 = 50.0;
  for (double b : {0.0, 0.5, 1.0}) {
    s.b = b;
    const Vec3 t = path_targets(s, 170.0);
    CHECK(t[2] == 50.0);
    CHECK(t[1] == doctest::Approx(50.0 + b * 120.0).epsilon(1e-15));  // b = 0: 50, 0.5: 110, 1: 170
  }
  s.path = StressPath::isotropic;
  s.p = 7.0;
  CHECK(path_targets(s, 1.0) == Vec3::Constant(7.0));
}

namespace {
// Axis 1 strain controlled at `axial` 1/s; axes 2 and 3 held at 100 Pa with gain 10 /s, capped at 2 /s.
ServoSettings lateral_servo(double axial) {
  ServoSettings s;
  s.path = StressPath::fixed;
  s.control = {AxisControl::strain, AxisControl::stress, AxisControl::stress};
  s.strain_rate = Vec3(axial, 0.0, 0.0);
  s.target = Vec3(0.0, 100.0, 100.0);
  s.gain = 10.0;
  s.max_rate = 2.0;
  return s;
}
}  // namespace

TEST_CASE("servo control law: proportional, capped, strain-controlled axes untouched") {
  const ServoSettings s = lateral_servo(0.3);
  // Axis 2: error (100 - 95)/100 = 0.05 -> 0.5 1/s (compress). Axis 3: error -0.5 -> -5, capped -2.
  const Vec3 r = servo_strain_rates(s, Vec3(1e9, 95.0, 150.0));
  CHECK(r[0] == 0.3);
  CHECK(r[1] == doctest::Approx(0.5).epsilon(1e-15));
  CHECK(r[2] == -2.0);
}

TEST_CASE("servo control law: the integral term advances by err dt and winds up only inside the cap") {
  ServoSettings s = lateral_servo(0.0);
  s.integral_time = 0.5;
  Vec3 integral(0.0, 0.01, 0.0);
  // Axis 2: err 0.05, I = 0.01 + 0.05 * 0.1 = 0.015, rate 10 (0.05 + 0.015/0.5) = 0.8.
  // Axis 3: err -0.5 saturates (10 x -0.5 = -5 < -2): I stays 0, rate -2.
  const Vec3 r = servo_strain_rates(s, Vec3(1e9, 95.0, 150.0), &integral, 0.1);
  CHECK(integral[1] == doctest::Approx(0.015).epsilon(1e-14));
  CHECK(r[1] == doctest::Approx(0.8).epsilon(1e-14));
  CHECK(integral[2] == 0.0);
  CHECK(r[2] == -2.0);
  // Saturated the other way round with an error that pulls back inside: the integral unwinds.
  integral = Vec3(0.0, 0.0, 2.0);  // 10 x 2/0.5 = 40: far above the cap
  servo_strain_rates(s, Vec3(1e9, 100.0, 110.0), &integral, 0.1);
  CHECK(integral[2] == doctest::Approx(2.0 - 0.1 * 0.1).epsilon(1e-14));
  // Without integral_time, a P law whatever the integral holds.
  s.integral_time = 0.0;
  CHECK(servo_strain_rates(s, Vec3(1e9, 95.0, 100.0), &integral, 0.1)[1] == doctest::Approx(0.5).epsilon(1e-15));
}

TEST_CASE("servo control law: a strain-controlled axis ramps linearly to its rate over ramp_time, then holds it") {
  ServoSettings s = lateral_servo(0.4);
  s.ramp_time = 2.0;
  const Vec3 sigma(1e9, 95.0, 100.0);
  CHECK(servo_strain_rates(s, sigma, nullptr, 0.0, 0.0)[0] == 0.0);
  CHECK(servo_strain_rates(s, sigma, nullptr, 0.0, 0.5)[0] == doctest::Approx(0.1).epsilon(1e-15));
  CHECK(servo_strain_rates(s, sigma, nullptr, 0.0, 2.0)[0] == 0.4);
  CHECK(servo_strain_rates(s, sigma, nullptr, 0.0, 7.0)[0] == 0.4);
  // The stress-controlled axes do not ramp: the servo acts at full gain from the start.
  CHECK(servo_strain_rates(s, sigma, nullptr, 0.0, 0.0)[1] == doctest::Approx(0.5).epsilon(1e-15));
}

namespace {

// A small dense-ish sample: jittered lattice of 6^3 spheres near contact, frictional, with rolling.
struct Sample {
  Model model;
  State state;
};

Sample small_sample() {
  Sample s;
  Material mat;
  mat.young = 70e9;
  mat.poisson = 0.3;
  mat.restitution = 0.5;
  mat.friction = 0.3;
  mat.rolling_friction = 0.1;
  s.model.materials = {mat};
  const double r = 1e-3;
  s.model.dt = 0.2 * rayleigh_time(0.9 * r, mat);
  s.model.contact.skin = 0.1e-3;
  s.state = test::jittered_lattice(s.model, 6, 2.0e-3, 0.9e-3, 1.0e-3, 0.0e-3, 0.0, 0.0, 11);
  return s;
}

Measures run_until(World& world, std::uint64_t steps) {
  world.step(steps);
  return measure(world.model(), world.state(), world.executor());
}

}  // namespace

TEST_CASE("servo closed loop: isotropic compression reaches p0 within 1 % on every axis") {
  Sample s = small_sample();
  s.model.servo.enabled = true;
  s.model.servo.path = StressPath::isotropic;
  s.model.servo.control = {AxisControl::stress, AxisControl::stress, AxisControl::stress};
  s.model.servo.p = 1e6;
  s.model.servo.max_rate = 20.0;
  s.model.servo.gain = 200.0;
  World world(s.model, std::move(s.state), systems_for(s.model), ExecutorConfig{Backend::tbb, 2});
  Measures m = run_until(world, 40000);
  // The servo must hold p0 for a while, not pass through it: check over the last 5000 steps.
  double worst = 0.0;
  for (int k = 0; k < 5; ++k) {
    m = run_until(world, 1000);
    for (int a = 0; a < 3; ++a) worst = std::max(worst, std::abs(m.stress(a, a) - 1e6) / 1e6);
  }
  MESSAGE("isotropic: worst axis error over the last 5000 steps ", worst, ", e = ", m.void_ratio, ", Z = ", m.z,
          ", Z_mech = ", m.z_mech);
  CHECK(worst < 0.01);  // the servo's acceptance criterion: every axis within 1 % of p0
  // A jammed sample, not a gas held at zero stress: a frictional packing is at least isostatic
  // (Z_mech >= 4, the limit of infinite friction) once rattlers are removed.
  CHECK(m.z_mech >= 4.0);
}

namespace {

// Compressed once, shared by the path tests.
const Sample& compressed_sample(double p0) {
  static const Sample sample = [&] {
    Sample s = small_sample();
    s.model.servo.enabled = true;
    s.model.servo.path = StressPath::isotropic;
    s.model.servo.control = {AxisControl::stress, AxisControl::stress, AxisControl::stress};
    s.model.servo.p = p0;
    s.model.servo.max_rate = 20.0;
    s.model.servo.gain = 200.0;
    World world(s.model, std::move(s.state), systems_for(s.model), ExecutorConfig{Backend::tbb, 2});
    world.step(40000);
    s.state = world.state();
    s.state.cell.length0 = s.state.cell.length;
    return s;
  }();
  return sample;
}

// Shears along a path; returns the worst deviations after the first 1 % of axial strain and the
// mean error of p. Samples every 101 steps, so both parities of the step are seen (a servo that
// oscillates with period 2 steps looks steady when sampled on even steps only).
struct Tracking {
  double p = 0.0, b = 0.0, s3 = 0.0;
  double mean_p = 0.0;  // mean (p - p0)/p0 after 1 %
  double eps1 = 0.0;
};

Tracking shear(Sample s, StressPath path, double b, double p0, double max_strain, bool integral = true,
               double gain = 300.0) {
  ServoSettings& v = s.model.servo;
  v.enabled = true;
  v.path = path;
  v.control = {AxisControl::strain, AxisControl::stress, AxisControl::stress};
  const double rate = 1.0;
  v.strain_rate = Vec3(rate, 0.0, 0.0);
  v.p = p0;
  v.sigma3 = p0;
  v.b = b;
  v.gain = gain * rate;
  v.max_rate = 2.0 * rate;
  v.integral_time = integral ? 1000.0 * s.model.dt : 0.0;
  s.state.cell.rate = Vec3(-rate, 0.0, 0.0);
  World world(s.model, std::move(s.state), systems_for(s.model), ExecutorConfig{Backend::tbb, 2}, false);
  Tracking t;
  int rows = 0;
  for (;;) {
    const Measures m = run_until(world, 101);
    t.eps1 = m.strain[0];
    if (t.eps1 > max_strain) break;
    if (t.eps1 < 0.01) continue;
    t.p = std::max(t.p, std::abs(m.inv.p - p0) / p0);
    t.mean_p += (m.inv.p - p0) / p0;
    ++rows;
    t.s3 = std::max(t.s3, std::abs(m.stress(2, 2) - p0) / p0);
    // b of the cell axes (sigma1 = S_xx ...), as the servo controls it.
    const double s1 = m.stress(0, 0), s2 = m.stress(1, 1), s3 = m.stress(2, 2);
    if (s1 - s3 > 0.05 * p0) t.b = std::max(t.b, std::abs((s2 - s3) / (s1 - s3) - b));
  }
  t.mean_p /= std::max(rows, 1);
  return t;
}

}  // namespace

TEST_CASE("servo closed loop: constant p and constant b hold along the path") {
  const double p0 = 1e6;
  const Sample& base = compressed_sample(p0);
  for (double b : {0.0, 0.5, 1.0}) {
    const Tracking t = shear(base, StressPath::constant_p, b, p0, 0.03);
    MESSAGE("constant p, b = ", b, ": worst |dp|/p ", t.p, ", worst |db| ", t.b, " up to eps1 = ", t.eps1);
    CHECK(t.p < 0.02);  // the path's acceptance criteria: p within 2 %,
    CHECK(t.b < 0.02);  // b within 0.02, after the first 1 % of axial strain
  }
}

TEST_CASE("servo closed loop: constant sigma3 and constant b hold along the path") {
  const double p0 = 1e6;
  const Sample& base = compressed_sample(p0);
  for (double b : {0.0, 0.5}) {
    const Tracking t = shear(base, StressPath::constant_sigma3, b, p0, 0.03);
    MESSAGE("constant sigma3, b = ", b, ": worst |dsigma3|/sigma3 ", t.s3, ", worst |db| ", t.b);
    CHECK(t.s3 < 0.02);  // sigma3 within 2 % after the first 1 % of axial strain
    CHECK(t.b < 0.02);
  }
}

TEST_CASE("servo closed loop: the integral term removes the lag of the P law") {
  // While sigma1 climbs, a P law keeps an error ~ (lateral rate)/g. A low gain (50/s: lateral
  // rates ~0.5/s give ~1 % of lag) makes that lag clearly measurable; the PI law at the same gain
  // must remove most of it. Measured values are printed below.
  const double p0 = 1e6;
  const Sample& base = compressed_sample(p0);
  const Tracking p_law = shear(base, StressPath::constant_p, 0.0, p0, 0.03, false, 50.0);
  const Tracking pi_law = shear(base, StressPath::constant_p, 0.0, p0, 0.03, true, 50.0);
  MESSAGE("constant p, b = 0, g = 50/s: mean (p - p0)/p0: P ", p_law.mean_p, ", PI ", pi_law.mean_p);
  REQUIRE(std::abs(p_law.mean_p) > 2e-3);  // the P law lags visibly, or the comparison says nothing
  // PI below a fifth of the P lag: the integral (T_i = 1000 dt, ~0.1 % of the 3 % run) has
  // settled long before the end, so only the rows of the first ~1 % strain keep some lag.
  CHECK(std::abs(pi_law.mean_p) < 0.2 * std::abs(p_law.mean_p));
  CHECK(pi_law.p < 0.02);
}

TEST_CASE("servo: the cap follows the axial rate (max_rate_ratio), the integral time the axial strain (integral_strain)") {
  // Constant sigma3, b = 1, at a set inertial number: the axial rate is I sqrt(p/rho)/d50 from the
  // measured p; sigma3 measured 40 % high asks axis 3 for g x 0.4 = 400 /s of extension.
  ServoSettings s;
  s.enabled = true;
  s.path = StressPath::constant_sigma3;
  s.control = {AxisControl::strain, AxisControl::stress, AxisControl::stress};
  s.sigma3 = 1e6;
  s.b = 1.0;
  s.gain = 1000.0;
  s.strain_rate = Vec3(1.0, 0.0, 0.0);
  s.inertial_number = 1e-3;
  s.d50 = 1e-3;
  s.density = 2500.0;
  s.max_rate = 10.0;
  const Vec3 sigma(9e6, 9e6, 1.4e6);  // p = 6.47 MPa
  const double axial = 1e-3 * std::sqrt(sigma.mean() / 2500.0) / 1e-3;  // 50.9 /s
  CHECK(servo_strain_rates(s, sigma)[0] == doctest::Approx(axial).epsilon(1e-14));
  CHECK(servo_strain_rates(s, sigma)[2] == -10.0);  // the fixed cap: the axis of sigma3 falls behind
  s.max_rate_ratio = 5.0;
  CHECK(servo_strain_rates(s, sigma)[2] == doctest::Approx(-5.0 * axial).epsilon(1e-14));  // 5 x the axial rate
  s.max_rate = 1000.0;
  CHECK(servo_strain_rates(s, sigma)[2] == doctest::Approx(-400.0).epsilon(1e-14));  // inside max(cap, 5 x): g x err
  // The integral term: one update of err over `interval` s adds g err interval / T_i. T_i = 1 s,
  // bounded by integral_strain / axial rate = 1e-3 / 50.9 s.
  s.integral_time = 1.0;
  s.integral_strain = 1e-3;
  Vec3 integral = Vec3::Zero();
  const double interval = 1e-5;
  const Vec3 r = servo_strain_rates(s, sigma, &integral, interval);
  const double t_i = 1e-3 / axial;
  CHECK(integral[2] == doctest::Approx(-0.4 * interval).epsilon(1e-14));
  CHECK(r[2] == doctest::Approx(1000.0 * (-0.4 - 0.4 * interval / t_i)).epsilon(1e-12));
  s.integral_strain = 0.0;  // T_i = 1 s as set
  integral.setZero();
  CHECK(servo_strain_rates(s, sigma, &integral, interval)[2] ==
        doctest::Approx(1000.0 * (-0.4 - 0.4 * interval / 1.0)).epsilon(1e-12));
  s.max_rate_ratio = -1.0;
  CHECK_THROWS_WITH_AS(validate(s), doctest::Contains("servo.max_rate_ratio = -1"), std::invalid_argument);
  s.max_rate_ratio = 0.0;
  s.integral_strain = std::nan("");
  CHECK_THROWS_WITH_AS(validate(s), doctest::Contains("servo.integral_strain"), std::invalid_argument);
}
