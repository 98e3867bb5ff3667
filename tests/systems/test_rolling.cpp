// Rolling resistance (docs/physics.md section 3, Ai et al. 2011; evaluated inside the contact pass): epsd2 (spring k_t R*^2, capped at mu_r R* |F_n|),
// epsd (spring 2.25 k_n mu_r^2 R*^2 plus a dashpot below the cap), cdt (constant torque), none.
//
// Scene: two identical spheres held at a fixed overlap along x (n = -x, from sphere 1 to sphere 0,
// which is i of the pair), stepped by the contact systems only (no integrator), with opposite spins
// w_0 = +w z, w_1 = -w z. The contact points then have no relative velocity (c_0 w_0 + c_1 w_1 = 0
// exactly: equal radii), so there is no tangential force; the relative rolling velocity is
// w_r = w_0 - w_1 = 2 w z and the rolling angle grows as theta = 2 w t.
#include "engine/world.hpp"
#include "support/scenes.hpp"
#include "systems/broadphase.hpp"
#include "systems/force_gather.hpp"
#include "systems/contact_pass.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <string>

using namespace sandcell;

namespace {

constexpr double k_radius = 1e-3;  // m
constexpr double k_delta = 1e-6;   // m, overlap held
constexpr double k_mu_r = 0.1;     // rolling friction
constexpr double k_eps = std::numeric_limits<double>::epsilon();

Model rolling_model(RollingModel rolling, double dt, double eta_r = 0.0, double mu_r = k_mu_r) {
  Model m;
  m.dt = dt;
  Material mat;           // E = 70 GPa, nu = 0.3, rho = 2650
  mat.restitution = 1.0;  // no normal dashpot: F_n = k_n delta exactly
  mat.friction = 0.5;
  mat.rolling_friction = mu_r;
  m.materials.push_back(mat);
  m.contact.rolling = rolling;
  m.contact.rolling_damping = eta_r;
  return m;
}

std::vector<SystemSpec> contact_systems() {
  return {make_system<Broadphase>(), make_system<ContactPass>(), make_system<ForceGather>()};
}

struct Setup {
  State state;
  double delta, r_star, k_n, k_t, f_n, mass;
};

Setup held_pair(const Model& model, double w) {
  Setup s;
  const double L = 16.0 * k_radius;
  s.state.cell.length = s.state.cell.length0 = Vec3::Constant(L);
  const Vec3 c = Vec3::Constant(L / 2.0);
  const double a = k_radius - k_delta / 2.0;
  add_sphere(s.state, model, 0, c - Vec3(a, 0, 0), k_radius, 0);
  add_sphere(s.state, model, 1, c + Vec3(a, 0, 0), k_radius, 0);
  s.state.particles.angular_velocity[0] = Vec3(0, 0, w);
  s.state.particles.angular_velocity[1] = Vec3(0, 0, -w);
  // Expected constants, from docs/physics.md section 2 (not from the engine).
  const Material& mat = model.materials[0];
  const double e_star = 1.0 / (2.0 * (1.0 - mat.poisson * mat.poisson) / mat.young);
  const double g_star = 1.0 / (2.0 * (2.0 - mat.poisson) / mat.shear());
  s.delta = 2.0 * k_radius - (s.state.particles.position[0] - s.state.particles.position[1]).norm();
  s.r_star = k_radius / 2.0;
  s.k_n = 4.0 / 3.0 * e_star * std::sqrt(s.r_star * s.delta);
  s.k_t = 8.0 * g_star * std::sqrt(s.r_star * s.delta);
  s.f_n = s.k_n * s.delta;
  s.mass = s.state.particles.mass[0];
  return s;
}

// Rolling torque on sphere 0 (the moment M enters as T_i -= M): its z component, after checking
// that the pair carries no tangential force and the torques are equal and opposite along z.
double torque_z(const World& world) {
  const State& st = world.state();
  REQUIRE(st.contacts.size() == 1);
  const Vec3 f = st.contacts.forces.force[0];
  CHECK(f.y() == 0.0);
  CHECK(f.z() == 0.0);
  const Vec3 t0 = st.particles.torque[0], t1 = st.particles.torque[1];
  CHECK(t0 == -t1);
  CHECK(t0.x() == 0.0);
  CHECK(t0.y() == 0.0);
  return t0.z();
}

}  // namespace

TEST_CASE("epsd2: the rolling torque grows as k_r theta, k_r = k_t R*^2, holds at mu_r R* F_n and unloads with k_r") {
  // mu_r = 0.1 (the study's), and the extreme 1 (a cap of R* F_n, reached 10x later).
  for (const double mu_r : {k_mu_r, 1.0}) {
    CAPTURE(mu_r);
    const double w = 1.0, dt = 1e-7;  // theta grows by 2 w dt = 2e-7 rad per step
    const Model model = rolling_model(RollingModel::epsd2, dt, 0.0, mu_r);
    Setup s = held_pair(model, w);
    const double k_r = s.k_t * s.r_star * s.r_star;
    const double cap = mu_r * s.r_star * s.f_n;
    const int scale = static_cast<int>(std::lround(mu_r / k_mu_r));  // steps to the cap scale with mu_r
    // Cap reached at theta = mu_r F_n / (k_t R*) = mu_r (E* / 6 G*) delta / R* = 1.6e-4 rad (mu_r
    // 0.1): 810 steps; 8100 at mu_r = 1.
    World world(model, s.state, contact_systems(), ExecutorConfig{Backend::tbb, 2});
    CHECK(world.state().contacts.has_rolling);
    CHECK(torque_z(world) == 0.0);  // setup does not advance the history
    const int n1 = 300;
    world.step(n1);
    // Tolerance: theta is a sum of n equal increments (n roundings of 2^-53) and k_r a few operations.
    CHECK(torque_z(world) == doctest::Approx(-k_r * 2.0 * w * n1 * dt).epsilon(4.0 * n1 * k_eps));
    CHECK(world.state().contacts.rolling[0].z() == doctest::Approx(k_r * 2.0 * w * n1 * dt).epsilon(4.0 * n1 * k_eps));
    // The normal force is untouched by rolling.
    CHECK(world.state().contacts.forces.force[0].x() == doctest::Approx(-s.f_n).epsilon(1e-13));
    world.step(700 * scale + 300 * (scale - 1));  // theta = 2e-4 rad (2e-3 at mu_r = 1): past the cap
    CHECK(torque_z(world) == doctest::Approx(-cap).epsilon(1e-13));
    world.step(500);
    CHECK(torque_z(world) == doctest::Approx(-cap).epsilon(1e-13));  // it holds
    // Reverse the spins: the moment was reset to the cap, so it unloads at once with slope k_r.
    world.state().particles.angular_velocity[0] = Vec3(0, 0, -w);
    world.state().particles.angular_velocity[1] = Vec3(0, 0, w);
    const int n2 = 200;
    world.step(n2);
    CHECK(torque_z(world) == doctest::Approx(-(cap - k_r * 2.0 * w * n2 * dt)).epsilon(4.0 * n2 * k_eps));
    // Twisting (relative spin about n) is removed from w_r: adding opposite x spins changes nothing.
    const double before = torque_z(world);
    world.state().particles.angular_velocity[0].x() = 3.0;
    world.state().particles.angular_velocity[1].x() = -3.0;
    world.step(1);
    CHECK(torque_z(world) == doctest::Approx(before + k_r * 2.0 * w * dt).epsilon(4.0 * (n2 + 1) * k_eps));
  }
}

TEST_CASE("epsd2 with mu_r = 0: the cap is zero, so no rolling torque ever, only the history is kept") {
  const Model model = rolling_model(RollingModel::epsd2, 1e-7, 0.0, 0.0);
  Setup s = held_pair(model, 1.0);
  World world(model, s.state, contact_systems(), ExecutorConfig{Backend::tbb, 2});
  for (int k = 0; k < 20; ++k) {
    world.step(50);
    CHECK(torque_z(world) == 0.0);
  }
}

TEST_CASE(
    "epsd: spring k_r = 2.25 k_n mu_r^2 R*^2 with the same cap, and a dashpot eta_r 2 sqrt(I_r k_r) only below it") {
  // Cap at theta = mu_r R* F_n / k_r = delta / (2.25 mu_r R*) = 8.9e-3 rad; 2 w dt = 2e-5 rad/step.
  const double w = 10.0, dt = 1e-6;
  for (double eta_r : {0.0, 0.3}) {
    INFO("eta_r = " << eta_r);
    const Model model = rolling_model(RollingModel::epsd, dt, eta_r);
    Setup s = held_pair(model, w);
    const double k_r = 2.25 * s.k_n * k_mu_r * k_mu_r * s.r_star * s.r_star;
    const double cap = k_mu_r * s.r_star * s.f_n;
    const double mr2 = s.mass * k_radius * k_radius;
    const double i_r = 1.4 * mr2 * mr2 / (mr2 + mr2);  // 1.4 (m R^2)_i (m R^2)_j / sum
    const double c_r = eta_r * 2.0 * std::sqrt(i_r * k_r);
    World world(model, s.state, contact_systems(), ExecutorConfig{Backend::tbb, 2});
    const int n1 = 200;  // theta = 4e-3 rad
    world.step(n1);
    const double expected = k_r * 2.0 * w * n1 * dt + c_r * 2.0 * w;
    CHECK(torque_z(world) == doctest::Approx(-expected).epsilon(4.0 * n1 * k_eps));
    if (eta_r > 0.0) CHECK(c_r * 2.0 * w > 0.01 * expected);  // the dashpot part is visible
    world.step(400);                                          // theta = 1.2e-2 rad: on the cap, no dashpot
    CHECK(torque_z(world) == doctest::Approx(-cap).epsilon(1e-13));
  }
}

TEST_CASE("cdt: the torque is mu_r k_n delta R* against w_r at once, and flips with it") {
  const double w = 0.5, dt = 1e-7;
  const Model model = rolling_model(RollingModel::cdt, dt);
  Setup s = held_pair(model, w);
  const double m_cdt = k_mu_r * s.k_n * s.delta * s.r_star;
  World world(model, s.state, contact_systems(), ExecutorConfig{Backend::tbb, 2});
  // Constant directional torque: no history, so it is there from the setup evaluation on.
  CHECK(torque_z(world) == doctest::Approx(-m_cdt).epsilon(1e-13));
  world.step(1);
  CHECK(torque_z(world) == doctest::Approx(-m_cdt).epsilon(1e-13));
  world.step(100);
  CHECK(torque_z(world) == doctest::Approx(-m_cdt).epsilon(1e-13));
  // A w_r in another direction (about y): the torque follows it, same magnitude.
  world.state().particles.angular_velocity[0] = Vec3(0, 2.0 * w, 0);
  world.state().particles.angular_velocity[1] = Vec3(0, -2.0 * w, 0);
  world.step(1);
  const Vec3 t0 = world.state().particles.torque[0];
  CHECK(t0.y() == doctest::Approx(-m_cdt).epsilon(1e-13));
  CHECK(t0.z() == 0.0);
  // No relative rolling: no torque.
  world.state().particles.angular_velocity[0].setZero();
  world.state().particles.angular_velocity[1].setZero();
  world.step(1);
  CHECK(world.state().particles.torque[0] == Vec3::Zero());
}

TEST_CASE("rolling none: no history allocated, no rolling torque") {
  Model model = rolling_model(RollingModel::none, 1e-7);
  Setup s = held_pair(model, 1.0);
  World world(model, s.state, contact_systems(), ExecutorConfig{Backend::tbb, 2});
  CHECK_FALSE(world.state().contacts.has_rolling);
  CHECK(world.state().contacts.rolling.empty());
  world.step(10);
  CHECK(world.state().contacts.rolling.empty());
  // Opposite spins at a fixed overlap: no tangential force, and no rolling resistance either.
  CHECK(torque_z(world) == 0.0);
  // With a rolling model the same scene does get a torque.
  Model with = rolling_model(RollingModel::epsd2, 1e-7);
  World w2(with, held_pair(with, 1.0).state, contact_systems(), ExecutorConfig{Backend::tbb, 2});
  CHECK(w2.state().contacts.has_rolling);
  w2.step(10);
  CHECK(w2.state().contacts.rolling.size() == 1);
  CHECK(torque_z(w2) < 0.0);
}
