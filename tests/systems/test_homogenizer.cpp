// Stress homogenizer and state measures (docs/physics.md section 5): the Love-Weber stress of a strained
// simple-cubic lattice against the analytic Hertz value, symmetry, the virial of an independent
// brute-force force computation, and the derived measures (invariants, Lode angle, void ratio,
// coordination, rattlers).
#include "engine/world.hpp"
#include "systems/catalogue.hpp"
#include "support/scenes.hpp"
#include "systems/homogenizer.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <numbers>
#include <optional>

using namespace sandcell;

namespace {

Model elastic_model() { return test::quartz_model(1e-8, 0.05e-3); }

// E* of two identical spheres: 1/E* = 2 (1 - nu^2)/E.
double e_star(const Material& m) { return m.young / (2.0 * (1.0 - m.poisson * m.poisson)); }

}  // namespace

TEST_CASE("homogenizer: strained simple-cubic lattice gives the analytic Hertz stress") {
  // n^3 spheres of radius R on a lattice with spacing a_k = 2R - delta_k per axis: each sphere
  // touches its 6 axis neighbours with overlap delta_k, force F_k = 4/3 E* sqrt(R* delta_k) delta_k
  // (R* = R/2), and the cell holds n^3 contacts per axis with branch a_k, so
  // sigma_kk = n^3 F_k a_k / (n^3 a_1 a_2 a_3) = F_k / (a_l a_m); off-diagonals are zero.
  const Model model = elastic_model();
  const double r = 1e-3;
  const Vec3 delta(2e-6, 1e-6, 0.5e-6);
  const int n = 4;
  State s;
  Vec3 a;
  for (int k = 0; k < 3; ++k) a[k] = 2.0 * r - delta[k];
  s.cell.length = s.cell.length0 = a * n;
  ParticleId id = 0;
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x)
        add_sphere(s, model, id++, Vec3((x + 0.5) * a[0], (y + 0.5) * a[1], (z + 0.5) * a[2]), r, 0);
  World world(model, std::move(s), systems_for(model), ExecutorConfig{Backend::serial});
  const Measures m = measure(world.model(), world.state(), world.executor());
  const double es = e_star(model.materials[0]);
  for (int k = 0; k < 3; ++k) {
    const double force = 4.0 / 3.0 * es * std::sqrt(0.5 * r * delta[k]) * delta[k];
    const double expected = force * a[k] / (a[0] * a[1] * a[2]);
    // Round-off only: one overlap is 2R - |branch| with |branch| ~ 2R, so delta carries a relative
    // error of ~eps 2R/delta = 2.2e-16 * 4e3 ~ 1e-12; the 1.5 power makes it 1.5e-12. 1e-9 leaves room.
    CHECK(m.stress(k, k) == doctest::Approx(expected).epsilon(1e-9));
  }
  CHECK(std::abs(m.stress(0, 1)) < 1e-9 * m.stress(0, 0));
  CHECK(std::abs(m.stress(0, 2)) < 1e-9 * m.stress(0, 0));
  CHECK(std::abs(m.stress(1, 2)) < 1e-9 * m.stress(0, 0));
  CHECK(m.contacts == static_cast<std::size_t>(3 * n * n * n));
  CHECK(m.z == doctest::Approx(6.0));
  CHECK(m.z_mech == doctest::Approx(6.0));
  CHECK(m.rattlers == 0);
  // Fabric of an axis-aligned lattice: 1/3 on the diagonal.
  for (int k = 0; k < 3; ++k) CHECK(m.fabric(k, k) == doctest::Approx(1.0 / 3.0));
  // Void ratio: V / V_s - 1 with V_s = n^3 4/3 pi R^3 (overlap volume is not subtracted, docs/physics.md section 5).
  const double vs = n * n * n * 4.0 / 3.0 * std::numbers::pi * r * r * r;
  CHECK(m.void_ratio == doctest::Approx(a.prod() * n * n * n / vs - 1.0).epsilon(1e-14));
  // Equilibrium: every sphere's forces cancel by symmetry (to round-off).
  CHECK(m.unbalanced < 1e-9);
  // Stored energy: the integral of the Hertz force over the overlap, 8/15 E* sqrt(R*) delta^(5/2),
  // per contact (n^3 per axis); no tangential or rolling history yet. Same round-off as the stress
  // (delta^2.5 carries 2.5 x 1e-12): 1e-9.
  double energy = 0.0;
  for (int k = 0; k < 3; ++k) energy += n * n * n * 8.0 / 15.0 * es * std::sqrt(0.5 * r) * std::pow(delta[k], 2.5);
  CHECK(m.elastic_energy == doctest::Approx(energy).epsilon(1e-9));
  CHECK(m.max_overlap_ratio == doctest::Approx(delta.maxCoeff() / r).epsilon(1e-9));
}

TEST_CASE("homogenizer: stress is symmetric and equals the virial of independently computed forces") {
  // A jittered, sheared dense lattice with spinning spheres: tangential forces make f (x) r
  // non-symmetric per contact. The reference sums f (x) r over a brute-force all-images pair search,
  // with the normal Hertz force recomputed here (first step from rest, frictionless: the contact
  // force is exactly normal and elastic at setup, since the velocities are zero).
  Model model = elastic_model();
  model.materials[0].friction = 0.0;
  model.contact.rolling = RollingModel::none;
  State s = test::jittered_lattice(model, 5, 2e-3, 1.01e-3, 1.03e-3, 0.02e-3, 0.0, 0.0, 7);
  World world(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
  const Measures m = measure(world.model(), world.state(), world.executor());
  const State& st = world.state();
  const Particles& p = st.particles;
  const double es = e_star(model.materials[0]);
  Mat3 virial = Mat3::Zero();
  for (std::size_t i = 0; i < p.size(); ++i)
    for (std::size_t j = i + 1; j < p.size(); ++j)
      for (int nx = -1; nx <= 1; ++nx)
        for (int ny = -1; ny <= 1; ++ny)
          for (int nz = -1; nz <= 1; ++nz) {
            const Vec3 r = p.position[i] - p.position[j] -
                           Vec3(nx * st.cell.length[0], ny * st.cell.length[1], nz * st.cell.length[2]);
            const double d = r.norm(), overlap = p.radius[i] + p.radius[j] - d;
            if (overlap <= 0.0) continue;
            const double rs = p.radius[i] * p.radius[j] / (p.radius[i] + p.radius[j]);
            const Vec3 f = 4.0 / 3.0 * es * std::sqrt(rs * overlap) * overlap * r / d;
            virial += f * r.transpose();
          }
  virial /= st.cell.volume();
  const double scale = virial.cwiseAbs().maxCoeff();
  // Same terms summed in another order: ~1e3 contacts of similar size, round-off ~1e3 eps relative.
  CHECK((m.stress - virial).cwiseAbs().maxCoeff() < 1e-10 * scale);
  CHECK((m.stress - m.stress.transpose()).cwiseAbs().maxCoeff() == 0.0);
  CHECK(m.inv.p > 0.0);
}

TEST_CASE("invariants: p, q, b and the Lode angle by hand") {
  // Principal values 3, 2, 1 MPa: p = 2, q = sqrt((1 + 1 + 4)/2) = sqrt(3), b = 0.5,
  // theta = atan(sqrt(3) 0.5 / 1.5) = atan(1/sqrt(3)) = 30 deg.
  Mat3 s = Vec3(2e6, 3e6, 1e6).asDiagonal();  // axis order must not matter
  StressInvariants inv = invariants(s);
  CHECK(inv.principal[0] == 3e6);
  CHECK(inv.principal[2] == 1e6);
  CHECK(inv.p == doctest::Approx(2e6).epsilon(1e-15));
  CHECK(inv.q == doctest::Approx(std::sqrt(3.0) * 1e6).epsilon(1e-15));
  CHECK(inv.b == doctest::Approx(0.5).epsilon(1e-15));
  CHECK(inv.theta == doctest::Approx(std::numbers::pi / 6.0).epsilon(1e-15));
  // Triaxial compression (b = 0, theta = 0) and extension (b = 1, theta = 60 deg).
  CHECK(invariants(Vec3(3e6, 1e6, 1e6).asDiagonal()).theta == 0.0);
  CHECK(invariants(Vec3(3e6, 3e6, 1e6).asDiagonal()).theta == doctest::Approx(std::numbers::pi / 3.0).epsilon(1e-15));
  // A rotated tensor has the same invariants (eigen-decomposition path): rotate diag(3,2,1) by 30
  // degrees about z and 45 about x; the solver's relative accuracy is ~1e-15 of the largest value.
  const Mat3 rot = (Eigen::AngleAxisd(0.5, Vec3::UnitZ()) * Eigen::AngleAxisd(0.8, Vec3::UnitX())).toRotationMatrix();
  const StressInvariants r = invariants(rot * Vec3(3e6, 2e6, 1e6).asDiagonal() * rot.transpose());
  CHECK(r.principal[0] == doctest::Approx(3e6).epsilon(1e-12));
  CHECK(r.principal[1] == doctest::Approx(2e6).epsilon(1e-12));
  CHECK(r.b == doctest::Approx(0.5).epsilon(1e-12));
}

TEST_CASE("measures: rattlers are removed recursively from the mechanical coordination") {
  // A chain of three spheres along x in a long cell: the two ends have one contact each (rattlers);
  // removing them leaves the middle one with none, so it is a rattler too: Z_mech = 0, Z = 4/3.
  Model model = elastic_model();
  State s;
  const double r = 1e-3;
  s.cell.length = s.cell.length0 = Vec3(20e-3, 10e-3, 10e-3);
  add_sphere(s, model, 0, Vec3(5e-3, 5e-3, 5e-3), r, 0);
  add_sphere(s, model, 1, Vec3(5e-3 + 1.999e-3, 5e-3, 5e-3), r, 0);
  add_sphere(s, model, 2, Vec3(5e-3 + 3.998e-3, 5e-3, 5e-3), r, 0);
  World world(model, std::move(s), systems_for(model), ExecutorConfig{Backend::serial});
  const Measures m = measure(world.model(), world.state(), world.executor());
  CHECK(m.contacts == 2);
  CHECK(m.z == doctest::Approx(4.0 / 3.0));
  CHECK(m.rattlers == 3);
  CHECK(m.z_mech == 0.0);
}

TEST_CASE("median_diameter: 50 % passing by mass") {
  // Masses ~ d^3: one sphere of d = 2 weighs as much as eight of d = 1, so the 50 % mass point lies
  // in the big sphere whatever the count of small ones below 8.
  Model model = elastic_model();
  State s;
  s.cell.length = Vec3::Constant(1.0);
  for (int k = 0; k < 7; ++k) add_sphere(s, model, k, Vec3(0.1 * k, 0, 0), 0.5e-3, 0);
  add_sphere(s, model, 7, Vec3(0.9, 0, 0), 1e-3, 0);
  CHECK(median_diameter(s.particles) == 2e-3);
}

namespace {

// The chain of three spheres along x of the rattler test, its middle one pressed by both ends (a
// stress S_xx > 0 only: every branch and force lies on x), in a cell given by `shape`.
template <class Shape>
World chain_world(Shape shape) {
  Model model = elastic_model();
  State s;
  const double r = 1e-3;
  s.cell.length = s.cell.length0 = Vec3(20e-3, 10e-3, 10e-3);
  shape(s.cell);
  add_sphere(s, model, 0, Vec3(5e-3, 5e-3, 5e-3), r, 0);
  add_sphere(s, model, 1, Vec3(5e-3 + 1.999e-3, 5e-3, 5e-3), r, 0);
  add_sphere(s, model, 2, Vec3(5e-3 + 3.998e-3, 5e-3, 5e-3), r, 0);
  return World(model, std::move(s), systems_for(model), ExecutorConfig{Backend::serial});
}

}  // namespace

TEST_CASE("measures: an orthorhombic cell keeps the arithmetic of its strains, its tensors diagonal") {
  World world = chain_world([](Cell& c) {
    c.length = Vec3(19.9e-3, 10.03e-3, 10.02e-3);
    c.rate = Vec3(-5.0, 2.0, 1.5);
  });
  MeasureOptions o;
  o.d50 = 2e-3;
  o.density = 2650.0;
  const Measures m = measure(world.model(), world.state(), world.executor(), o);
  const Cell& c = world.state().cell;
  // The formulas measure() had before the cell could shear, restated: equal bit for bit.
  Vec3 e;
  for (int a = 0; a < 3; ++a) {
    e[a] = -std::log(c.length[a] / c.length0[a]);
    CHECK(m.strain[a] == e[a]);
    CHECK(m.strain_engineering[a] == 1.0 - c.length[a] / c.length0[a]);
    CHECK(m.strain_rate[a] == -c.rate[a]);
  }
  CHECK(m.eps_v == e.sum());
  CHECK(m.eps_q ==
        std::sqrt(2.0) / 3.0 *
            std::sqrt((e[0] - e[1]) * (e[0] - e[1]) + (e[1] - e[2]) * (e[1] - e[2]) + (e[2] - e[0]) * (e[2] - e[0])));
  const double gdot = m.strain_rate.maxCoeff() - m.strain_rate.minCoeff();
  CHECK(m.inertial_number == gdot * o.d50 * std::sqrt(o.density / m.inv.p));
  // The tensors: diagonal, exactly the axes' values; principal values the strains sorted.
  CHECK(m.strain_tensor == Mat3(m.strain.asDiagonal()));
  CHECK(m.strain_rate_tensor == Mat3(m.strain_rate.asDiagonal()));
  for (int a = 0; a < 3; ++a) CHECK(m.deformation(a, a) == c.length[a] / c.length0[a]);
  CHECK(m.gamma == Vec3::Zero());
  CHECK(m.principal_strain == Vec3(e[0], e[2], e[1]));  // 0.005, -0.002, -0.003: x, z, y
  CHECK(m.inv.principal == Vec3(m.stress(0, 0), 0.0, 0.0));
  CHECK(m.stress_directions == Mat3::Identity());
  CHECK(m.alpha == 0.0);
  CHECK(m.noncoaxiality == 0.0);  // the stress's and the rate's majors both on x
}

TEST_CASE("measures: a sheared cell's strain is the log strain of F, eps_q its deviatoric invariant, gamma -F_ab") {
  World world = chain_world([](Cell& c) {
    c.length[2] = 9.9e-3;           // 1 % shorter along z
    c.tilt = Vec3(0.0, 2e-3, 0.0);  // xz, after one flip: F_xz = (L1 + xz) / L3_0 = 2.2
    c.flip = Vec3(0.0, 1.0, 0.0);
    c.rate = Vec3(0.0, 0.0, -1.0);
    c.shear_rate = Vec3(0.0, -100.0, 0.0);  // gamma_dot_xz = 100 1/s
  });
  MeasureOptions o;
  o.d50 = 2e-3;
  o.density = 2650.0;
  const Measures m = measure(world.model(), world.state(), world.executor(), o);
  const Cell& c = world.state().cell;
  CHECK(m.deformation == c.deformation());
  CHECK(m.deformation(0, 2) == doctest::Approx(2.2).epsilon(1e-15));
  CHECK(m.gamma == Vec3(0.0, -m.deformation(0, 2), 0.0));
  CHECK(m.strain_tensor == log_strain(c.deformation()));
  // eps_v from the lengths equals the trace, -ln det F, up to the eigen-solver's rounding (1e-15
  // of the largest principal strain, ~1).
  CHECK(std::abs(m.eps_v - m.strain_tensor.trace()) <= 1e-14);
  const Vec3 e = principal(m.strain_tensor).values;
  CHECK(m.principal_strain == e);
  CHECK(m.eps_q ==
        std::sqrt(2.0) / 3.0 *
            std::sqrt((e[0] - e[1]) * (e[0] - e[1]) + (e[1] - e[2]) * (e[1] - e[2]) + (e[2] - e[0]) * (e[2] - e[0])));
  // The strain rate tensor -sym(L) in xz is [[0, 50], [50, 1]] 1/s: principal rates
  // (1 +- sqrt(1 + 4 50^2)) / 2 and 0, so gamma_dot = eps_dot_1 - eps_dot_3 = sqrt(10001); the
  // major direction at atan(eps_dot_1 / 50) from x toward z, the stress's major on x.
  CHECK(m.strain_rate_tensor(0, 2) == 50.0);
  CHECK(m.strain_rate_tensor(2, 2) == 1.0);
  CHECK(m.inertial_number ==
        doctest::Approx(std::sqrt(10001.0) * o.d50 * std::sqrt(o.density / m.inv.p)).epsilon(1e-14));
  const double rate1 = 0.5 * (1.0 + std::sqrt(10001.0));
  CHECK(std::abs(m.noncoaxiality - std::atan2(rate1, 50.0) * 180.0 / std::numbers::pi) <= 1e-9);
  CHECK(m.alpha == 0.0);
}

TEST_CASE("homogenizer: the stress the contact pass sums per block is measure()'s, bitwise the same for any executor") {
  // The servo's stress comes from the contact pass's per-block sums of f (x) r (StressBlocks), not
  // from a second pass over the pairs. Over 1,000 moving, spinning spheres with friction and rolling
  // (some 100 blocks of pairs, several chunks), in an orthorhombic and a tilted cell, under the
  // serial executor and 1-3 threads with the dynamic and the owner partition (whose crossing pairs
  // read ghost copies): the measured stress is the same bits every time, and measure()'s pair-by-pair
  // sum of the same forces and branch vectors to round-off.
  for (const bool tilted : {false, true}) {
    CAPTURE(tilted);
    Model model = elastic_model();
    model.servo.enabled = true;
    model.servo.path = StressPath::fixed;
    model.servo.gain = 10.0;  // every axis strain-controlled at rate 0: the cell does not move
    model.servo.max_rate = 1.0;
    State s = test::jittered_lattice(model, 10, 2e-3, 1.01e-3, 1.03e-3, 0.02e-3, 0.5, 50.0, 11);
    if (tilted) s.cell.tilt = Vec3(0.1, -0.05, 0.08) * s.cell.length[0];
    std::optional<Mat3> first;
    const ExecutorConfig configs[] = {{Backend::serial},
                                      {Backend::tbb, 1},
                                      {Backend::tbb, 2, Partition::dynamic},
                                      {Backend::tbb, 3, Partition::owner}};
    for (const ExecutorConfig& config : configs) {
      CAPTURE(config.threads);
      World world(model, s, systems_for(model), config);
      world.step(20);
      const MeasuredStress& measured = world.scratch().own<MeasuredStress>();
      REQUIRE(measured.step == 19);
      const Mat3 pairwise = measure(world.model(), world.state(), world.executor()).stress;
      // ~3,000 touching pairs of similar force summed in two orders: round-off of order sqrt(3,000)
      // eps ~ 1e-14 of the largest component; 1e-12 leaves room and is far below any force's share.
      const double scale = pairwise.cwiseAbs().maxCoeff();
      REQUIRE(scale > 0.0);
      CHECK((measured.stress - pairwise).cwiseAbs().maxCoeff() < 1e-12 * scale);
      CHECK(measured.stress != pairwise);  // not measure()'s own sum: the pass's blocks
      if (!first) first = measured.stress;
      CHECK(measured.stress == *first);  // every bit
    }
  }
}
