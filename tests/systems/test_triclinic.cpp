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
#include <array>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <random>
#include <set>
#include <tuple>
#include <vector>

#include <unistd.h>

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

namespace {

// Two spheres (ids 0 and 1) and what the engine did to them, step by step.
struct PairRun {
  std::vector<std::array<Vec3, 4>> load;  // force on 0, on 1, torque on 0, on 1 (N, N m)
  std::vector<std::array<Vec3, 2>> hist;  // the touching pair's tangential (m) and rolling (N m) histories
  std::vector<Image> image;               // the touching pair's image
  std::vector<int> touching;              // 1 when the pair overlaps
  std::vector<Vec3> flip;                 // the cell's flip counts
  double x_max = 0.0;                     // m, largest coordinate met: |x|, and |H n| <= |H| (row sums)
  double overlap_max = 0.0;               // m
};

PairRun run_pair(const Model& model, const State& s, std::uint64_t steps) {
  World world(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
  PairRun out;
  for (std::uint64_t step = 0; step < steps; ++step) {
    world.step();
    const State& st = world.state();
    const Particles& p = st.particles;
    std::array<Vec3, 4> load;
    for (std::size_t k = 0; k < 2; ++k) {
      load[p.id[k]] = p.force[k];
      load[2 + p.id[k]] = p.torque[k];
      out.x_max = std::max(out.x_max, p.position[k].cwiseAbs().maxCoeff());
    }
    out.x_max = std::max(out.x_max, inf_norm(st.cell.h()));
    out.load.push_back(load);
    std::array<Vec3, 2> hist{Vec3::Zero(), Vec3::Zero()};
    Image image{0, 0, 0};
    int touching = 0;
    const ContactPairs& pairs = st.contacts.pairs;
    for (std::size_t c = 0; c < pairs.size(); ++c) {
      const Vec3 r = p.position[pairs.i[c]] - p.position[pairs.j[c]] - image_offset(pairs.image[c], st.cell);
      const double overlap = p.radius[0] + p.radius[1] - r.norm();
      if (overlap <= 0.0) continue;
      REQUIRE(touching == 0);  // one image at most touches
      touching = 1;
      hist = {st.contacts.tangential[c], st.contacts.rolling[c]};
      image = pairs.image[c];
      out.overlap_max = std::max(out.overlap_max, overlap);
    }
    out.hist.push_back(hist);
    out.image.push_back(image);
    out.touching.push_back(touching);
    out.flip.push_back(st.cell.flip);
  }
  return out;
}

// Sphere 1 (0.8 mm) at x1, sphere 0 (1 mm) at x1 + r0, spinning, approaching obliquely.
State pair_state(const Model& model, const Cell& cell, const Vec3& x1, const Vec3& r0) {
  State s;
  s.cell = cell;
  add_sphere(s, model, 0, x1 + r0, 1.0e-3, 0);
  add_sphere(s, model, 1, x1, 0.8e-3, 0);
  const Vec3 n = r0.normalized();
  const Vec3 t = n.cross(Vec3(0.2, -1.0, 0.4)).normalized();
  s.particles.velocity[0] = -0.3 * n + 0.12 * t;
  s.particles.velocity[1] = 0.2 * n - 0.05 * t + 0.04 * n.cross(t);
  s.particles.angular_velocity[0] = Vec3(400.0, -300.0, 200.0);
  s.particles.angular_velocity[1] = Vec3(-250.0, 150.0, 350.0);
  return s;
}

// The collision of pair_state across a face of `tilted` (sphere 1 near the corner s = (1, 1, 1),
// sphere 0 beyond it, wrapped to the opposite corner) and in the middle of a 40 mm orthorhombic
// cell with the same velocity gradient; returns both runs.
std::pair<PairRun, PairRun> collide(const Model& model, const Cell& tilted, std::uint64_t steps) {
  const Vec3 r0 = Vec3(0.55, 0.62, 0.56).normalized() * (1.8e-3 + 0.05e-6);
  const Vec3 corner = tilted.h() * Vec3(0.93, 0.92, 0.94);
  Cell bulk = tilted;
  bulk.length = bulk.length0 = Vec3::Constant(40e-3);
  bulk.tilt = bulk.tilt0 = Vec3::Zero();
  return {run_pair(model, pair_state(model, tilted, corner, r0), steps),
          run_pair(model, pair_state(model, bulk, Vec3(20.3e-3, 19.7e-3, 20.1e-3), r0), steps)};
}

// Compares the two runs step by step. The exact trajectories of the branch vector, velocities and
// spins are the same; the runs differ only in rounding, as the coordinates differ (and the tilted
// run's branch vector subtracts H n). Each step rounds each coordinate by u X at most (X the
// largest coordinate met), so a branch vector carries at most 4 u X more error per step: e_r =
// 4 n u X after n steps. The force answers with the stiffness k = dF_n/d delta = 2 E* sqrt(R*
// delta) at the peak overlap, the tangential spring (k_t < k) and the dashpots adding less than
// that again; force errors feed back through the velocities, by at most (omega t_c)^2 = pi^2 over
// a collision: |dF| <= 30 k e_r. Torques: lever arms and the rolling moment add at most 2 R_max
// times that; the histories: u by 30 e_r, the rolling moment as torques.
void check_same_history(const Model& model, const PairRun& a, const PairRun& b) {
  const std::size_t n = a.load.size();
  const Material& m = model.materials[0];
  const double e_star = m.young / (2.0 * (1.0 - m.poisson * m.poisson));
  const double r_star = 1.0e-3 * 0.8e-3 / 1.8e-3;
  const double k = 2.0 * e_star * std::sqrt(r_star * b.overlap_max);
  const double e_r = 4.0 * static_cast<double>(n) * k_u * std::max(a.x_max, b.x_max);
  const double tol_f = 30.0 * k * e_r, tol_t = 2.0 * 1.0e-3 * tol_f, tol_u = 30.0 * e_r;
  double peak_f = 0.0, peak_t = 0.0, peak_u = 0.0, peak_m = 0.0;
  double err_f = 0.0, err_t = 0.0, err_u = 0.0, err_m = 0.0;
  for (std::size_t s = 0; s < n; ++s) {
    INFO("step " << s + 1);
    REQUIRE(a.touching[s] == b.touching[s]);
    for (int q = 0; q < 2; ++q) {
      peak_f = std::max(peak_f, b.load[s][q].norm());
      peak_t = std::max(peak_t, b.load[s][2 + q].norm());
      err_f = std::max(err_f, (a.load[s][q] - b.load[s][q]).norm());
      err_t = std::max(err_t, (a.load[s][2 + q] - b.load[s][2 + q]).norm());
    }
    peak_u = std::max(peak_u, b.hist[s][0].norm());
    peak_m = std::max(peak_m, b.hist[s][1].norm());
    err_u = std::max(err_u, (a.hist[s][0] - b.hist[s][0]).norm());
    err_m = std::max(err_m, (a.hist[s][1] - b.hist[s][1]).norm());
  }
  MESSAGE("peaks: force " << peak_f << " N, torque " << peak_t << " N m, u " << peak_u << " m, M " << peak_m
                          << " N m (overlap " << b.overlap_max << " m)\nlargest differences: force " << err_f
                          << " N (bound " << tol_f << "), torque " << err_t << " N m (bound " << tol_t << "), u "
                          << err_u << " m (bound " << tol_u << "), M " << err_m << " N m (bound " << tol_t << ")");
  CHECK(err_f <= tol_f);
  CHECK(err_t <= tol_t);
  CHECK(err_u <= tol_u);
  CHECK(err_m <= tol_t);
  // The bounds are small against what they guard: a lost history, a wrong image shift or affine
  // term changes the loads at the 1e-2 level of their peaks at least.
  CHECK(tol_f < 1e-4 * peak_f);
  CHECK(tol_t < 1e-4 * peak_t);
  CHECK(tol_u < 1e-4 * peak_u);
  CHECK(tol_t < 1e-4 * peak_m);
}

int nonzero_components(const Image& n) { return (n[0] != 0) + (n[1] != 0) + (n[2] != 0); }

}  // namespace

TEST_CASE(
    "two spheres colliding across a corner of a tilted cell feel, step by step, the force, torques and histories of "
    "the same pair in the bulk, to round-off") {
  Model model = test::quartz_model(2e-8, 0.02e-3);  // e = 0.5, mu = 0.5, mu_r = 0.1 (epsd2)
  // A list build every step (the sort forces it): the pair's image is recomputed at every step of
  // the collision, and a tilt past half a length flipped at once.
  model.contact.sort_interval = 1;
  const std::uint64_t steps = 500;  // the collision lasts about 330

  SUBCASE("a static tilted cell: the image spans the three axes") {
    Cell tilted;
    tilted.length = tilted.length0 = Vec3(6.0e-3, 6.4e-3, 6.8e-3);
    tilted.tilt = tilted.tilt0 = Vec3(0.3 * 6.0e-3, -0.4 * 6.0e-3, 0.45 * 6.4e-3);
    const auto [a, b] = collide(model, tilted, steps);
    int widest = 0, touching = 0;
    for (std::size_t s = 0; s < steps; ++s)
      if (a.touching[s]) {
        ++touching;
        widest = std::max(widest, nonzero_components(a.image[s]));
      }
    MESSAGE("touching for " << touching << " steps, image " << int(a.image[100][0]) << " " << int(a.image[100][1])
                            << " " << int(a.image[100][2]));
    REQUIRE(touching > 100);
    REQUIRE(!a.touching.back());  // the collision is over
    REQUIRE(widest >= 2);
    check_same_history(model, a, b);
  }

  SUBCASE("a cell sheared by a general L, flipped in the middle of the collision") {
    Cell tilted;
    tilted.length = tilted.length0 = Vec3(6.0e-3, 6.4e-3, 6.8e-3);
    tilted.rate = Vec3(150.0, -120.0, 100.0);
    tilted.shear_rate = Vec3(200.0, 300.0, -250.0);
    // xz just short of half a length: d(xz)/dt = L_xx xz + L_xy yz + L_xz L3 takes it past in
    // about 150 steps, while the spheres touch.
    const Vec3 t0(0.3 * 6.0e-3, 0.0, 0.45 * 6.4e-3);
    const double xz_rate = tilted.rate[0] * 3.0e-3 + tilted.shear_rate[0] * t0[2] + tilted.shear_rate[1] * 6.8e-3;
    tilted.tilt = tilted.tilt0 = Vec3(t0[0], 0.5 * 6.0e-3 - 150.0 * model.dt * xz_rate, t0[2]);
    const auto [a, b] = collide(model, tilted, steps);
    int touching = 0, flipped_touching = 0;
    for (std::size_t s = 0; s < steps; ++s) {
      touching += a.touching[s];
      if (s > 0 && a.flip[s] != a.flip[s - 1] && a.touching[s] && a.touching[s - 1]) {
        ++flipped_touching;
        MESSAGE("step " << s + 1 << ": flips " << a.flip[s].transpose() << ", image " << int(a.image[s - 1][0]) << " "
                        << int(a.image[s - 1][1]) << " " << int(a.image[s - 1][2]) << " -> " << int(a.image[s][0])
                        << " " << int(a.image[s][1]) << " " << int(a.image[s][2]));
        CHECK(a.image[s] != a.image[s - 1]);  // the flip changed the image the history is carried under
      }
    }
    MESSAGE("touching for " << touching << " steps");
    REQUIRE(touching > 100);
    REQUIRE(!a.touching.back());
    REQUIRE(flipped_touching == 1);
    CHECK(b.flip.back() == Vec3::Zero());  // the bulk cell never flips
    check_same_history(model, a, b);
  }
}

namespace {

// The dense packing in a tilted cell. Tilts of whole lattice spacings (2 mm) put the periodic
// images of lattice sites on lattice sites, so the packing is as dense across the tilted faces as
// inside. tilt0 = tilt: the reference (F = I).
State dense_tilted(const Model& model, const Vec3& spacings) {
  State s = dense(model);
  s.cell.tilt = s.cell.tilt0 = spacings * 2e-3;
  return s;
}

// The axial vector of a tensor's antisymmetric part, (S_yz - S_zy, S_zx - S_xz, S_xy - S_yx):
// for S = f r^T it is f x r.
Vec3 axial(const Mat3& s) { return Vec3(s(1, 2) - s(2, 1), s(2, 0) - s(0, 2), s(0, 1) - s(1, 0)); }

}  // namespace

// The contact torques of a pair, t_i = -c_i n x f_t - M and t_j = -c_j n x f_t + M, add up to
// -(c_i + c_j) n x f_t = f x r, since the lever arms c_i + c_j = R_i + R_j - delta = |r| and the
// normal force is parallel to r (the rolling moment cancels). Summed over contacts: the axial
// vector of the antisymmetric part of sum_c f_c (x) r_c is the particles' total torque, sum_k T_k.
// It vanishes only when the particles' moments balance; in a packing sheared at a finite rate they
// do not, so the identity is asserted, not the symmetry. Across a tilted face the branch vector
// must subtract the whole H n (its tilt part included) for the identity to hold.
TEST_CASE(
    "Love-Weber sum of a packing sheared by a general L through a flip: its antisymmetric part is the particles' total "
    "contact torque, to round-off") {
  const Model model = quartz();
  State s = dense_tilted(model, Vec3(1.0, 3.0, -2.0));  // xz at half a length: flips at once
  s.cell.rate = Vec3(-300.0, 150.0, 100.0);
  s.cell.shear_rate = Vec3(-800.0, 2000.0, 600.0);
  World world(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
  world.step(3000);
  const State& st = world.state();
  const Particles& p = st.particles;
  const ContactPairs& pairs = st.contacts.pairs;
  const ContactForces& cf = st.contacts.forces;
  REQUIRE(st.cell.flip != Vec3::Zero());

  const Mat3 sum = contact_stress_sum(pairs, cf.force, p.position, st.cell, world.executor());
  Vec3 torque = Vec3::Zero();
  for (const Vec3& t : p.torque) torque += t;
  // Round-off: S sums m products f r^T (each entry off by u |f||r|, the sum by m u sum |f||r|),
  // the axial vector subtracts two; the particle torques sum the m pairs' t_i, t_j in n + m
  // additions; per contact, t_i + t_j and f x r differ by the rounding of n, the arms and the
  // cross products, under 16 u (|f||r| + |t_i| + |t_j|).
  double size = 0.0;  // sum_c |f||r| + |t_i| + |t_j|, N m
  std::size_t touching = 0, across_tilted_faces = 0;
  for (std::size_t c = 0; c < pairs.size(); ++c) {
    const Vec3 r = p.position[pairs.i[c]] - p.position[pairs.j[c]] - image_offset(pairs.image[c], st.cell);
    size += cf.force[c].norm() * r.norm() + cf.torque_i[c].norm() + cf.torque_j[c].norm();
    if (cf.force[c].isZero(0.0)) continue;
    ++touching;
    across_tilted_faces += pairs.image[c][1] != 0 || pairs.image[c][2] != 0;
  }
  const double bound = 2.0 * k_u * static_cast<double>(pairs.size() + p.size() + 16) * size;
  const Vec3 defect = axial(sum) - torque;
  MESSAGE(touching << " touching contacts, " << across_tilted_faces << " across the tilted faces; flips "
                   << st.cell.flip.transpose() << "\nsum f x r " << axial(sum).transpose() << " N m, sum T "
                   << torque.transpose() << " N m\n|difference| " << defect.norm() << " N m (bound " << bound
                   << "); symmetric part of S " << (0.5 * (sum + sum.transpose())).norm() << " N m");
  REQUIRE(across_tilted_faces > 50);
  CHECK(defect.cwiseAbs().maxCoeff() <= bound);
  // Not 0 = 0: the particles are not in moment balance, by far more than the bound.
  CHECK(axial(sum).norm() > 1e3 * bound);
  // And the tilts matter: with the branch vectors of the orthorhombic cell (H n without the tilts)
  // the contacts across the tilted faces break the identity.
  Mat3 untilted = Mat3::Zero();
  for (std::size_t c = 0; c < pairs.size(); ++c)
    untilted +=
        cf.force[c] *
        (p.position[pairs.i[c]] - p.position[pairs.j[c]] - image_offset(pairs.image[c], st.cell.length)).transpose();
  MESSAGE("without the tilts: |difference| " << (axial(untilted) - torque).norm() << " N m");
  CHECK((axial(untilted) - torque).norm() > 1e3 * bound);
}

namespace {

// A listed pair as the test sees it: ids, branch vector, histories, whether it overlaps.
struct ListedPair {
  ParticleId id_i, id_j;
  Image image;
  Vec3 r, u, m;  // m; tangential (m), rolling (N m) histories
  double reach;  // m, R_i + R_j
};
std::vector<ListedPair> listed_pairs(const State& s) {
  std::vector<ListedPair> out;
  const Particles& p = s.particles;
  const ContactPairs& pairs = s.contacts.pairs;
  for (std::size_t c = 0; c < pairs.size(); ++c) {
    const std::uint32_t i = pairs.i[c], j = pairs.j[c];
    out.push_back({pairs.id_i[c], pairs.id_j[c], pairs.image[c],
                   p.position[i] - p.position[j] - image_offset(pairs.image[c], s.cell), s.contacts.tangential[c],
                   s.contacts.rolling[c], p.radius[i] + p.radius[j]});
  }
  return out;
}

// Forces a list build on a copy of `before` (a state whose tilts went past half a length since
// its last build) and checks that the flip changed the basis and nothing physical: every contact
// keeps its branch vector (to round-off) and its histories (bitwise: they are copied), F = H N H0^-1
// stays, the tilts are reduced.
void check_flip_at_build(const Model& model, const State& before) {
  State after = before;
  Scratch scratch;
  Executor exec(ExecutorConfig{Backend::serial, 1});
  build_neighbor_list(model, after, scratch, exec);
  REQUIRE(scratch.error.empty());
  const Cell& c0 = before.cell;
  const Cell& c1 = after.cell;
  MESSAGE("tilts " << c0.tilt.transpose() << " -> " << c1.tilt.transpose() << " m (lengths " << c0.length.transpose()
                   << "), flips " << c0.flip.transpose() << " -> " << c1.flip.transpose());
  REQUIRE(c1.flip != c0.flip);
  CHECK(std::abs(c1.tilt[0]) <= 0.5 * c1.length[0] * (1.0 + 4.0 * k_u));
  CHECK(std::abs(c1.tilt[1]) <= 0.5 * c1.length[0] * (1.0 + 4.0 * k_u));
  CHECK(std::abs(c1.tilt[2]) <= 0.5 * c1.length[1] * (1.0 + 4.0 * k_u));
  // H' N' = H N in exact arithmetic; t - k L rounds each tilt by u of its size, and the two products
  // H N H0^-1 round by 3 u of |H||N||H0^-1| per entry.
  const double f_bound = 8.0 * k_u *
                         std::max(inf_norm(c0.h()) * inf_norm(c0.flips()), inf_norm(c1.h()) * inf_norm(c1.flips())) *
                         inf_norm(c0.h0().inverse());
  const double f_defect = (c1.deformation() - c0.deformation()).cwiseAbs().maxCoeff();
  MESSAGE("F changed by " << f_defect << " (bound " << f_bound << ")");
  CHECK(f_defect <= f_bound);

  // Branch vectors: x_i - x_j - H n before, and after the wrap x' = x - H' s: each rounds by at
  // most 4 u of the largest coordinate or image shift X, twice.
  double x_max = 0.0;
  for (const State* s : {&before, static_cast<const State*>(&after)})
    for (const Vec3& x : s->particles.position) x_max = std::max(x_max, x.cwiseAbs().maxCoeff());
  const double r_bound = 16.0 * k_u * (x_max + std::max(inf_norm(c0.h()), inf_norm(c1.h())));
  const std::vector<ListedPair> old_pairs = listed_pairs(before), new_pairs = listed_pairs(after);
  std::vector<int> matched(new_pairs.size(), 0);
  std::size_t touching = 0, with_history = 0, image_changed = 0, left = 0;
  double r_err = 0.0;
  for (const ListedPair& a : old_pairs) {
    const bool touches = a.r.norm() < a.reach;
    touching += touches;
    with_history += !a.u.isZero(0.0);
    std::size_t found = new_pairs.size();
    for (std::size_t q = 0; q < new_pairs.size(); ++q) {
      const ListedPair& b = new_pairs[q];
      if (b.id_i != a.id_i || b.id_j != a.id_j || (b.r - a.r).cwiseAbs().maxCoeff() > r_bound) continue;
      REQUIRE(found == new_pairs.size());  // one match at most (other images are a lattice vector away)
      found = q;
    }
    INFO("pair " << a.id_i << "-" << a.id_j << " r " << a.r.transpose());
    if (found == new_pairs.size()) {
      // Left the list: farther than R_i + R_j + skin at this build, without history.
      ++left;
      CHECK(a.r.norm() >= (a.reach + model.contact.skin) * (1.0 - 1e-12));
      CHECK(a.u.isZero(0.0));
      CHECK(a.m.isZero(0.0));
      continue;
    }
    const ListedPair& b = new_pairs[found];
    matched[found] = 1;
    r_err = std::max(r_err, (b.r - a.r).cwiseAbs().maxCoeff());
    image_changed += b.image != a.image;
    CHECK(b.u == a.u);
    CHECK(b.m == a.m);
  }
  std::size_t joined = 0;
  for (std::size_t q = 0; q < new_pairs.size(); ++q) {
    if (matched[q]) continue;
    ++joined;  // new in the list: not touching, no history
    CHECK(new_pairs[q].r.norm() >= new_pairs[q].reach);
    CHECK(new_pairs[q].u.isZero(0.0));
    CHECK(new_pairs[q].m.isZero(0.0));
  }
  MESSAGE(old_pairs.size() << " pairs listed before, " << new_pairs.size() << " after (" << left << " left, " << joined
                           << " joined); " << touching << " touching, " << with_history
                           << " with a tangential history, " << image_changed
                           << " under a new image; branch vectors moved by " << r_err << " m (bound " << r_bound
                           << ")");
  REQUIRE(touching > 100);
  REQUIRE(with_history > 100);
  CHECK(image_changed > 10);  // the flip re-expressed the images across the tilted faces
}

}  // namespace

TEST_CASE(
    "a list build that flips the cell keeps every contact: the same pairs, branch vectors to round-off, histories "
    "bitwise; F unchanged, tilts reduced") {
  const Model model = quartz();
  SUBCASE("xz past half a length after a simple shear from xz = L1/3") {
    State s = dense_tilted(model, Vec3(1.0, 2.0, -2.0));
    s.cell.shear_rate = Vec3(300.0, 2000.0, -300.0);
    World world(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
    // Step until xz passes L1/2 (about 4,200 steps); the state is then one whose flip is due at
    // the next build.
    for (int step = 0; step < 10000; ++step) {
      world.step();
      REQUIRE(world.state().cell.flip == Vec3::Zero());
      if (world.state().cell.tilt[1] > 0.5 * world.state().cell.length[0]) break;
    }
    REQUIRE(world.state().cell.tilt[1] > 0.5 * world.state().cell.length[0]);
    check_flip_at_build(world.model(), world.state());
  }
  SUBCASE("xy and yz past half a length (yz's flip takes c - b, which brings xz near 0)") {
    // All three tilts at half a length (the setup build leaves them), then one step at a shear
    // rate that takes them past it without a build: the contacts have one step of history.
    State s = dense_tilted(model, Vec3(3.0, 3.0, 3.0));
    s.cell.shear_rate = Vec3(2000.0, 2000.0, 2000.0);
    World world(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
    world.step();
    REQUIRE(world.state().cell.flip == Vec3::Zero());
    check_flip_at_build(world.model(), world.state());
  }
}

namespace {

bool same_bits(const Vec3& a, const Vec3& b) { return std::memcmp(a.data(), b.data(), sizeof(Vec3)) == 0; }

// Every field of two states, bit for bit: particles and contacts through the field registry, the
// whole cell, the list's reference cell, the clock.
void check_same_state(const State& a, const State& b) {
  CHECK(first_difference(a.particles, b.particles) == "");
  CHECK(first_difference(a.contacts, b.contacts) == "");
  const Cell &p = a.cell, &q = b.cell;
  CHECK(same_bits(p.length, q.length));
  CHECK(same_bits(p.tilt, q.tilt));
  CHECK(same_bits(p.length0, q.length0));
  CHECK(same_bits(p.tilt0, q.tilt0));
  CHECK(same_bits(p.flip, q.flip));
  CHECK(same_bits(p.rate, q.rate));
  CHECK(same_bits(p.shear_rate, q.shear_rate));
  CHECK(same_bits(p.servo_integral, q.servo_integral));
  CHECK(same_bits(p.shear_integral, q.shear_integral));
  CHECK(same_bits(a.contacts.pairs.reference_length, b.contacts.pairs.reference_length));
  CHECK(same_bits(a.contacts.pairs.reference_tilt, b.contacts.pairs.reference_tilt));
  CHECK(a.clock.step == b.clock.step);
  CHECK(std::memcmp(&a.clock.time, &b.clock.time, sizeof(double)) == 0);
}

// A dense packing sheared by a general L: xz starts at half a length (it flips at the first
// build after the start), yz 0.3 mm short of it (it flips after about 1,900 steps, and its flip
// c - b takes xz past -L1/2, which flips xz back).
State sheared_packing(const Model& model) {
  State s = dense_tilted(model, Vec3(1.0, 3.0, 0.0));
  s.cell.tilt[2] = s.cell.tilt0[2] = 6.0e-3 - 0.3e-3;
  s.cell.rate = Vec3(-300.0, 150.0, 100.0);
  s.cell.shear_rate = Vec3(-800.0, 2000.0, 600.0);
  return s;
}

}  // namespace

TEST_CASE(
    "a packing sheared through flips: serial, 1, 2 and 3 threads, one step per call or many, give bitwise the same "
    "state, and so does a run continued from a checkpoint written mid-shear") {
  const Model model = quartz();
  const State s = sheared_packing(model);
  constexpr std::uint64_t half = 1500;
  const auto run = [&](ExecutorConfig cfg) {
    World w(model, s, systems_for(model), cfg);
    w.step(2 * half);
    return w.state();
  };
  const State reference = run({Backend::serial, 1});
  MESSAGE("flips " << reference.cell.flip.transpose() << ", " << reference.contacts.size() << " pairs");
  REQUIRE(first_difference(reference.particles, s.particles) != "");  // the run did something
  REQUIRE(reference.cell.flip[2] != 0.0);  // yz flipped (and xz back: N = (0, 0, 1), see below)
  for (int threads : {1, 2, 3}) {
    INFO("threads = " << threads);
    check_same_state(run({Backend::tbb, threads}), reference);
  }
  {
    // One step per call: no final kick left to the next step's drift (World::step_until).
    INFO("one step per call");
    World w(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
    for (std::uint64_t k = 0; k < 2 * half; ++k) w.step();
    check_same_state(w.state(), reference);
  }

  // The checkpoint: written after `half` steps (xz flipped, yz not yet), read back, continued by a
  // World that takes the forces of the file (initial_forces = false), as a restart does.
  const std::filesystem::path path =
      std::filesystem::temp_directory_path() / ("sandcell_test_triclinic_" + std::to_string(::getpid()) + ".h5");
  World first(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
  first.step(half);
  REQUIRE(first.state().cell.flip[1] != 0.0);
  REQUIRE(first.state().cell.flip[2] == 0.0);
  write_checkpoint(path, first.state());
  const State back = read_checkpoint(path);
  std::filesystem::remove(path);
  check_same_state(back, first.state());
  World resumed(model, back, systems_for(model), ExecutorConfig{Backend::tbb, 2}, false);
  resumed.step(half);
  // The continued run flipped too: yz, c - b, took xz past -L1/2, and xz flipped back.
  CHECK(resumed.state().cell.flip != back.cell.flip);
  check_same_state(resumed.state(), reference);
}

namespace {

using PairKey = std::tuple<ParticleId, ParticleId, Image>;  // (id_i, id_j, image), id_i < id_j

// Every (id_i < id_j, image n in {-2..2}^3) with |x_i - x_j - H n| < R_i + R_j + skin, by brute
// force; within 1e-12 (relative) of the cutoff into `ties` (the engine may round either way).
void all_images(const State& s, double skin, std::set<PairKey>& pairs, std::set<PairKey>& ties) {
  const Particles& p = s.particles;
  for (std::size_t a = 0; a < p.size(); ++a)
    for (std::size_t b = 0; b < p.size(); ++b) {
      if (p.id[a] >= p.id[b]) continue;
      const double cut = p.radius[a] + p.radius[b] + skin;
      for (int nz = -2; nz <= 2; ++nz)
        for (int ny = -2; ny <= 2; ++ny)
          for (int nx = -2; nx <= 2; ++nx) {
            const Image n{std::int8_t(nx), std::int8_t(ny), std::int8_t(nz)};
            const double d = (p.position[a] - p.position[b] - image_offset(n, s.cell)).norm();
            const PairKey key{p.id[a], p.id[b], n};
            if (std::abs(d - cut) <= 1e-12 * cut)
              ties.insert(key);
            else if (d < cut)
              pairs.insert(key);
          }
    }
}

}  // namespace

// The broadphase bins reduced coordinates, with as many bins per axis as the width between faces
// holds cutoffs: in a cell whose tilts reach half a length, the widths are well below the lengths,
// and a bin count taken from the lengths (or an image search along the axes) would miss pairs.
TEST_CASE("in tilted cells down to 1.05 cutoffs between faces, the pair list equals an all-images O(N^2) search") {
  const double r_min = 0.5e-3, r_max = 1e-3, skin = 0.3e-3;
  const double cut = 2.0 * r_max + skin;
  const Model model = test::quartz_model(1e-7, skin);
  struct Shape {
    Vec3 length;   // relative
    Vec3 tilt;     // xy, xz as fractions of L1, yz of L2
    double width;  // the smallest width between faces, in cutoffs
  };
  const Shape shapes[] = {{{1, 1, 1}, {0.5, 0.5, 0.5}, 1.05},      {{1, 2.5, 4}, {-0.5, 0.3, -0.45}, 1.05},
                          {{3, 1, 2}, {0.49, -0.49, 0.2}, 1.05},   {{1, 1, 1}, {-0.3, 0.45, 0.5}, 2.1},
                          {{1, 1.2, 0.9}, {0.5, -0.5, -0.5}, 3.3}, {{1, 1, 1}, {0.25, -0.1, 0.4}, 6.0}};
  std::uint64_t seed = 40;
  std::size_t compared = 0, multi_axis = 0;
  for (const Shape& shape : shapes) {
    Cell cell;
    cell.length = shape.length;
    cell.tilt = Vec3(shape.tilt[0] * shape.length[0], shape.tilt[1] * shape.length[0], shape.tilt[2] * shape.length[1]);
    const double scale = shape.width * cut / cell.min_width();
    cell.length *= scale;
    cell.tilt *= scale;
    cell.length0 = cell.length;
    cell.tilt0 = cell.tilt;
    const double mean_volume = 4.0 / 3.0 * 3.14159 * std::pow(0.75e-3, 3);
    const auto n = std::max<std::size_t>(3, static_cast<std::size_t>(0.4 * cell.volume() / mean_volume));
    for (int rep = 0; rep < 3; ++rep) {
      State s;
      s.cell = cell;
      std::mt19937_64 rng(++seed);
      std::uniform_real_distribution<double> u01(0.0, 1.0);
      for (std::size_t k = 0; k < n; ++k)
        add_sphere(s, model, static_cast<ParticleId>(k), cell.h() * Vec3(u01(rng), u01(rng), u01(rng)),
                   r_min + (r_max - r_min) * u01(rng), 0);
      INFO("cell H =\n"
           << cell.h() << "\nwidths " << cell.widths().transpose() << " m, " << n << " spheres, seed " << seed);
      World world(model, s, {make_system<Broadphase>()}, ExecutorConfig{Backend::tbb, 2});
      std::set<PairKey> engine, brute, ties;
      const ContactPairs& c = world.state().contacts.pairs;
      for (std::size_t k = 0; k < c.size(); ++k) engine.insert({c.id_i[k], c.id_j[k], c.image[k]});
      CHECK(engine.size() == c.size());  // no duplicates
      all_images(world.state(), skin, brute, ties);
      for (const PairKey& k : ties) engine.erase(k);
      for (const PairKey& k : brute) {
        const Image& img = std::get<2>(k);
        INFO("pair " << std::get<0>(k) << "-" << std::get<1>(k) << " image " << int(img[0]) << " " << int(img[1]) << " "
                     << int(img[2]));
        CHECK(engine.count(k) == 1);
        multi_axis += nonzero_components(img) >= 2;
      }
      CHECK(engine.size() == brute.size());
      compared += brute.size();
    }
  }
  MESSAGE(compared << " pairs compared, " << multi_axis << " of them through images along two or three axes");
  CHECK(multi_axis > 0);
}

namespace {

// Every (id_i < id_j, image n) with |x_i - x_j - H n| < R_i + R_j + extra, in any cell wider than
// the cutoff between faces: a branch vector shorter than w_k has |s_k - n_k| < cutoff / w_k < 1 in
// reduced coordinates s = H^-1 (x_i - x_j), so two values of n_k at most per axis.
std::set<PairKey> pairs_within(const State& s, double extra, double r_max) {
  const Particles& p = s.particles;
  const Vec3 widths = s.cell.widths();
  const double cut_max = 2.0 * r_max + extra;
  REQUIRE(cut_max < widths.minCoeff());
  std::set<PairKey> out;
  for (std::size_t a = 0; a < p.size(); ++a)
    for (std::size_t b = 0; b < p.size(); ++b) {
      if (p.id[a] >= p.id[b]) continue;
      const Vec3 d = reduced(p.position[a] - p.position[b], s.cell.length, s.cell.tilt);
      std::array<std::array<int, 2>, 3> n{};
      std::array<int, 3> count{};
      for (int k = 0; k < 3; ++k)
        for (const double c : {std::floor(d[k]), std::floor(d[k]) + 1.0})
          if (std::abs(d[k] - c) < cut_max / widths[k]) n[k][count[k]++] = static_cast<int>(c);
      const double cut = p.radius[a] + p.radius[b] + extra;
      for (int i0 = 0; i0 < count[0]; ++i0)
        for (int i1 = 0; i1 < count[1]; ++i1)
          for (int i2 = 0; i2 < count[2]; ++i2) {
            const Image img{std::int8_t(n[0][i0]), std::int8_t(n[1][i1]), std::int8_t(n[2][i2])};
            if ((p.position[a] - p.position[b] - image_offset(img, s.cell)).norm() < cut)
              out.insert({p.id[a], p.id[b], img});
          }
    }
  return out;
}

}  // namespace

// Between builds the list is kept while 2 d_max + |H H_ref^-1 - I| (2 r_max + skin) <= skin: the
// affine change of every branch vector since the build counted by the Frobenius norm of the
// deformation since the build (a tilted cell), flips only at builds. Each step, every touching pair
// must be listed, under the image the positions (unwrapped since the build) need.
TEST_CASE(
    "in a cell sheared by a general L through flips, every touching pair stays listed between builds, and each build "
    "lists exactly the pairs within the cutoff") {
  const double skin = 0.1e-3, r_max = 1.0e-3;
  Model model = test::quartz_model(1e-7, skin);
  // 125 spheres (0.9-1.0 mm) on a 2.1 mm lattice, shifted half a spacing so that spheres sit on the
  // faces, at 5 m/s and 100 rad/s; xy, xz 0.45 L, yz -0.45 L with shear rates that take each past
  // half a length within the 3,000 steps.
  State s = test::jittered_lattice(model, 5, 2.1e-3, 0.9e-3, r_max, 0.02e-3, 5.0, 100.0, 78);
  for (Vec3& x : s.particles.position)
    for (int a = 0; a < 3; ++a) x[a] = std::fmod(x[a] + 1.05e-3, s.cell.length[a]);
  const double l = s.cell.length[0];
  s.cell.tilt = s.cell.tilt0 = Vec3(0.45 * l, 0.45 * l, -0.45 * l);
  s.cell.rate = Vec3(-60.0, 30.0, 20.0);
  s.cell.shear_rate = Vec3(300.0, 400.0, -300.0);
  World world(model, s, systems_for(model), ExecutorConfig{Backend::tbb, 2});
  std::uint64_t builds = list_builds(world.scratch());
  const std::uint64_t builds0 = builds;
  std::size_t touching_checked = 0, missing = 0, exact_builds = 0, flip_builds = 0;
  Vec3 flip = world.state().cell.flip;
  const int steps = 3000;
  for (int step = 1; step <= steps; ++step) {
    world.step();
    const State& st = world.state();
    std::set<PairKey> engine;
    const ContactPairs& c = st.contacts.pairs;
    for (std::size_t k = 0; k < c.size(); ++k) engine.insert({c.id_i[k], c.id_j[k], c.image[k]});
    if (list_builds(world.scratch()) != builds) {  // built in this step: exactly the pairs within the cutoff
      builds = list_builds(world.scratch());
      ++exact_builds;
      flip_builds += st.cell.flip != flip;
      flip = st.cell.flip;
      INFO("step " << step);
      CHECK(engine == pairs_within(st, skin, r_max));
    }
    for (const PairKey& k : pairs_within(st, 0.0, r_max)) {
      ++touching_checked;
      missing += !engine.count(k);
    }
  }
  const std::uint64_t n_builds = list_builds(world.scratch()) - builds0;
  MESSAGE(n_builds << " builds in " << steps << " steps (" << flip_builds
                   << " of them flipped: " << world.state().cell.flip.transpose() << "); " << touching_checked
                   << " touching pair-steps checked");
  CHECK(missing == 0);
  CHECK(exact_builds == n_builds);
  CHECK(flip_builds >= 2);
  CHECK(n_builds >= 5);
  CHECK(n_builds < steps / 5);  // the list is reused between builds (else this tests nothing)
  CHECK(touching_checked > 1000);
}
