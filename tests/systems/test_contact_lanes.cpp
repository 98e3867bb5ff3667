// A pair's contact forces do not depend on the pairs it is evaluated with. The contact pass
// evaluates touching pairs four at a time in the lanes of AVX2 registers where the laws allow
// (systems/contact_kernel.hpp, visit4) and one at a time otherwise (fewer than four touching pairs
// left in a block, other laws, a build without AVX2). Each lane repeats the per-pair arithmetic in
// the same order, so the two must agree bit for bit. Here every pair of a scene of separate
// pairs (two materials, sticking and sliding, at and below the rolling cap, and pairs in the list
// that do not touch) is stepped once among all the others, where whole blocks of touching pairs
// fill the lanes, and once alone, where its block holds one touching pair and the pass visits it
// by itself: the forces and torques must be equal, not close.
// In a build without AVX2 both runs take the per-pair path and the test checks only that a pair's
// result does not depend on its neighbours in the list.
#include "engine/world.hpp"
#include "systems/broadphase.hpp"
#include "systems/contact_pass.hpp"
#include "systems/force_gather.hpp"
#include "support/scenes.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

using namespace sandcell;

namespace {

constexpr double k_radius = 1e-3;   // m
constexpr double k_spacing = 8e-3;  // m, between pair centres: far beyond 2 R + skin
constexpr int k_nx = 6, k_ny = 5, k_nz = 2;

struct PairSpec {
  Vec3 centre, dir;  // m, unit axis from sphere 1 to sphere 0
  double gap;        // m, surface gap (< 0: overlap)
  std::uint32_t mat0, mat1;
  Vec3 v0, v1, w0, w1;  // m/s, rad/s
};

std::vector<PairSpec> pair_specs(std::uint32_t materials) {
  std::mt19937_64 rng(2017);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<PairSpec> out;
  for (int z = 0; z < k_nz; ++z)
    for (int y = 0; y < k_ny; ++y)
      for (int x = 0; x < k_nx; ++x) {
        PairSpec p;
        p.centre = (Vec3(x, y, z) + Vec3::Constant(0.5)) * k_spacing;
        p.dir = Vec3(u(rng), u(rng), u(rng)).normalized();
        const int k = static_cast<int>(out.size());
        // One pair in seven in the list but apart (gap below the skin); overlaps 1e-7 to 5e-6 m.
        p.gap = k % 7 == 3 ? 2e-6 : -(1e-7 + 4.9e-6 * 0.5 * (1.0 + u(rng)));
        p.mat0 = static_cast<std::uint32_t>(k) % materials;
        p.mat1 = static_cast<std::uint32_t>(k / 2) % materials;
        // Relative sliding speeds of 1e-3 to 1 m/s and spins up to 200 rad/s: within 30 steps of
        // 1e-7 s some pairs stay below the Coulomb and rolling caps, others reach them.
        const double slide = std::pow(10.0, -3.0 + 3.0 * 0.5 * (1.0 + u(rng)));
        p.v0 = slide * Vec3(u(rng), u(rng), u(rng));
        p.v1 = slide * Vec3(u(rng), u(rng), u(rng));
        p.w0 = 200.0 * Vec3(u(rng), u(rng), u(rng)) * (k % 3 == 0 ? 1.0 : 0.01);
        p.w1 = 200.0 * Vec3(u(rng), u(rng), u(rng)) * (k % 3 == 0 ? 1.0 : 0.01);
        out.push_back(p);
      }
  return out;
}

// The benchmark's material (test::quartz_model: Hertz, Mindlin with history, epsd2), and with
// `materials` = 2 a second, softer and lighter one.
Model lanes_model(std::uint32_t materials) {
  Model m = test::quartz_model(1e-7, Model{}.contact.skin);
  Material b;
  b.young = 20e9;
  b.poisson = 0.2;
  b.density = 1500.0;
  b.restitution = 0.8;
  b.friction = 0.3;
  b.rolling_friction = 0.05;
  if (materials == 2) m.materials.push_back(b);
  REQUIRE(m.contact.rolling == RollingModel::epsd2);
  REQUIRE(m.contact.tangential == TangentialModel::history);
  m.finalize();
  return m;
}

// The scene with the pairs `which` (indices into specs), sphere ids 2k and 2k+1.
State scene(const Model& model, const std::vector<PairSpec>& specs, const std::vector<std::size_t>& which) {
  State s;
  s.cell.length = s.cell.length0 = Vec3(k_nx, k_ny, k_nz) * k_spacing;
  for (std::size_t k : which) {
    const PairSpec& p = specs[k];
    const Vec3 half = (k_radius + 0.5 * p.gap) * p.dir;
    const auto id = static_cast<ParticleId>(2 * k);
    const std::size_t i0 = add_sphere(s, model, id, p.centre + half, k_radius, p.mat0);
    const std::size_t i1 = add_sphere(s, model, id + 1, p.centre - half, k_radius, p.mat1);
    s.particles.velocity[i0] = p.v0;
    s.particles.velocity[i1] = p.v1;
    s.particles.angular_velocity[i0] = p.w0;
    s.particles.angular_velocity[i1] = p.w1;
  }
  return s;
}

std::vector<SystemSpec> contact_systems() {
  return {make_system<Broadphase>(), make_system<ContactPass>(), make_system<ForceGather>()};
}

// Index of sphere `id` in the state (the broadphase may reorder the particles).
std::size_t index_of(const State& s, ParticleId id) {
  for (std::size_t i = 0; i < s.particles.size(); ++i)
    if (s.particles.id[i] == id) return i;
  FAIL("sphere " << id << " missing");
  return 0;
}

void check_pairs_alone_and_together(std::uint32_t materials, int threads) {
  const Model model = lanes_model(materials);
  const std::vector<PairSpec> specs = pair_specs(materials);
  std::vector<std::size_t> all(specs.size());
  for (std::size_t k = 0; k < all.size(); ++k) all[k] = k;
  constexpr unsigned k_steps = 30;  // positions fixed (no integrator): the histories grow each step
  World together(model, scene(model, specs, all), contact_systems(), ExecutorConfig{Backend::tbb, threads});
  together.step(k_steps);
  const State& t = together.state();
  REQUIRE(t.contacts.pairs.size() >= specs.size());  // every pair in the list, touching or not
  int capped = 0, touching = 0;
  for (std::size_t k = 0; k < specs.size(); ++k) {
    INFO("pair " << k << ", materials " << specs[k].mat0 << "/" << specs[k].mat1);
    World alone(model, scene(model, specs, {k}), contact_systems(), ExecutorConfig{Backend::tbb, 1});
    alone.step(k_steps);
    const State& a = alone.state();
    for (ParticleId id : {static_cast<ParticleId>(2 * k), static_cast<ParticleId>(2 * k + 1)}) {
      const std::size_t it = index_of(t, id), ia = index_of(a, id);
      CHECK(t.particles.force[it] == a.particles.force[ia]);
      CHECK(t.particles.torque[it] == a.particles.torque[ia]);
    }
    const std::size_t i0 = index_of(a, static_cast<ParticleId>(2 * k));
    const double f_n = std::abs(a.particles.force[i0].dot(specs[k].dir));
    const double f_t = (a.particles.force[i0] - a.particles.force[i0].dot(specs[k].dir) * specs[k].dir).norm();
    if (f_n > 0.0) ++touching;
    const double mu = 0.5 * (model.materials[specs[k].mat0].friction + model.materials[specs[k].mat1].friction);
    // At the cap |F_t| = mu |F_n| up to the roundings of the projection above (~1e-15 relative),
    // which 1e-9 absorbs; the count only checks that the scene has pairs on both sides of the cap.
    if (f_n > 0.0 && f_t >= mu * f_n * (1.0 - 1e-9)) ++capped;
  }
  // The scene exercises what it is meant to: whole groups of four touching pairs, and pairs on
  // both sides of the Coulomb cap.
  CHECK(touching >= 24);
  CHECK(capped >= 4);
  CHECK(capped <= touching - 4);
}

}  // namespace

TEST_CASE("contact pass: a pair's forces and torques are bitwise the same alone and among others (one material)") {
  check_pairs_alone_and_together(1, 1);
}

TEST_CASE("contact pass: a pair's forces and torques are bitwise the same alone and among others (two materials)") {
  check_pairs_alone_and_together(2, 1);
  check_pairs_alone_and_together(2, 2);
}
