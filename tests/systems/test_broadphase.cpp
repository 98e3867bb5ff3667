// Broadphase (neighbour list over the periodic cell) and periodicity of the contact forces:
// the list equals an all-images O(N^2) search, also in cells barely wider than the cutoff and in
// deforming cells; a too narrow cell is a clear error; contacts across faces and corners, and a
// translated packing, give the same forces as in the bulk.
#include "engine/world.hpp"
#include "systems/catalogue.hpp"
#include "support/scenes.hpp"
#include "systems/broadphase.hpp"
#include "systems/force_gather.hpp"
#include "systems/contact_pass.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <string>
#include <tuple>
#include <vector>

using namespace sandcell;

namespace {

constexpr double k_eps = std::numeric_limits<double>::epsilon();

using Key = std::tuple<ParticleId, ParticleId, Image>;  // (id_i, id_j, image), id_i < id_j

// All pairs (id_i < id_j, any image n in {-1,0,1}^3) with |x_i - (x_j + L n)| < R_i + R_j + extra,
// by brute force. Pairs within 1e-12 (relative) of the cutoff are reported in `ties` instead: the
// engine may round them either way.
struct BruteForce {
  std::set<Key> pairs;
  std::set<Key> ties;
};
BruteForce all_images(const State& s, double extra) {
  BruteForce out;
  const Particles& p = s.particles;
  const Vec3 L = s.cell.length;
  for (std::size_t a = 0; a < p.size(); ++a)
    for (std::size_t b = 0; b < p.size(); ++b) {
      if (p.id[a] >= p.id[b]) continue;
      const double cut = p.radius[a] + p.radius[b] + extra;
      const Vec3 d = p.position[a] - p.position[b];
      for (int nx = -1; nx <= 1; ++nx) {
        if (std::abs(d.x() - nx * L.x()) >= cut * (1 + 1e-12)) continue;
        for (int ny = -1; ny <= 1; ++ny) {
          if (std::abs(d.y() - ny * L.y()) >= cut * (1 + 1e-12)) continue;
          for (int nz = -1; nz <= 1; ++nz) {
            const Vec3 r = p.position[a] - (p.position[b] + Vec3(nx * L.x(), ny * L.y(), nz * L.z()));
            const double dist = r.norm();
            const Key k{p.id[a], p.id[b], Image{std::int8_t(nx), std::int8_t(ny), std::int8_t(nz)}};
            if (std::abs(dist - cut) <= 1e-12 * cut)
              out.ties.insert(k);
            else if (dist < cut)
              out.pairs.insert(k);
          }
        }
      }
    }
  return out;
}

// The engine's list as keys; checks the documented invariants on the way: id_i < id_j, the indices
// point at those ids, and the canonical order (strictly increasing (id_i, id_j, image)).
std::set<Key> listed(const State& s) {
  const ContactPairs& c = s.contacts.pairs;
  std::set<Key> out;
  for (std::size_t k = 0; k < c.size(); ++k) {
    CHECK(c.id_i[k] < c.id_j[k]);
    CHECK(s.particles.id[c.i[k]] == c.id_i[k]);
    CHECK(s.particles.id[c.j[k]] == c.id_j[k]);
    const Key key{c.id_i[k], c.id_j[k], c.image[k]};
    if (k > 0) CHECK(Key{c.id_i[k - 1], c.id_j[k - 1], c.image[k - 1]} < key);
    out.insert(key);
  }
  CHECK(out.size() == c.size());  // no duplicates
  return out;
}

// Set equality up to ties; reports the first few differences.
void check_same_pairs(const std::set<Key>& engine, const BruteForce& brute) {
  std::size_t missing = 0, extra = 0;
  for (const Key& k : brute.pairs)
    if (!engine.count(k)) {
      if (++missing <= 5)
        MESSAGE("missing pair " << std::get<0>(k) << "-" << std::get<1>(k) << " image (" << int(std::get<2>(k)[0])
                                << "," << int(std::get<2>(k)[1]) << "," << int(std::get<2>(k)[2]) << ")");
    }
  for (const Key& k : engine)
    if (!brute.pairs.count(k) && !brute.ties.count(k)) {
      if (++extra <= 5)
        MESSAGE("extra pair " << std::get<0>(k) << "-" << std::get<1>(k) << " image (" << int(std::get<2>(k)[0]) << ","
                              << int(std::get<2>(k)[1]) << "," << int(std::get<2>(k)[2]) << ")");
    }
  CHECK(missing == 0);
  CHECK(extra == 0);
}

// Random polydisperse spheres (overlaps allowed) in an orthorhombic cell.
State random_spheres(const Model& model, std::size_t n, const Vec3& box, double r_min, double r_max,
                     std::uint64_t seed) {
  State s;
  s.cell.length = s.cell.length0 = box;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  for (std::size_t k = 0; k < n; ++k) {
    const double r = r_min + (r_max - r_min) * u01(rng);
    add_sphere(s, model, static_cast<ParticleId>(k), Vec3(u01(rng), u01(rng), u01(rng)).cwiseProduct(box), r, 0);
  }
  return s;
}

Model default_model(double dt, double skin = 0.3e-3) {
  Model m;
  m.dt = dt;
  m.materials.push_back(Material{});
  m.contact.skin = skin;
  return m;
}

std::vector<SystemSpec> contact_systems() {
  return {make_system<Broadphase>(), make_system<ContactPass>(), make_system<ForceGather>()};
}

}  // namespace

TEST_CASE("the pair list equals an all-images O(N^2) search, down to cells 1.05 x (2 r_max + skin) wide") {
  const double r_min = 0.5e-3, r_max = 1e-3, skin = 0.3e-3;
  const double cut = 2.0 * r_max + skin;
  const Model model = default_model(1e-7, skin);
  // Cell shapes in units of the cutoff: 1, 2 or several bins per axis, and mixtures.
  const Vec3 shapes[] = {{1.05, 1.05, 1.05}, {1.05, 2.5, 4.2}, {2.02, 1.3, 7.1}, {3.3, 3.1, 3.05},
                         {6.0, 6.0, 6.0},    {1.5, 1.5, 9.0},  {2.9, 1.05, 2.1}};
  std::size_t multi_image = 0, pairs_seen = 0;
  std::uint64_t seed = 100;
  for (const Vec3& shape : shapes) {
    const Vec3 box = shape * cut;
    // Density: ~0.4 solid fraction of spheres of mean radius 0.75 mm, at least 3 spheres.
    const double mean_volume = 4.0 / 3.0 * 3.14159 * std::pow(0.75e-3, 3);
    const auto n = std::max<std::size_t>(3, static_cast<std::size_t>(0.4 * box.prod() / mean_volume));
    for (int rep = 0; rep < 4; ++rep) {
      const State s = random_spheres(model, n, box, r_min, r_max, ++seed);
      INFO("cell " << box.transpose() << " m, " << n << " spheres, seed " << seed);
      World world(model, s, contact_systems(), ExecutorConfig{Backend::tbb, 2});
      const std::set<Key> engine = listed(world.state());
      const BruteForce brute = all_images(world.state(), skin);
      check_same_pairs(engine, brute);
      pairs_seen += brute.pairs.size();
      // Pairs listed through more than one image (possible only below 2 cutoffs).
      for (auto it = brute.pairs.begin(); it != brute.pairs.end(); ++it) {
        auto next = std::next(it);
        if (next != brute.pairs.end() && std::get<0>(*next) == std::get<0>(*it) &&
            std::get<1>(*next) == std::get<1>(*it))
          ++multi_image;
      }
    }
  }
  MESSAGE(pairs_seen << " pairs compared; " << multi_image << " of them also listed through another image");
  CHECK(multi_image > 0);  // the narrow cells did exercise pairs touching through two images
}

TEST_CASE(
    "radius ratio 10:1: the pair list still equals the all-images search (bins sized by r_max hold many small spheres)") {
  const double r_min = 0.1e-3, r_max = 1e-3, skin = 0.05e-3;
  const double cut = 2.0 * r_max + skin;
  const Model model = default_model(1e-7, skin);
  std::uint64_t seed = 900;
  std::size_t pairs_seen = 0, small_small = 0;
  for (const Vec3& shape : {Vec3(1.05, 1.05, 1.05), Vec3(3.3, 2.2, 5.1), Vec3(6.0, 6.0, 6.0)}) {
    const Vec3 box = shape * cut;
    // Radii uniform in [0.1, 1] mm: mean volume 4/3 pi <r^3> = 4/3 pi (1e-12 - 1e-16) / (4 * 0.9e-3);
    // 0.35 solid fraction.
    const double mean_volume =
        4.0 / 3.0 * 3.14159 * (std::pow(r_max, 4) - std::pow(r_min, 4)) / (4.0 * (r_max - r_min));
    const auto n = std::max<std::size_t>(3, static_cast<std::size_t>(0.35 * box.prod() / mean_volume));
    for (int rep = 0; rep < 3; ++rep) {
      const State s = random_spheres(model, n, box, r_min, r_max, ++seed);
      INFO("cell " << box.transpose() << " m, " << n << " spheres, seed " << seed);
      World world(model, s, contact_systems(), ExecutorConfig{Backend::tbb, 2});
      const BruteForce brute = all_images(world.state(), skin);
      check_same_pairs(listed(world.state()), brute);
      pairs_seen += brute.pairs.size();
      const auto& radius = world.state().particles.radius;
      const auto& index = world.state().contacts.pairs;
      for (std::size_t k = 0; k < index.size(); ++k)
        if (radius[index.i[k]] < 0.3e-3 && radius[index.j[k]] < 0.3e-3) ++small_small;
    }
  }
  MESSAGE(pairs_seen << " pairs compared, " << small_small << " between two spheres under 0.3 mm");
  CHECK(small_small > 0);  // the small end of the distribution was exercised
}

TEST_CASE("a pair touching through two images gets two contacts, with the force of each") {
  // Cell 1.05 x (2 r_max + skin) along x: two spheres of radius R at distance L/2 along x overlap
  // both directly (image 0) and through the boundary (image -1): 2R > L/2 on both sides.
  const double R = 1e-3, skin = 0.3e-3;
  const Model model = default_model(1e-7, skin);
  State s;
  const double Lx = 1.05 * (2.0 * R + skin);  // 2.415 mm; L/2 = 1.2075 mm < 2R = 2 mm
  s.cell.length = s.cell.length0 = Vec3(Lx, 10e-3, 10e-3);
  add_sphere(s, model, 0, Vec3(0.25 * Lx, 5e-3, 5e-3), R, 0);
  add_sphere(s, model, 1, Vec3(0.75 * Lx, 5e-3, 5e-3), R, 0);
  World world(model, s, contact_systems(), ExecutorConfig{Backend::tbb, 2});
  const State& st = world.state();
  REQUIRE(st.contacts.size() == 2);
  const Image a{0, 0, 0}, b{-1, 0, 0};  // j at x_j and at x_j - L (sorted: -1 before 0)
  CHECK(st.contacts.pairs.image[0] == b);
  CHECK(st.contacts.pairs.image[1] == a);
  // Equal overlaps 2R - L/2 from both sides: equal and opposite forces, net force zero on each.
  const Vec3 f0 = st.contacts.forces.force[0], f1 = st.contacts.forces.force[1];
  CHECK(f0.x() > 0.0);  // image -1: j sits at x_j - L, left of i: pushes i to +x
  CHECK(f1.x() < 0.0);
  CHECK(f0.x() == doctest::Approx(-f1.x()).epsilon(1e-12));
  CHECK(std::abs(st.particles.force[0].x()) < 1e-12 * f0.x());
}

TEST_CASE(
    "in a deforming cell every touching pair stays listed between rebuilds, and each rebuild lists exactly the pairs within the cutoff") {
  // A dense polydisperse gas (solid fraction 0.39) on a jittered lattice, without initial
  // overlaps, with random velocities of a few m/s, in a cell compressed along x and stretched along
  // y and z: pairs meet and part, spheres cross the faces, and the list is rebuilt by the skin
  // criterion (displacements and the affine stretch). The pair keys carry the image, so a pair
  // kept with a stale image after one of its spheres was wrapped counts as missing.
  const double dt = 1e-7;
  const Model model = default_model(dt);
  State s = test::jittered_lattice(model, 7, 2.1e-3, 0.9e-3, 1.0e-3, 0.02e-3, 5.0, 100.0, 77);
  // Shift the lattice by half a spacing so that a layer of spheres sits on each face: spheres cross
  // the faces (and are wrapped) while touching partners on the other side.
  for (Vec3& x : s.particles.position)
    for (int a = 0; a < 3; ++a) x[a] = std::fmod(x[a] + 1.05e-3, s.cell.length[a]);
  s.cell.rate = Vec3(-60.0, 30.0, 20.0);  // 1/s: over 3000 steps (3e-4 s), -1.8 %, +0.9 %, +0.6 %
  World world(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
  std::uint64_t builds = list_builds(world.scratch());
  const std::uint64_t builds0 = builds;
  std::size_t touching_checked = 0, rebuild_checks = 0, missing_total = 0;
  const int steps = 3000;
  std::vector<int> wrapped(s.particles.size(), 0);
  std::size_t wraps = 0, touching_wrapped = 0;
  for (int step = 1; step <= steps; ++step) {
    const std::vector<Vec3> before = world.state().particles.position;
    world.step();
    const State& st = world.state();
    for (std::size_t k = 0; k < before.size(); ++k)
      for (int a = 0; a < 3; ++a)
        if (std::abs(st.particles.position[k][a] - before[k][a]) > 0.5 * st.cell.length[a]) {
          ++wraps;
          wrapped[k] = 1;
        }
    std::set<Key> engine;
    for (std::size_t k = 0; k < st.contacts.size(); ++k)
      engine.insert(Key{st.contacts.pairs.id_i[k], st.contacts.pairs.id_j[k], st.contacts.pairs.image[k]});
    if (list_builds(world.scratch()) != builds) {  // rebuilt in this step: exact equality
      builds = list_builds(world.scratch());
      std::fill(wrapped.begin(), wrapped.end(), 0);
      ++rebuild_checks;
      INFO("step " << step);
      check_same_pairs(listed(st), all_images(st, model.contact.skin));
    }
    // Completeness between builds: every pair that touches now is in the list.
    const BruteForce touching = all_images(st, 0.0);
    for (const Key& k : touching.pairs) {
      ++touching_checked;
      if (wrapped[std::get<0>(k)] || wrapped[std::get<1>(k)]) ++touching_wrapped;
      if (!engine.count(k)) ++missing_total;
    }
  }
  const std::uint64_t n_builds = list_builds(world.scratch()) - builds0;
  MESSAGE(n_builds << " rebuilds in " << steps << " steps; " << touching_checked << " touching pair-steps checked, "
                   << touching_wrapped << " of them with a sphere wrapped since the last build (" << wraps
                   << " wraps); cell now " << world.state().cell.length.transpose());
  CHECK(missing_total == 0);
  CHECK(rebuild_checks == n_builds);
  // The list is reused between builds (else this tests nothing) and rebuilt often enough to matter.
  CHECK(n_builds >= 5);
  CHECK(n_builds < steps / 5);
  CHECK(touching_checked > 1000);  // contacts did happen
}

TEST_CASE("a touching pair keeps its force while one of its spheres crosses faces between list builds") {
  // Two spheres in contact (overlap 1 um) drift together at 1 m/s along (1,1,1); the one next to
  // the corner of the cell crosses the three faces within the first 70 steps, long before the skin
  // criterion asks for a new list (2.6 um of displacement against a 0.3 mm skin). Whether the
  // engine wraps positions at every step or only at list builds, the pair's stored image must stay
  // consistent with the positions it is applied to (a stale image after a wrap loses the contact:
  // this test caught that in an earlier version, which wrapped every step). Without a dashpot and
  // friction the force is the Hertz force of the minimum-image overlap at every step; the overlap
  // shrinks smoothly as they repel (by 10 % over the 150 steps).
  const double R = 1e-3, delta0 = 1e-6, dt = 1e-8;
  Model model = default_model(dt);
  model.materials[0].restitution = 1.0;
  model.materials[0].friction = 0.0;
  model.contact.rolling = RollingModel::none;
  const double e_star = 1.0 / (2.0 * (1.0 - 0.09) / model.materials[0].young);
  const double k_hertz = 4.0 / 3.0 * e_star * std::sqrt(R / 2.0);
  for (int corner_id : {0, 1}) {  // the sphere at the corner is i (id 0) or j (id 1) of the pair
    INFO("sphere at the corner: id " << corner_id);
    State s;
    const double L = 16.0 * R;
    s.cell.length = s.cell.length0 = Vec3::Constant(L);
    const Vec3 corner_x = Vec3(L - 0.5e-6, L - 0.3e-6, L - 0.7e-6);
    const Vec3 axis = Vec3(1.0, 2.0, 2.0) / 3.0;
    const Vec3 other_x = corner_x - (2.0 * R - delta0) * axis;
    add_sphere(s, model, 0, corner_id == 0 ? corner_x : other_x, R, 0);
    add_sphere(s, model, 1, corner_id == 0 ? other_x : corner_x, R, 0);
    s.particles.velocity[0] = s.particles.velocity[1] = Vec3(1.0, 1.0, 1.0);
    World world(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
    const std::uint64_t builds0 = list_builds(world.scratch());
    bool crossed[3] = {false, false, false};
    int failures = 0;
    double worst = 0.0;
    for (int step = 1; step <= 150; ++step) {
      const Vec3 before = world.state().particles.position[corner_id];
      world.step();
      const State& st = world.state();
      // A face is crossed when the coordinate is past L (unwrapped) or jumped back by ~L (wrapped).
      for (int a = 0; a < 3; ++a)
        if (st.particles.position[corner_id][a] >= L || st.particles.position[corner_id][a] < before[a] - 0.5 * L)
          crossed[a] = true;
      Vec3 d = st.particles.position[0] - st.particles.position[1];
      for (int a = 0; a < 3; ++a) d[a] -= L * std::nearbyint(d[a] / L);  // minimum image
      const double delta = 2.0 * R - d.norm();
      REQUIRE(delta > 0.0);
      const double expected = k_hertz * std::pow(delta, 1.5);
      // Round-off: the engine and this check take the overlap from the same stored positions;
      // they may difference them differently (an ulp of L is 3.5e-18 m, against delta = 1e-6 m)
      // and round a few operations: 1e-9 is far above that (measured 7e-16) and far below the O(1)
      // error of a stale image (the force drops to zero).
      const double err = std::abs(st.particles.force[0].norm() / expected - 1.0);
      worst = std::max(worst, err);
      if (err > 1e-9 && ++failures == 1)  // report the first one
        FAIL_CHECK("step " << step << ": |F| = " << st.particles.force[0].norm() << " N, Hertz force of the "
                           << "minimum-image overlap " << delta << " m is " << expected << " N (pair image ("
                           << int(st.contacts.pairs.image[0][0]) << "," << int(st.contacts.pairs.image[0][1]) << ","
                           << int(st.contacts.pairs.image[0][2]) << "))");
    }
    CHECK(failures == 0);
    MESSAGE("corner sphere id " << corner_id << ": " << list_builds(world.scratch()) - builds0
                                << " list builds after the first, largest relative force error " << worst);
    CHECK((crossed[0] && crossed[1] && crossed[2]));
  }
}

TEST_CASE("a sliding contact keeps its tangential and rolling history when a list build wraps one of its spheres") {
  // Two touching spheres drift at 1 m/s along (1,1,1), one of them sliding past the other at
  // 0.02 m/s; with a 20 nm skin the list is rebuilt every step or two, so the corner sphere is
  // wrapped across the three faces while touching, and its pair changes image. The same pair run
  // in the middle of the cell (no wrap) is the reference: the stored tangential displacement and
  // rolling moment must follow the contact. Tolerance: the two runs differ only in where the
  // branch vector is differenced (positions ~L apart: an ulp of 16 mm is 3.5e-18 m against a
  // 1 um overlap and a 2e-10 m tangential displacement per step), so 1e-6 relative is far above
  // round-off; a history lost at a wrap restarts from zero, an O(1) difference. This test failed
  // before the fix (the history was matched by the old image alone).
  const double R = 1e-3, delta0 = 1e-6, dt = 1e-8, L = 16.0 * R;
  Model model = default_model(dt, 2e-8);
  model.materials[0].restitution = 1.0;
  model.materials[0].friction = 0.5;
  model.contact.rolling = RollingModel::epsd2;
  const Vec3 axis = Vec3(1.0, 2.0, 2.0) / 3.0;
  const Vec3 slide = Vec3(2.0, -1.0, 0.0).normalized() * 0.02;  // perpendicular to axis
  const auto run = [&](const Vec3& corner_x, int& builds, bool& crossed) {
    State s;
    s.cell.length = s.cell.length0 = Vec3::Constant(L);
    add_sphere(s, model, 0, corner_x, R, 0);
    add_sphere(s, model, 1, corner_x - (2.0 * R - delta0) * axis, R, 0);
    s.particles.velocity[0] = Vec3(1.0, 1.0, 1.0) + slide;
    s.particles.velocity[1] = Vec3(1.0, 1.0, 1.0);
    s.particles.angular_velocity[0] = Vec3(0.0, 0.0, 30.0);  // rolls: builds the rolling moment
    World world(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
    const std::uint64_t builds0 = list_builds(world.scratch());
    crossed = false;
    for (int step = 0; step < 150; ++step) {
      const double x_before = world.state().particles.position[0][0];
      world.step();
      if (world.state().particles.position[0][0] < x_before - 0.5 * L) crossed = true;
    }
    builds = static_cast<int>(list_builds(world.scratch()) - builds0);
    const State& st = world.state();
    std::size_t touching = st.contacts.size();
    for (std::size_t k = 0; k < st.contacts.size(); ++k)
      if (st.contacts.forces.force[k].squaredNorm() > 0.0) touching = k;
    REQUIRE(touching < st.contacts.size());
    return std::pair<Vec3, Vec3>(st.contacts.tangential[touching], st.contacts.rolling[touching]);
  };
  int builds_corner = 0, builds_bulk = 0;
  bool crossed_corner = false, crossed_bulk = false;
  const auto [u_corner, m_corner] = run(Vec3(L - 0.5e-6, L - 0.3e-6, L - 0.7e-6), builds_corner, crossed_corner);
  const auto [u_bulk, m_bulk] = run(Vec3(0.5 * L, 0.5 * L, 0.5 * L), builds_bulk, crossed_bulk);
  MESSAGE("list builds " << builds_corner << " (corner) / " << builds_bulk << " (bulk); |u_t| " << u_corner.norm()
                         << " / " << u_bulk.norm() << " m; |M_r| " << m_corner.norm() << " / " << m_bulk.norm()
                         << " N m");
  CHECK(crossed_corner);
  CHECK(!crossed_bulk);
  CHECK(builds_corner > 50);      // the wraps happen at list builds, many of them while touching
  REQUIRE(u_bulk.norm() > 1e-9);  // 150 steps of sliding and rolling: 4.5e-8 m (below the cap)
  REQUIRE(m_bulk.norm() > 0.0);
  CHECK((u_corner - u_bulk).norm() <= 1e-6 * u_bulk.norm());
  CHECK((m_corner - m_bulk).norm() <= 1e-6 * m_bulk.norm());
}

TEST_CASE("a cell narrower than 2 r_max + skin is a SimulationError naming the width") {
  const double R = 1e-3, skin = 0.3e-3;
  const Model model = default_model(1e-7, skin);
  SUBCASE("at construction") {
    State s;
    s.cell.length = s.cell.length0 = Vec3(10e-3, 0.99 * (2.0 * R + skin), 10e-3);
    add_sphere(s, model, 0, Vec3(5e-3, 1e-3, 5e-3), R, 0);
    add_sphere(s, model, 1, Vec3(1e-3, 1e-3, 1e-3), 0.5 * R, 0);
    std::string message;
    try {
      World world(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
    } catch (const SimulationError& e) {
      message = e.what();
    }
    MESSAGE("message: " << message);
    CHECK(message.find("width") != std::string::npos);
    CHECK(message.find("L2") != std::string::npos);  // the axis
  }
  SUBCASE("while the cell is compressed") {
    // 1.2 x cutoff along z, compressed at 1e4 /s (1e-3 per step): it crosses the cutoff after
    // ~180 steps. The list built at width w stays complete until the width has shrunk by the skin,
    // so the error must come before the width drops below 2 r_max (spheres meeting their images).
    State s;
    s.cell.length = s.cell.length0 = Vec3(10e-3, 10e-3, 1.2 * (2.0 * R + skin));
    add_sphere(s, model, 0, Vec3(5e-3, 5e-3, 1e-3), R, 0);
    s.cell.rate = Vec3(0.0, 0.0, -1e4);
    World world(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
    std::string message;
    int step = 0;
    try {
      for (; step < 1000; ++step) world.step();
    } catch (const SimulationError& e) {
      message = e.what();
    }
    const double width = world.state().cell.length.z();
    MESSAGE("thrown at step " << step << ", width " << width << " m: " << message);
    CHECK(message.find("width") != std::string::npos);
    CHECK(width < 2.0 * R + skin);
    CHECK(width > 2.0 * R);
  }
}

TEST_CASE("a state whose pair list has an image beyond one cell is refused, naming the contact and the image") {
  // The broadphase only ever builds images of -1, 0 or 1 (the cell is wider than the cutoff), and
  // the contact pass takes the image shift from a table of those 27: a list edited or read from
  // elsewhere with (2, 0, 0) must be refused at World construction, not read out of the table.
  const double R = 1e-3;
  const Model model = default_model(1e-7, 0.3e-3);
  State s;
  s.cell.length = s.cell.length0 = Vec3::Constant(10e-3);
  add_sphere(s, model, 3, Vec3(1e-3, 5e-3, 5e-3), R, 0);
  add_sphere(s, model, 8, Vec3(9e-3, 5e-3, 5e-3), R, 0);
  resize(s.contacts, 1);
  s.contacts.pairs.id_i[0] = 3;
  s.contacts.pairs.id_j[0] = 8;
  s.contacts.pairs.i[0] = 0;
  s.contacts.pairs.j[0] = 1;
  s.contacts.pairs.image[0] = Image{2, 0, 0};
  std::string message;
  try {
    World world(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 1}, false);
  } catch (const std::invalid_argument& e) {
    message = e.what();
  }
  MESSAGE("message: " << message);
  CHECK(message.find("ids 3, 8") != std::string::npos);
  CHECK(message.find("image = (2, 0, 0)") != std::string::npos);
  CHECK(message.find("-1, 0 or 1") != std::string::npos);
  // The same list with image (-1, 0, 0), the one the broadphase would build, is accepted.
  s.contacts.pairs.image[0] = Image{-1, 0, 0};
  CHECK_NOTHROW(World(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 1}, false));
}

namespace {

// Dyadic scene for exact periodicity checks: cell 2^-5 m, radius 2^-10 m, every coordinate a
// multiple of u = 2^-22 m (so the cell is 2^17 u), so x_j + L n and x_i - (x_j + L n) are exact
// whichever way they are computed: a pair across the boundary has bitwise the same branch vector
// as the same pair in the bulk, and must get bitwise the same forces.
constexpr double k_unit = 1.0 / double(1 << 22);
constexpr double k_cell = double(1 << 17) * k_unit;
constexpr double k_r = 1.0 / 1024.0;

State dyadic_pair(const Model& model, const Vec3& x0, const Vec3& branch) {
  State s;
  s.cell.length = s.cell.length0 = Vec3::Constant(k_cell);
  auto wrap = [](Vec3 x) {
    for (int a = 0; a < 3; ++a) {
      if (x[a] < 0.0) x[a] += k_cell;
      if (x[a] >= k_cell) x[a] -= k_cell;
    }
    return x;
  };
  add_sphere(s, model, 0, wrap(x0), k_r, 0);
  add_sphere(s, model, 1, wrap(x0 - branch), k_r, 0);  // r_01 = x0 - x1 = branch
  s.particles.velocity[0] = Vec3(0.25, -0.5, 0.125);
  s.particles.velocity[1] = Vec3(-0.125, 0.25, 0.375);
  s.particles.angular_velocity[0] = Vec3(100, -200, 50);
  s.particles.angular_velocity[1] = Vec3(-50, 25, 300);
  return s;
}

}  // namespace

TEST_CASE(
    "a contact across a face, an edge or a corner (image (1,1,1)) gives bitwise the force of the same pair in the bulk") {
  Model model = default_model(1.0 / double(1 << 24));  // dyadic dt too
  model.materials[0].restitution = 0.5;
  model.materials[0].friction = 0.4;
  model.materials[0].rolling_friction = 0.1;
  // Branch vectors r_01 = x_0 - x_1, |r| = 1.82e-3 m < 2R = 1.95e-3 m, along no axis.
  const Vec3 branches[] = {Vec3(1400, -1000, 600) * k_unit, Vec3(-1400, -1000, -600) * k_unit,
                           Vec3(600, 1400, -1000) * k_unit};
  const double centre = k_cell / 2.0;
  for (const Vec3& branch : branches) {
    REQUIRE(branch.norm() < 2.0 * k_r);
    World ref(model, dyadic_pair(model, Vec3::Constant(centre), branch), contact_systems(),
              ExecutorConfig{Backend::tbb, 2});
    // Which axes sphere 1 (at x_0 - r) lies across: faces, edges, the corner. Sphere 0 sits 300 u
    // inside the boundary that x_0 - r crosses; the expected image brings x_1 back next to x_0.
    const int masks[] = {1, 2, 4, 3, 6, 7};
    std::vector<std::unique_ptr<World>> worlds;
    std::vector<std::string> names;
    for (int mask : masks) {
      Vec3 x0 = Vec3::Constant(centre);
      Image image{0, 0, 0};
      for (int a = 0; a < 3; ++a)
        if (mask & (1 << a)) {
          x0[a] = branch[a] > 0.0 ? 300.0 * k_unit : k_cell - 300.0 * k_unit;
          image[a] = branch[a] > 0.0 ? -1 : 1;
        }
      worlds.push_back(std::make_unique<World>(model, dyadic_pair(model, x0, branch), contact_systems(),
                                               ExecutorConfig{Backend::tbb, 2}));
      names.push_back("branch (" + std::to_string(branch.x() / k_unit) + ", " + std::to_string(branch.y() / k_unit) +
                      ", " + std::to_string(branch.z() / k_unit) + ") u, image (" + std::to_string(image[0]) + "," +
                      std::to_string(image[1]) + "," + std::to_string(image[2]) + ")");
      const State& st = worlds.back()->state();
      INFO(names.back());
      REQUIRE(st.contacts.size() == 1);
      CHECK(st.contacts.pairs.image[0] == image);
    }
    // Step the contact systems only (positions fixed, velocities set: history accumulates) and
    // compare every step, from the setup on.
    for (int step = 0; step <= 20; ++step) {
      const State& r = ref.state();
      REQUIRE(r.contacts.size() == 1);
      CHECK(r.contacts.pairs.image[0] == Image{0, 0, 0});
      for (std::size_t k = 0; k < worlds.size(); ++k) {
        INFO(names[k] << ", step " << step);
        const State& st = worlds[k]->state();
        CHECK(st.contacts.forces.force[0] == r.contacts.forces.force[0]);
        CHECK(st.contacts.forces.torque_i[0] == r.contacts.forces.torque_i[0]);
        CHECK(st.contacts.forces.torque_j[0] == r.contacts.forces.torque_j[0]);
        CHECK(st.contacts.tangential[0] == r.contacts.tangential[0]);
        CHECK(st.contacts.rolling[0] == r.contacts.rolling[0]);
        CHECK(st.particles.force[1] == r.particles.force[1]);
        CHECK(st.particles.torque[0] == r.particles.torque[0]);
        if (step < 20) worlds[k]->step();
      }
      if (step < 20) ref.step();
    }
    // The contact is real: normal, tangential and rolling parts are all non-zero.
    const State& r = ref.state();
    CHECK(r.contacts.forces.force[0].norm() > 0.0);
    CHECK(r.contacts.tangential[0].norm() > 0.0);
    CHECK(r.contacts.rolling[0].norm() > 0.0);
  }
}

TEST_CASE("translating a dense packing by any vector (positions wrapped) changes no force beyond round-off") {
  Model model = default_model(1e-7);
  model.materials[0].friction = 0.5;
  model.materials[0].restitution = 0.5;
  // 343 spheres, radii 1.00-1.03 mm on a 2 mm lattice: lattice neighbours overlap by up to
  // 0.08 mm; random velocities so that the dashpots contribute.
  const State base = test::jittered_lattice(model, 7, 2e-3, 1.00e-3, 1.03e-3, 0.01e-3, 0.5, 200.0, 9);
  const double L = base.cell.length.x();
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(-2.0, 2.0);
  const int n_steps = 5;
  World ref(model, base, systems_for(model), ExecutorConfig{Backend::tbb, 2});
  const State r_setup = ref.state();
  ref.step(n_steps);
  const State& r_stepped = ref.state();
  // Round-off bound per particle: shifting and wrapping round each coordinate twice, by at most
  // ulp(L)/2 each, and the engine's difference of positions once more: the branch vector moves by
  // |dr| <= 3 sqrt(3) ulp(L)/2 < 3 eps L. A contact force then changes by at most
  // (S_n + |F| / |r|) |dr| (stiffness along n, turn of n), S_n = 2 E* sqrt(R* delta) the tangent
  // stiffness; the tangential spring and the dashpots are of the same order or smaller, so twice
  // that, summed over the contacts of a particle, bounds its force change at setup. Each step adds
  // at most one more rounding of ulp(L)/2 to each position (x += v dt at a different magnitude):
  // after n steps the bound grows by the factor (3 + n) / 3. A wrong image or wrap changes a force
  // by O(F).
  const double e_star = 1.0 / (2.0 * (1.0 - 0.09) / model.materials[0].young);
  std::vector<double> bound(base.particles.size(), 0.0);
  const ContactPairs& pr = r_setup.contacts.pairs;
  for (std::size_t k = 0; k < pr.size(); ++k) {
    const Vec3 rij = r_setup.particles.position[pr.i[k]] -
                     (r_setup.particles.position[pr.j[k]] + Vec3(pr.image[k][0], pr.image[k][1], pr.image[k][2]) * L);
    const double ri = r_setup.particles.radius[pr.i[k]], rj = r_setup.particles.radius[pr.j[k]];
    const double delta = ri + rj - rij.norm();
    if (delta <= 0.0) continue;
    const double s_n = 2.0 * e_star * std::sqrt(ri * rj / (ri + rj) * delta);
    const double b = 2.0 * (s_n + r_setup.contacts.forces.force[k].norm() / rij.norm()) * 3.0 * k_eps * L;
    bound[pr.i[k]] += b;
    bound[pr.j[k]] += b;
  }
  for (int trial = 0; trial < 4; ++trial) {
    const Vec3 shift = Vec3(u(rng), u(rng), u(rng)) * L;  // up to two cell lengths
    State moved = base;
    for (auto& x : moved.particles.position) {
      x += shift;
      for (int a = 0; a < 3; ++a) {
        x[a] -= std::floor(x[a] / L) * L;
        if (x[a] >= L) x[a] -= L;
      }
    }
    World w(model, moved, systems_for(model), ExecutorConfig{Backend::tbb, 2});
    INFO("shift " << shift.transpose());
    for (int stage = 0; stage < 2; ++stage) {
      const State& a = w.state();
      const State& b = stage == 0 ? r_setup : r_stepped;
      const double factor = stage == 0 ? 1.0 : (3.0 + n_steps) / 3.0;
      double worst_ratio = 0.0;
      std::size_t fails = 0;
      for (std::size_t k = 0; k < base.particles.size(); ++k) {
        const double diff = (a.particles.force[k] - b.particles.force[k]).norm();
        worst_ratio = std::max(worst_ratio, diff / (factor * bound[k]));
        if (diff > factor * bound[k]) ++fails;
        // Torques: lever arms <= R_max, rolling moments <= mu_r R* F_n: R_max times the force bound.
        if ((a.particles.torque[k] - b.particles.torque[k]).norm() > 1.03e-3 * factor * bound[k]) ++fails;
      }
      MESSAGE(std::string(stage == 0 ? "setup" : "after 5 steps")
              << ": largest force change / round-off bound = " << worst_ratio);
      CHECK(fails == 0);
      CHECK(a.contacts.size() == b.contacts.size());
      if (stage == 0) w.step(n_steps);
    }
  }
}
