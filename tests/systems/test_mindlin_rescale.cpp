// The tangential law mindlin_rescale (systems/laws/mindlin.hpp; LAMMPS GRANULAR `tangential
// mindlin_rescale`): a single contact loaded, sheared and unloaded, against the closed form.
#include "engine/checkpoint.hpp"
#include "engine/world.hpp"
#include "systems/broadphase.hpp"
#include "systems/contact_pass.hpp"
#include "systems/force_gather.hpp"

#include <doctest/doctest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <string>

using namespace sandcell;

namespace {

constexpr double k_r = 1e-3;  // m, both spheres
constexpr double k_eps = std::numeric_limits<double>::epsilon();

Model model_of(TangentialModel tangential) {
  Model m;
  m.dt = 1e-8;
  Material mat;  // E = 70 GPa, nu = 0.3
  mat.restitution = 1.0;
  mat.friction = 0.5;
  mat.rolling_friction = 0.0;
  m.materials.push_back(mat);
  m.contact.rolling = RollingModel::none;
  m.contact.tangential = tangential;
  return m;
}

// Two spheres at overlap delta along x, stepped by the contact systems only (positions stay put).
State held_pair(const Model& model, double delta) {
  State s;
  const double L = 16.0 * k_r;
  s.cell.length = s.cell.length0 = Vec3::Constant(L);
  const Vec3 c = Vec3::Constant(L / 2.0);
  add_sphere(s, model, 0, c - Vec3(k_r - delta / 2.0, 0, 0), k_r, 0);
  add_sphere(s, model, 1, c + Vec3(k_r - delta / 2.0, 0, 0), k_r, 0);
  return s;
}


std::vector<SystemSpec> contact_systems() {
  return {make_system<Broadphase>(), make_system<ContactPass>(), make_system<ForceGather>()};
}

struct Loaded {
  double f_t;             // N, tangential force on sphere 0 after the normal move
  double u;               // m, the stored displacement after it
  double radius;          // m, the stored contact radius (mindlin_rescale), else NaN
  double delta1, delta2;  // m, the overlaps as the engine sees them (2R - |x0 - x1|) before and after
};

double overlap_of(const State& s) { return 2.0 * k_r - (s.particles.position[0] - s.particles.position[1]).norm(); }

// Shear by u at delta1 (below the Coulomb cap), then move sphere 1 along x to overlap delta2 with
// no tangential motion and step once.
Loaded load_then_move(TangentialModel law, double delta1, double delta2) {
  const Model model = model_of(law);
  State s = held_pair(model, delta1);
  s.particles.velocity[1] = Vec3(0, 1e-2, 0);
  World world(model, s, contact_systems(), ExecutorConfig{Backend::tbb, 2});
  world.step(1000);  // u = 1000 v dt = 1e-7 m
  const double d1 = overlap_of(world.state());
  world.state().particles.velocity[1].setZero();
  world.state().particles.position[1].x() += delta1 - delta2;
  world.step();
  const Contacts& c = world.state().contacts;
  return {world.state().particles.force[0].y(), c.tangential[0].norm(),
          c.has_tangential_radius ? c.tangential_radius[0] : std::nan(""), d1, overlap_of(world.state())};
}

}  // namespace

TEST_CASE("mindlin_rescale: on unloading F_t = k_t(delta2) u sqrt(delta2 / delta1), on loading as the history law") {
  // Closed form: k_t = 8 G* a, a = sqrt(R* delta). Sheared by u at delta1, then unloaded to delta2 with no
  // tangential motion: the displacement is scaled by a2/a1 = sqrt(delta2/delta1), so F_t = k_t(delta2) u
  // sqrt(delta2/delta1), half of the history law's k_t(delta2) u at delta2 = delta1/4. Reloading (delta2 >
  // delta1) scales nothing. The closed form takes the overlaps the engine sees (the positions' rounding
  // moves delta by ~1e-10 relative from the nominal). Tolerance: u is a sum of 1000 equal increments (1000
  // roundings) and the rest a few operations: 4 x 1000 eps, as the history law's own test; a wrong exponent
  // (a2/a1 squared, or the rescale skipped) is off by a factor of 2.
  const double delta1 = 1e-6, u = 1000 * 1e-2 * 1e-8;
  const Material mat = model_of(TangentialModel::history).materials[0];
  const double g_star = 1.0 / (2.0 * (2.0 - mat.poisson) / (mat.young / (2.0 * (1.0 + mat.poisson))));
  const double r_star = k_r / 2.0;
  const double tol = 4.0 * 1000 * k_eps;
  for (const double delta2 : {0.25 * delta1, 4.0 * delta1}) {
    INFO("delta2 / delta1 = " << delta2 / delta1);
    const Loaded rescale = load_then_move(TangentialModel::mindlin_rescale, delta1, delta2);
    const Loaded history = load_then_move(TangentialModel::history, delta1, delta2);
    REQUIRE(rescale.delta2 == history.delta2);  // the same positions in both runs
    const double d1 = rescale.delta1, d2 = rescale.delta2;
    const double k_t2 = 8.0 * g_star * std::sqrt(r_star * d2);
    const double scale = d2 < d1 ? std::sqrt(r_star * d2) / std::sqrt(r_star * d1) : 1.0;  // a2 / a1
    CHECK(history.f_t == doctest::Approx(k_t2 * u).epsilon(tol));
    CHECK(rescale.f_t == doctest::Approx(k_t2 * u * scale).epsilon(tol));
    CHECK(rescale.u == doctest::Approx(u * scale).epsilon(tol));
    CHECK(rescale.radius == std::sqrt(r_star * d2));  // the engine's own formula: exact
    CHECK(std::isnan(history.radius));  // the other laws allocate no radius history
  }
}

TEST_CASE("mindlin_rescale: the radius history resets when the contact opens and survives a checkpoint") {
  const Model model = model_of(TangentialModel::mindlin_rescale);
  State s = held_pair(model, 1e-6);
  s.particles.velocity[1] = Vec3(0, 1e-2, 0);
  World world(model, s, contact_systems(), ExecutorConfig{Backend::tbb, 1});
  world.step(100);
  const Contacts& c = world.state().contacts;
  REQUIRE(c.has_tangential_radius);
  CHECK(c.tangential_radius[0] > 0.0);
  const auto path = std::filesystem::temp_directory_path() / "sandcell-mindlin-rescale.h5";
  write_checkpoint(path, world.state());
  const State back = read_checkpoint(path);
  std::filesystem::remove(path);
  CHECK(back.contacts.has_tangential_radius);
  CHECK(first_difference(back.contacts, world.state().contacts).empty());
  world.state().particles.position[1].x() += 2e-6;  // open, within the skin: the pair stays listed
  world.step();
  CHECK(c.tangential_radius[0] == 0.0);
  CHECK(c.tangential[0] == Vec3::Zero());
}

TEST_CASE("tangential and rolling laws by name: the registries the apps and Python read") {
  CHECK(tangential_law_names() == std::vector<std::string>{"history", "incremental", "mindlin_rescale"});
  CHECK(rolling_law_names() == std::vector<std::string>{"none", "epsd2", "epsd", "cdt"});
  for (const std::string& n : tangential_law_names()) CHECK(tangential_law_name(*tangential_law(n)) == n);
  for (const std::string& n : rolling_law_names()) CHECK(rolling_law_name(*rolling_law(n)) == n);
  CHECK_FALSE(tangential_law("mindlin").has_value());
}
