// The shearing periodic cell (components/cell.hpp, docs/physics.md section 1): a full upper
// triangular H, its affine field L x, wrapping and bins in reduced coordinates, flips.
//
// Round-off bounds below are written with u = eps/2, the unit round-off: one correctly rounded
// operation on values of size X errs by at most u X.
#include "engine/checkpoint.hpp"
#include "engine/world.hpp"
#include "systems/broadphase.hpp"
#include "systems/catalogue.hpp"
#include "systems/stress.hpp"
#include "support/scenes.hpp"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <vector>

using namespace sandcell;

namespace {

constexpr double k_u = 0.5 * std::numeric_limits<double>::epsilon();

Model quartz() { return test::quartz_model(2e-8, 0.05e-3); }

// A dense jittered lattice (every lattice neighbour touching), at rest.
State dense(const Model& model, std::size_t side = 6) {
  return test::jittered_lattice(model, side, 2e-3, 1.01e-3, 1.03e-3, 0.02e-3, 0.0, 0.0, 3);
}

// Row-sum norm, and the condition number it gives.
double inf_norm(const Mat3& m) { return m.cwiseAbs().rowwise().sum().maxCoeff(); }
double condition(const Mat3& m) { return inf_norm(m) * inf_norm(m.inverse()); }

// Each particle's position by id.
std::vector<Vec3> positions_by_id(const State& s) {
  std::vector<Vec3> x(s.particles.size());
  for (std::size_t k = 0; k < s.particles.size(); ++k) x[s.particles.id[k]] = s.particles.position[k];
  return x;
}

}  // namespace

TEST_CASE("simple shear of a dense packing to gamma = 2.5: flips, the deformation continuous, a finite stress") {
  const Model model = quartz();
  State s = dense(model);
  const double gamma_dot = 2000.0;  // 1/s: gamma = 2.5 in 62,500 steps
  s.cell.shear_rate = Vec3(0.0, gamma_dot, 0.0);
  World world(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
  const std::uint64_t steps = 62500;
  world.step(steps);
  const Cell& c = world.state().cell;
  MESSAGE("flips " << c.flip.transpose() << " tilt " << c.tilt.transpose() << " F " << c.deformation());
  CHECK(c.flip[1] != 0.0);
  CHECK(c.deformation()(0, 2) == doctest::Approx(double(steps) * gamma_dot * model.dt).epsilon(1e-9));
  const Mat3 sigma = contact_stress(world.state(), world.executor());
  MESSAGE("stress " << sigma);
  CHECK(sigma.allFinite());
}

// With v~ = 0 and no contact touching, the drift x += L x dt and the cell H += L H dt are the same
// map I + L dt, so s = H^-1 x is kept; a flip (H' = H E) and the wrap that follows it change s by
// integers only, and N counts the change of basis: H^-1 x - N s0 stays an integer vector. A wrong
// term of L H (or of L x), a flip miscounted in N, or a wrap by a vector off the lattice, each
// moves it by far more than round-off.
TEST_CASE(
    "spheres at rest in the affine field of a general upper triangular L stay on it through many flips: H^-1 x - N s0 "
    "integer to round-off") {
  // 4^3 spheres (radius 0.25 mm) on a 2 mm lattice with 0.2 mm jitter, at rest; contacts enabled
  // with a 0.5 mm skin, and a spatial sort every 50 steps, which sends the broadphase to a build
  // (400 builds: each flips the tilts that went past half a length since the last one, and wraps).
  Model model = test::quartz_model(1e-5, 0.5e-3);
  model.contact.sort_interval = 50;
  const State s = test::jittered_lattice(model, 4, 2e-3, 0.25e-3, 0.25e-3, 0.2e-3, 0.0, 0.0, 7);
  State sheared = s;
  // Over 0.2 s: xz to 5.0 (four flips), yz to -1.7 (two), xy to 0.7 (one); the lengths change by
  // +10 %, -15 %, +13 %.
  sheared.cell.rate = Vec3(0.5, -0.8, 0.6);
  sheared.cell.shear_rate = Vec3(3.5, 25.0, -8.5);
  const std::uint64_t steps = 20000;
  const Mat3 h0 = s.cell.h();
  const std::vector<Vec3> x0 = positions_by_id(s);
  std::vector<Vec3> s0(x0.size());
  for (std::size_t k = 0; k < x0.size(); ++k) s0[k] = h0.inverse() * x0[k];

  World world(model, sheared, systems_for(model), ExecutorConfig{Backend::tbb, 2});
  const Mat3 lg = world.state().cell.velocity_gradient();
  Mat3 p = Mat3::Identity();  // prod (I + L dt): F in exact arithmetic
  double kappa = condition(h0);
  std::vector<Mat3> bases{Mat3::Identity()};  // every N the run went through
  std::uint64_t builds = list_builds(world.scratch());
  std::size_t max_pairs = 0;
  double gap = std::numeric_limits<double>::infinity();  // m
  for (std::uint64_t step = 0; step < steps; ++step) {
    world.step();
    p = p + lg * p * model.dt;
    const Cell& c = world.state().cell;
    kappa = std::max(kappa, condition(c.h()));
    max_pairs = std::max(max_pairs, world.state().contacts.size());
    // The closest surfaces of the listed pairs (the affine field brings some within 0.16 mm).
    const State& now = world.state();
    for (std::size_t q = 0; q < now.contacts.size(); ++q) {
      const ContactPairs& pq = now.contacts.pairs;
      const Vec3 r =
          now.particles.position[pq.i[q]] - now.particles.position[pq.j[q]] - image_offset(pq.image[q], now.cell);
      gap = std::min(gap, r.norm() - now.particles.radius[pq.i[q]] - now.particles.radius[pq.j[q]]);
    }
    if (c.flips() != bases.back()) bases.push_back(c.flips());
    if (const std::uint64_t b = list_builds(world.scratch()); b != builds) {
      builds = b;
      // A build reduces the basis: |xy|, |xz| <= L1/2, |yz| <= L2/2 (t - k L rounds by u L at most).
      INFO("step " << step << " tilt " << c.tilt.transpose() << " length " << c.length.transpose());
      CHECK(std::abs(c.tilt[0]) <= 0.5 * c.length[0] * (1.0 + 4.0 * k_u));
      CHECK(std::abs(c.tilt[1]) <= 0.5 * c.length[0] * (1.0 + 4.0 * k_u));
      CHECK(std::abs(c.tilt[2]) <= 0.5 * c.length[1] * (1.0 + 4.0 * k_u));
    }
  }
  const State& end = world.state();
  const Cell& c = end.cell;
  MESSAGE("flips (xy, xz, yz) " << c.flip.transpose() << ", " << builds << " list builds, up to " << max_pairs
                                << " listed pairs (closest surfaces " << gap << " m apart), cond(H) <= " << kappa
                                << "\nF =\n"
                                << c.deformation());
  // Flips of every kind happened (xy, xz several times, yz the negative way), and the contact pass
  // had pairs to evaluate, none touching.
  REQUIRE(c.flip[0] != 0.0);
  REQUIRE(std::abs(c.flip[1]) >= 3.0);
  REQUIRE(c.flip[2] < 0.0);
  REQUIRE(max_pairs > 0);
  REQUIRE(gap > 0.0);
  // No contact touched: every velocity is still exactly zero.
  for (std::size_t k = 0; k < end.particles.size(); ++k) {
    REQUIRE(end.particles.velocity[k] == Vec3::Zero());
    REQUIRE(end.particles.angular_velocity[k] == Vec3::Zero());
  }

  // Error bound. Each step rounds each coordinate of x and each entry of H to u of its size (the
  // increments L x dt, L H dt are 1e-3 of those and carry a few u of their own size); with s in
  // [0, 1)^3, |x| <= |H| (row sums), so s moves by at most 2 u cond(H) per step: 3 u cond(H) bounds
  // it with the increments. A wrap at a build rounds x - H n the same way. An error made in
  // reduced coordinates while the flips were N_t shows in the final basis multiplied by
  // N_f N_t^-1 (x = H_t s_t = H_f N_f N_t^-1 s_t): at most G in row-sum norm.
  const Mat3 nf = c.flips();
  double g = 0.0;
  for (const Mat3& n : bases) g = std::max(g, inf_norm(nf * n.inverse()));
  const double bound = static_cast<double>(steps + builds + 4) * 3.0 * k_u * kappa * g;

  const std::vector<Vec3> x = positions_by_id(end);
  double worst = 0.0;
  for (std::size_t k = 0; k < x.size(); ++k) {
    const Vec3 d = reduced(x[k], c.length, c.tilt) - nf * s0[k];
    worst = std::max(worst, (d - d.array().round().matrix()).cwiseAbs().maxCoeff());
  }
  MESSAGE("largest drift of H^-1 x - N s0 from an integer: " << worst << " (bound " << bound << ", G = " << g << ")");
  CHECK(worst <= bound);

  // The cell itself: F = H N H0^-1 is prod (I + L dt) (the engine updates the lengths and tilts
  // entry by entry, the test multiplies matrices: both round each entry by u per step). In the
  // final reduced basis, H_f^-1 P H0 - N_f: the engine's part is bounded as for the particles; the
  // product's P_t H0 = H_t N_t adds |N_t| as much.
  double n_max = 0.0;
  for (const Mat3& n : bases) n_max = std::max(n_max, inf_norm(n));
  const Mat3 defect = c.h().inverse() * p * h0 - nf;
  const double f_bound = static_cast<double>(steps + 4) * 3.0 * k_u * kappa * g * (1.0 + n_max);
  MESSAGE("F against prod (I + L dt): " << defect.cwiseAbs().maxCoeff() << " (bound " << f_bound << ")");
  CHECK(defect.cwiseAbs().maxCoeff() <= f_bound);
}
