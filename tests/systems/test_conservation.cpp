// Conservation laws of the contact systems on dense periodic packings: Newton's third law and the
// angular momentum balance of every contact, bounded energy error of the elastic frictionless
// packing under velocity Verlet, and bitwise determinism for any thread count.
#include "engine/world.hpp"
#include "systems/broadphase.hpp"
#include "systems/catalogue.hpp"
#include "systems/contact_pass.hpp"
#include "support/scenes.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

using namespace sandcell;

namespace {

constexpr double k_eps = std::numeric_limits<double>::epsilon();

Vec3 branch(const State& s, std::size_t k) {
  const ContactPairs& p = s.contacts.pairs;
  const Image& n = p.image[k];
  return s.particles.position[p.i[k]] -
         (s.particles.position[p.j[k]] +
          Vec3(n[0] * s.cell.length[0], n[1] * s.cell.length[1], n[2] * s.cell.length[2]));
}

// Neumaier (compensated) sum of vectors: its own rounding stays at eps |sum| + O(n eps^2) sum |x|.
struct CompensatedSum {
  Vec3 sum = Vec3::Zero(), c = Vec3::Zero();
  void add(const Vec3& x) {
    for (int a = 0; a < 3; ++a) {
      const double t = sum[a] + x[a];
      if (std::abs(sum[a]) >= std::abs(x[a]))
        c[a] += (sum[a] - t) + x[a];
      else
        c[a] += (x[a] - t) + sum[a];
      sum[a] = t;
    }
  }
  Vec3 value() const { return sum + c; }
};

}  // namespace

TEST_CASE("Newton's third law and the angular momentum balance hold for every contact of a dense sheared packing") {
  Model model = test::quartz_model(1e-7, 0.3e-3);  // epsd2 rolling, history tangential law
  // 512 spheres, radii 1.00-1.03 mm on a 2 mm lattice (neighbours overlap by up to 0.08 mm), random
  // velocities and spins, in a cell sheared at constant volume rate (affine term in v_rel).
  State s = test::jittered_lattice(model, 8, 2e-3, 1.00e-3, 1.03e-3, 0.01e-3, 0.5, 300.0, 21);
  s.cell.rate = Vec3(-20.0, 10.0, 10.0);
  World world(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
  world.step(100);  // tangential and rolling histories build up
  const State& st = world.state();
  const ContactPairs& pairs = st.contacts.pairs;
  const ContactForces& cf = st.contacts.forces;
  const std::size_t n = st.particles.size(), m = pairs.size();

  // 1. The per-particle gather is the signed sum of the pair slots (force on j = -force on i), in
  //    the documented fixed order (systems/force_gather.hpp): first the pairs where the particle
  //    is i, then those where it is j, each ascending. Recomputed here in that order, it is
  //    bitwise the same.
  std::vector<Vec3> f(n, Vec3::Zero()), t(n, Vec3::Zero());
  for (std::size_t k = 0; k < m; ++k) {
    f[pairs.i[k]] += cf.force[k];
    t[pairs.i[k]] += cf.torque_i[k];
  }
  for (std::size_t k = 0; k < m; ++k) {
    f[pairs.j[k]] -= cf.force[k];
    t[pairs.j[k]] += cf.torque_j[k];
  }
  std::size_t gather_mismatch = 0;
  for (std::size_t p = 0; p < n; ++p)
    if (f[p] != st.particles.force[p] || t[p] != st.particles.torque[p]) ++gather_mismatch;
  CHECK(gather_mismatch == 0);

  // 2. Total force: zero up to the rounding of the per-particle sums. Each particle sums at most
  //    z_max terms, with an error below (z_max - 1) eps times the sum of their magnitudes; each
  //    contact is in two particles: |sum F| <= 2 z_max eps sum_c |F_c| (the total itself is taken
  //    with a compensated sum, which adds no error of that order).
  std::vector<int> z(n, 0);
  double sum_abs = 0.0, sum_fn = 0.0, sum_ft = 0.0, sum_roll = 0.0;
  std::size_t touching = 0;
  for (std::size_t k = 0; k < m; ++k) {
    const double fk = cf.force[k].norm();
    if (fk == 0.0) continue;
    ++z[pairs.i[k]];
    ++z[pairs.j[k]];
    sum_abs += fk;
    const Vec3 nk = branch(st, k).normalized();
    sum_fn += std::abs(cf.force[k].dot(nk));
    sum_ft += (cf.force[k] - cf.force[k].dot(nk) * nk).norm();
    sum_roll += (cf.torque_i[k] + cf.torque_j[k]).norm();
    ++touching;
  }
  const int z_max = *std::max_element(z.begin(), z.end());
  CompensatedSum total;
  for (std::size_t p = 0; p < n; ++p) total.add(st.particles.force[p]);
  const double bound = 2.0 * z_max * k_eps * sum_abs;
  MESSAGE(touching << " touching contacts, z_max = " << z_max << ", |sum F| = " << total.value().norm() << " N, bound "
                   << bound << " N, sum |F_c| = " << sum_abs << " N");
  CHECK(total.value().norm() <= bound);
  // The packing is a meaningful test: friction and rolling are active.
  CHECK(touching > 2 * n);
  CHECK(sum_ft > 0.01 * sum_fn);

  // 3. Angular momentum per contact, about a common point: the force F on i at x_i, -F on j at
  //    x_j + H n, and the torques T_i, T_j: r_ij x F + T_i + T_j = 0. It holds because the lever
  //    arms c_i + c_j = R_i + R_j - delta = |r_ij| and the rolling moments are equal and opposite.
  //    Round-off: c_i + c_j differs from |r| by a few eps (R_i + R_j), n = r/|r| is rounded, the
  //    cross products add a few roundings: 16 eps ((R_i + R_j) |F| + |T_i| + |T_j|) bounds it. A
  //    lever arm of R instead of R - delta/2 leaves delta |F_t| (~1e-2 of the terms).
  double worst = 0.0;
  std::size_t violations = 0;
  for (std::size_t k = 0; k < m; ++k) {
    if (cf.force[k] == Vec3::Zero()) continue;
    const Vec3 r = branch(st, k);
    const Vec3 residual = r.cross(cf.force[k]) + cf.torque_i[k] + cf.torque_j[k];
    const double scale = (st.particles.radius[pairs.i[k]] + st.particles.radius[pairs.j[k]]) * cf.force[k].norm() +
                         cf.torque_i[k].norm() + cf.torque_j[k].norm();
    worst = std::max(worst, residual.norm() / (k_eps * scale));
    if (residual.norm() > 16.0 * k_eps * scale) ++violations;
  }
  MESSAGE("largest angular momentum residual per contact: " << worst << " eps x scale; sum |T_i + T_j| (rolling) = "
                                                            << sum_roll << " N m");
  CHECK(violations == 0);
  CHECK(sum_roll > 0.0);  // rolling moments present (they cancel pairwise in the balance)
}

namespace {

struct Energy {
  double kinetic = 0.0, rotational = 0.0, elastic = 0.0;
  double total() const { return kinetic + rotational + elastic; }
};

// Kinetic (translational + rotational) energy and the Hertz elastic energy
// sum_c 8/15 E* sqrt(R*) delta^(5/2) (the work of F = 4/3 E* sqrt(R*) delta^(3/2)), all from the
// state: positions, radii and the pair list (which holds every touching pair).
Energy energy_of(const State& s, double e_star) {
  Energy e;
  const Particles& p = s.particles;
  for (std::size_t k = 0; k < p.size(); ++k) {
    e.kinetic += 0.5 * p.mass[k] * p.velocity[k].squaredNorm();
    e.rotational += 0.5 / p.inv_inertia[k] * p.angular_velocity[k].squaredNorm();
  }
  for (std::size_t k = 0; k < s.contacts.size(); ++k) {
    const double ri = p.radius[s.contacts.pairs.i[k]], rj = p.radius[s.contacts.pairs.j[k]];
    const double delta = ri + rj - branch(s, k).norm();
    if (delta > 0.0) e.elastic += 8.0 / 15.0 * e_star * std::sqrt(ri * rj / (ri + rj)) * std::pow(delta, 2.5);
  }
  return e;
}

struct EnergyRun {
  double max_dev = 0.0;  // max |E - E0| / E0
  double end_dev = 0.0;  // (E_end - E0) / E0
  Energy start, end;
};

EnergyRun energy_run(const Model& model, const State& s, std::uint64_t steps, double e_star) {
  World world(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
  EnergyRun out;
  out.start = energy_of(world.state(), e_star);
  const double e0 = out.start.total();
  for (std::uint64_t k = 0; k < steps; k += 10) {
    world.step(10);
    const double e = energy_of(world.state(), e_star).total();
    out.max_dev = std::max(out.max_dev, std::abs(e - e0) / e0);
  }
  out.end = energy_of(world.state(), e_star);
  out.end_dev = (out.end.total() - e0) / e0;
  return out;
}

}  // namespace

TEST_CASE(
    "elastic frictionless packing: total energy (kinetic + rotational + Hertz elastic) stays bounded over 1e4 steps") {
  Model model;
  Material mat;  // E = 70 GPa, nu = 0.3, rho = 2650
  mat.restitution = 1.0;
  mat.friction = 0.0;
  mat.rolling_friction = 0.0;
  model.materials.push_back(mat);
  model.contact.rolling = RollingModel::none;
  const double r_min = 1.0e-3, r_max = 1.01e-3;
  const double dt_r = rayleigh_time(r_min, mat);
  model.dt = 0.1 * dt_r;
  const double e_star = 1.0 / (2.0 * (1.0 - mat.poisson * mat.poisson) / mat.young);
  // 343 spheres on a 2 mm lattice with radii 1.00-1.01 mm and 2 um jitter: lattice neighbours
  // overlap by up to 27 um, some not at all; random velocities of a few m/s, so kinetic and elastic
  // energies are of the same order and contacts open and close.
  const State s = test::jittered_lattice(model, 7, 2e-3, r_min, r_max, 2e-6, 3.0, 1000.0, 5);
  const EnergyRun coarse = energy_run(model, s, 10000, e_star);
  Model fine_model = model;
  fine_model.dt = model.dt / 2.0;
  const EnergyRun fine = energy_run(fine_model, s, 20000, e_star);  // the same physical time
  MESSAGE("E0 = " << coarse.start.total() << " J (kinetic " << coarse.start.kinetic << ", rotational "
                  << coarse.start.rotational << ", elastic " << coarse.start.elastic << "); at the end: kinetic "
                  << coarse.end.kinetic << ", elastic " << coarse.end.elastic);
  MESSAGE("dt = 0.1 dt_R: max |E - E0| / E0 = " << coarse.max_dev << ", drift at the end " << coarse.end_dev
                                                << "; dt = 0.05 dt_R: " << fine.max_dev << ", " << fine.end_dev
                                                << "; ratio " << coarse.max_dev / fine.max_dev);
  // Rotational energy is constant without tangential forces and rolling torques.
  CHECK(coarse.end.rotational == doctest::Approx(coarse.start.rotational).epsilon(1e-14));
  // Energy is exchanged: the test is not trivially passed by a frozen packing.
  CHECK(std::abs(coarse.end.elastic - coarse.start.elastic) > 0.05 * coarse.start.total());
  // Bounds: velocity Verlet has a bounded energy error of O(dt^2). At dt = 0.1 dt_R (about 60 steps
  // per contact oscillation period here) a correct contact pass gives max |E - E0| / E0 = 2.1e-4
  // (1.9e-4 to 2.3e-4 over five seeds, measured with a neighbour list rebuilt every step) and we
  // assert 1e-3, as the issue suggests; the error must shrink about 4x when dt halves (measured
  // 4.0 to 4.8; 3 to 6 allows for the chaotic trajectories differing). A force that is not the
  // gradient of the Hertz energy, or a contact missed and then found deep (an energy injection
  // at the next list build), fails both.
  CHECK(coarse.max_dev < 1e-3);
  CHECK(coarse.max_dev / fine.max_dev > 3.0);
  CHECK(coarse.max_dev / fine.max_dev < 6.0);
}

TEST_CASE(
    "dense frictional packing with rolling, 500 steps: bitwise identical for 1, 2, 3, 8 threads and the serial backend") {
  struct Config {
    const char* name;
    TangentialModel tangential;
    RollingModel rolling;
    double eta_r;
    std::size_t n_side;
    int sort_interval;
  };
  // The first scene holds ~3400 spheres and ~10^4 pairs: several parallel_for chunks of particles
  // (1024) and of pairs (4096), so the chunking and the gather are exercised.
  // One scene also reorders the particles along a Morton curve every 100 steps (spatial_sort).
  const Config configs[] = {
      {"history + epsd2", TangentialModel::history, RollingModel::epsd2, 0.0, 15, 0},
      {"incremental + epsd with dashpot, spatial sort", TangentialModel::incremental, RollingModel::epsd, 0.3, 12, 100},
      {"history + cdt", TangentialModel::history, RollingModel::cdt, 0.0, 12, 0}};
  for (const Config& c : configs) {
    INFO(c.name);
    Model model = test::quartz_model(1e-7, 0.3e-3);
    model.contact.tangential = c.tangential;
    model.contact.rolling = c.rolling;
    model.contact.rolling_damping = c.eta_r;
    model.contact.sort_interval = c.sort_interval;
    State s = test::jittered_lattice(model, c.n_side, 2e-3, 1.00e-3, 1.03e-3, 0.02e-3, 1.0, 500.0, 99);
    s.cell.rate = Vec3(-30.0, 15.0, 15.0);
    auto run = [&](ExecutorConfig cfg) {
      World w(model, s, systems_for(model), cfg);
      w.step(500);
      CHECK(list_builds(w.scratch()) >= 1);
      return w.state();
    };
    const State reference = run({Backend::serial, 1});
    CHECK(reference.contacts.size() > 2 * reference.particles.size());
    CHECK(reference.particles.position != s.particles.position);
    for (int threads : {1, 2, 3, 8}) {
      const State other = run({Backend::tbb, threads});
      INFO("threads = " << threads);
      CHECK(first_difference(other.particles, reference.particles) == "");
      CHECK(first_difference(other.contacts, reference.contacts) == "");
      CHECK(other.cell.length == reference.cell.length);
    }
    if (c.n_side == 15) CHECK(reference.contacts.size() > 4096);
  }
}

TEST_CASE("the contact pass's visiting order and its skipping of open pairs change no result") {
  // the contact pass visits the pairs of a block grouped by last step's regime (kept in Scratch), and
  // does not write again the zero outputs and histories of a pair that was open in the last step.
  // A World made from a state starts with no regimes, visits every block in array order and writes
  // every open pair. Stepping a sheared frictional packing one step at a time through fresh Worlds
  // must then give bitwise the states of one World stepping on with its regimes: a pair visited
  // twice or skipped by a wrong order, or an open pair whose slot holds another pair's values after
  // a list build, would leave a slot with another value.
  struct Scene {
    const char* name;
    double skin, r_min, v_scale;
    int window;
    std::size_t min_open, min_array_order, min_builds;
  };
  // Dense: all but a few pairs touch, so some blocks hold no capped or open pair and keep array
  // order (20 sliding, 95 at the rolling cap, 14 open, 24 of 81 blocks in array order; no build).
  // Loose and fast with a thin skin: 551 of 4988 pairs open, every block sorted, 4 list builds in
  // the window (slots then hold other pairs) while contacts open and close.
  const Scene scenes[] = {{"dense", 0.3e-3, 1.00e-3, 1.0, 20, 10, 2, 0},
                          {"loose, rebuilding", 0.02e-3, 0.98e-3, 2.0, 60, 100, 0, 2}};
  for (const Scene& c : scenes) {
    INFO("scene: " << std::string(c.name));
    Model model = test::quartz_model(1e-7, c.skin);  // friction 0.5, epsd2 rolling
    State s = test::jittered_lattice(model, 12, 2e-3, c.r_min, 1.03e-3, 0.02e-3, c.v_scale, 500.0, 7);
    s.cell.rate = Vec3(-30.0, 15.0, 15.0);
    const ExecutorConfig cfg{Backend::tbb, 2};
    World world(model, s, systems_for(model), cfg);
    world.step(100);
    const State start = world.state();

    // The grouping is exercised: pairs at each cap and open, blocks in sorted and in array order.
    const ContactScratch& hint = world.scratch().own<ContactScratch>();
    std::size_t sliding = 0, rolling = 0, open = 0, sorted = 0;
    for (std::uint8_t r : hint.regime) {
      if (r == ContactScratch::k_apart) {
        ++open;
        continue;
      }
      sliding += r & 1;
      rolling += (r >> 1) & 1;
    }
    for (std::uint8_t b : hint.sorted) sorted += b;
    INFO("pairs " << hint.regime.size() << ", sliding " << sliding << ", rolling cap " << rolling << ", open " << open
                  << ", sorted blocks " << sorted << " of " << hint.sorted.size());
    REQUIRE(sliding >= 10);
    REQUIRE(rolling >= 10);
    REQUIRE(open >= c.min_open);
    REQUIRE(sorted >= 2);
    REQUIRE(hint.sorted.size() - sorted >= c.min_array_order);

    const std::uint64_t builds_before = list_builds(world.scratch());
    world.step(c.window);
    const std::uint64_t builds = list_builds(world.scratch()) - builds_before;
    INFO("list builds in the window: " << builds);
    REQUIRE(builds >= c.min_builds);
    State chain = start;
    for (int k = 0; k < c.window; ++k) {
      World fresh(model, chain, systems_for(model), cfg, /*initial_forces=*/false);
      fresh.step(1);
      chain = fresh.state();
    }
    CHECK(first_difference(chain.particles, world.state().particles) == "");
    CHECK(first_difference(chain.contacts, world.state().contacts) == "");
  }
}
