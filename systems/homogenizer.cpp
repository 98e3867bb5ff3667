#include "systems/homogenizer.hpp"

#include "systems/contact_pass.hpp"
#include "systems/stress.hpp"

#include "engine/assert.hpp"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <string>
#include <vector>

namespace sandcell {

namespace {

// sum over particles of m v~ (x) v~ (a symmetric tensor), deterministic.
Mat3 kinetic_sum(const std::vector<Vec3>& v, const std::vector<double>& m, Executor& exec) {
  return exec.deterministic_reduce(
      v.size(), 4096, Mat3(Mat3::Zero()),
      [&](std::size_t b, std::size_t e) {
        Mat3 s = Mat3::Zero();
        for (std::size_t k = b; k < e; ++k) s += m[k] * v[k] * v[k].transpose();
        return s;
      },
      [](const Mat3& a, const Mat3& b) { return Mat3(a + b); });
}

}  // namespace

void Homogenizer::run(const Model& model, State& state, Scratch& scratch, Executor& exec) {
  if (!servo_due(model.servo, state.clock.step)) return;
  const Cell& cell = state.read<Component::cell>();
  Mat3 sum = Mat3::Zero();
  if (model.contact.enabled) {  // the contact pass of this step summed f (x) r per block
    const StressBlocks& blocks = scratch.read<StressBlocks>();
    SANDCELL_CHECK(blocks.step == state.clock.step,
                   "homogenizer: the contact pass summed no stress at step " + std::to_string(state.clock.step) +
                       " (it must run before the homogenizer in the same step)");
    const std::size_t n_blocks = (blocks.pairs + StressBlocks::k_stress_block - 1) / StressBlocks::k_stress_block;
    const double* s = blocks.sum.data();
    sum = exec.deterministic_reduce(
        n_blocks, 256, Mat3(Mat3::Zero()),
        [s](std::size_t b, std::size_t e) {
          double t[9] = {};  // in registers, block after block in order
          for (std::size_t k = b; k < e; ++k)
            for (int c = 0; c < 9; ++c) t[c] += s[9 * k + c];
          Mat3 m;
          m << t[0], t[1], t[2], t[3], t[4], t[5], t[6], t[7], t[8];  // row a: f_a r_b
          return m;
        },
        [](const Mat3& a, const Mat3& b) { return Mat3(a + b); });
  }
  if (model.servo.kinetic_stress)
    sum += kinetic_sum(state.read<Component::particle_velocity>(), state.read<Component::particle_mass>(), exec);
  MeasuredStress& out = scratch.write<MeasuredStress>();
  const Mat3 s = sum / cell.volume();
  out.stress = 0.5 * (s + s.transpose());
  out.step = state.clock.step;
}

StressInvariants invariants(const Mat3& stress) {
  StressInvariants r;
  const Mat3 sym = 0.5 * (stress + stress.transpose());
  Vec3 ev;
  if (sym(0, 1) == 0.0 && sym(0, 2) == 0.0 && sym(1, 2) == 0.0) {
    ev = sym.diagonal();  // principal-aligned cell: exact, no iteration round-off
  } else {
    Eigen::SelfAdjointEigenSolver<Mat3> solver(sym, Eigen::EigenvaluesOnly);
    ev = solver.eigenvalues();
  }
  std::sort(ev.data(), ev.data() + 3, [](double a, double b) { return a > b; });
  r.principal = ev;
  const double s1 = ev[0], s2 = ev[1], s3 = ev[2];
  r.p = (s1 + s2 + s3) / 3.0;
  r.q = std::sqrt(0.5 * ((s1 - s2) * (s1 - s2) + (s2 - s3) * (s2 - s3) + (s3 - s1) * (s3 - s1)));
  r.eta = r.p > 0.0 ? r.q / r.p : 0.0;
  // b is undefined for an isotropic stress; report 0 (compression) rather than a NaN.
  r.b = s1 - s3 > 0.0 ? (s2 - s3) / (s1 - s3) : 0.0;
  r.theta = std::atan(std::sqrt(3.0) * r.b / (2.0 - r.b));
  return r;
}

double median_diameter(std::span<const double> radius) {
  if (radius.empty()) return 0.0;
  // Summed in ascending order of radius, so any order of the input (a spatial sort, a file) gives
  // the same bits.
  std::vector<double> r(radius.begin(), radius.end());
  std::sort(r.begin(), r.end());
  double total = 0.0;
  for (double x : r) total += x * x * x;
  double passing = 0.0;
  for (double x : r) {
    passing += x * x * x;
    if (passing >= 0.5 * total) return 2.0 * x;
  }
  return 2.0 * r.back();
}

double median_diameter(const Particles& particles) { return median_diameter(particles.radius); }

Measures measure(const Model& model, const State& state, Executor& exec, const MeasureOptions& options) {
  Measures m;
  m.dt = model.dt;
  const Particles& p = state.particles;
  const Contacts& c = state.contacts;
  const Cell& cell = state.cell;
  const std::size_t n = p.size();
  const double volume = cell.volume();

  const std::size_t n_pairs = std::min(c.pairs.size(), c.forces.force.size());
  const Mat3 sum = contact_stress_sum(c.pairs, c.forces.force, p.position, cell, exec);
  m.contact_stress = 0.5 * (sum + sum.transpose()) / volume;
  m.stress = m.contact_stress;
  if (options.kinetic_stress) m.stress += kinetic_sum(p.velocity, p.mass, exec) / volume;
  m.inv = invariants(m.stress);

  for (int a = 0; a < 3; ++a) {
    m.strain[a] = -std::log(cell.length[a] / cell.length0[a]);
    m.strain_engineering[a] = 1.0 - cell.length[a] / cell.length0[a];
    m.strain_rate[a] = -cell.rate[a];
  }
  // The tensors (systems/kinematics.hpp); a diagonal deformation takes the lengths' arithmetic, so
  // its strain tensor is diag(strain) bitwise and its principal values are the strains sorted.
  const bool diagonal = diagonal_deformation(cell);
  if (diagonal) {
    m.deformation = Mat3::Zero();
    for (int a = 0; a < 3; ++a) m.deformation(a, a) = cell.length[a] / cell.length0[a];
  } else {
    m.deformation = cell.deformation();
  }
  m.strain_tensor = cell_strain(cell);
  m.strain_rate_tensor = strain_rate_tensor(cell.velocity_gradient());
  m.gamma = Vec3::Zero() - Vec3(m.deformation(0, 1), m.deformation(0, 2), m.deformation(1, 2));  // 0 - 0 = +0
  const Principal ps = principal(m.stress), pe = principal(m.strain_tensor);
  m.stress_directions = ps.directions;
  m.principal_strain = pe.values;
  m.strain_directions = pe.directions;
  m.alpha = alpha_deg(m.stress);
  m.noncoaxiality = noncoaxiality_deg(m.stress, m.strain_rate_tensor);

  // eps_v from the lengths in every case: -ln det F = -ln(V / V0), the trace of the strain tensor.
  // eps_q from the principal strains; for a diagonal deformation from the axes' strains as always.
  m.eps_v = m.strain.sum();
  m.eps_q = deviatoric_strain(cell);

  double solid = 0.0;
  for (std::size_t k = 0; k < n; ++k) solid += 4.0 / 3.0 * std::numbers::pi * p.radius[k] * p.radius[k] * p.radius[k];
  m.solid_fraction = solid / volume;
  m.void_ratio = solid > 0.0 ? volume / solid - 1.0 : 0.0;

  // Touching contacts: per-particle counts, fabric, mean contact force magnitude. Serial over the
  // pair list (an output-step cost, in a fixed order).
  std::vector<std::uint32_t> count(n, 0);
  std::vector<std::uint8_t> touching(n_pairs, 0);
  double force_sum = 0.0;
  Mat3 fabric = Mat3::Zero();
  for (std::size_t k = 0; k < n_pairs; ++k) {
    const std::uint32_t i = c.pairs.i[k], j = c.pairs.j[k];
    const Vec3 r = p.position[i] - p.position[j] - image_offset(c.pairs.image[k], cell);
    const double reach = p.radius[i] + p.radius[j];
    const double d2 = r.squaredNorm();
    if (!(d2 < reach * reach)) continue;
    touching[k] = 1;
    ++count[i];
    ++count[j];
    ++m.contacts;
    const double dist = std::sqrt(d2);
    const Vec3 nrm = r / dist;
    fabric += nrm * nrm.transpose();
    force_sum += c.forces.force[k].norm();
    const double overlap = reach - dist;
    m.max_overlap_ratio = std::max(m.max_overlap_ratio, overlap / std::min(p.radius[i], p.radius[j]));
  }
  m.elastic_energy = contact_elastic_energy(model, state);  // as the model's contact laws store it
  if (m.contacts > 0) m.fabric = fabric / static_cast<double>(m.contacts);
  m.z = n > 0 ? 2.0 * static_cast<double>(m.contacts) / static_cast<double>(n) : 0.0;

  // Mechanical coordination: rattlers (< 2 contacts) and their contacts removed; removing one can
  // make a neighbour a rattler, so removal propagates (a work list over a per-particle contact index).
  std::vector<std::uint32_t> start(n + 1, 0), entry(2 * m.contacts);
  for (std::size_t k = 0; k < n; ++k) start[k + 1] = start[k] + count[k];
  {
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    for (std::size_t q = 0; q < n_pairs; ++q)
      if (touching[q]) {
        entry[fill[c.pairs.i[q]]++] = static_cast<std::uint32_t>(q);
        entry[fill[c.pairs.j[q]]++] = static_cast<std::uint32_t>(q);
      }
  }
  std::vector<std::uint8_t> rattler(n, 0);
  std::vector<std::uint32_t> work;
  for (std::size_t k = 0; k < n; ++k)
    if (count[k] < 2) {
      rattler[k] = 1;
      work.push_back(static_cast<std::uint32_t>(k));
    }
  std::size_t kept_contacts = m.contacts;
  while (!work.empty()) {
    const std::uint32_t k = work.back();
    work.pop_back();
    for (std::uint32_t e = start[k]; e < start[k + 1]; ++e) {
      const std::uint32_t q = entry[e];
      if (!touching[q]) continue;
      touching[q] = 0;
      --kept_contacts;
      const std::uint32_t other = c.pairs.i[q] == k ? c.pairs.j[q] : c.pairs.i[q];
      if (--count[other] < 2 && !rattler[other]) {
        rattler[other] = 1;
        work.push_back(other);
      }
    }
  }
  std::size_t kept_particles = 0;
  for (std::size_t k = 0; k < n; ++k) {
    m.rattlers += rattler[k];
    kept_particles += !rattler[k];
  }
  m.z_mech = kept_particles > 0 ? 2.0 * static_cast<double>(kept_contacts) / static_cast<double>(kept_particles) : 0.0;

  double net = 0.0, kinetic = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    net += p.force[k].norm();
    kinetic +=
        0.5 * p.mass[k] * p.velocity[k].squaredNorm() + 0.5 * p.angular_velocity[k].squaredNorm() / p.inv_inertia[k];
  }
  m.kinetic_energy = kinetic;
  m.unbalanced = force_sum > 0.0 ? (net / static_cast<double>(n)) / (force_sum / static_cast<double>(m.contacts)) : 0.0;

  if (options.d50 > 0.0 && options.density > 0.0 && m.inv.p > 0.0) {
    // gamma_dot = eps_dot_1 - eps_dot_3 of the principal strain rates: largest minus smallest (a
    // shearing cell's from the tensor: in simple shear, the engineering rate itself).
    const Vec3 rates = cell.shear_rate.isZero(0.0) ? m.strain_rate : principal(m.strain_rate_tensor).values;
    const double shear_rate = rates.maxCoeff() - rates.minCoeff();
    m.inertial_number = shear_rate * options.d50 * std::sqrt(options.density / m.inv.p);
    m.inertial_number_axial = std::abs(m.strain_rate[0]) * options.d50 * std::sqrt(options.density / m.inv.p);
  }
  return m;
}

}  // namespace sandcell
