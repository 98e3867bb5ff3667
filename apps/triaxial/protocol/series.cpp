#include "protocol/series.hpp"

#include "systems/path_watch.hpp"

#include "engine/world.hpp"

#include <cmath>
#include <string>

namespace sandcell::triaxial {

namespace {

void six(const Mat3& t, double* out) {
  const double v[6] = {t(0, 0), t(1, 1), t(2, 2), t(0, 1), t(0, 2), t(1, 2)};
  for (int k = 0; k < 6; ++k) out[k] = v[k];
}
void three(const Vec3& v, double* out) {
  for (int k = 0; k < 3; ++k) out[k] = v[k];
}
// The columns of a matrix one after another (each principal direction's x, y, z).
void nine_columns(const Mat3& t, double* out) {
  for (int k = 0; k < 9; ++k) out[k] = t(k % 3, k / 3);
}

using S = const State&;
using M = const Measures&;
// The columns of docs/physics.md section 8, in the order of the results files.
constexpr SeriesColumn k_columns[] = {
    {"time", "s", 1, [](S s, M, double, double* o) { *o = s.clock.time; }},
    {"step", "-", 1, [](S s, M, double, double* o) { *o = static_cast<double>(s.clock.step); }},
    {"dt", "s (the step in effect: fixed, or time.step = stiffness's)", 1, [](S, M m, double, double* o) { *o = m.dt; }},
    {"state_digest", "- (FNV-1a of the particle state, particle_digest: high and low 32 bits, exact)", 2,
     [](S s, M, double, double* o) {
       const std::uint64_t d = particle_digest(s);
       o[0] = static_cast<double>(d >> 32);
       o[1] = static_cast<double>(d & 0xffffffffu);
     }},
    {"strain", "- (logarithmic, compression positive)", 3, [](S, M m, double, double* o) { three(m.strain, o); }},
    {"strain_engineering", "-", 3, [](S, M m, double, double* o) { three(m.strain_engineering, o); }},
    {"strain_rate", "1/s (compression positive)", 3, [](S, M m, double, double* o) { three(m.strain_rate, o); }},
    {"stress", "Pa (xx yy zz xy xz yz, compression positive)", 6, [](S, M m, double, double* o) { six(m.stress, o); }},
    {"principal_stress", "Pa (s1 >= s2 >= s3)", 3, [](S, M m, double, double* o) { three(m.inv.principal, o); }},
    {"p", "Pa", 1, [](S, M m, double, double* o) { *o = m.inv.p; }},
    {"q", "Pa", 1, [](S, M m, double, double* o) { *o = m.inv.q; }},
    {"eta", "-", 1, [](S, M m, double, double* o) { *o = m.inv.eta; }},
    {"b", "-", 1, [](S, M m, double, double* o) { *o = m.inv.b; }},
    {"theta", "rad", 1, [](S, M m, double, double* o) { *o = m.inv.theta; }},
    {"eps_v", "-", 1, [](S, M m, double, double* o) { *o = m.eps_v; }},
    {"eps_q", "-", 1, [](S, M m, double, double* o) { *o = m.eps_q; }},
    {"e", "-", 1, [](S, M m, double, double* o) { *o = m.void_ratio; }},
    {"Z", "-", 1, [](S, M m, double, double* o) { *o = m.z; }},
    {"Z_mech", "-", 1, [](S, M m, double, double* o) { *o = m.z_mech; }},
    {"rattlers", "-", 1, [](S, M m, double, double* o) { *o = static_cast<double>(m.rattlers); }},
    {"fabric", "- (xx yy zz xy xz yz)", 6, [](S, M m, double, double* o) { six(m.fabric, o); }},
    {"kinetic_energy", "J", 1, [](S, M m, double, double* o) { *o = m.kinetic_energy; }},
    {"elastic_energy", "J", 1, [](S, M m, double, double* o) { *o = m.elastic_energy; }},
    {"max_overlap_ratio", "- (largest overlap / smaller radius)", 1,
     [](S, M m, double, double* o) { *o = m.max_overlap_ratio; }},
    {"unbalanced_force_ratio", "-", 1, [](S, M m, double, double* o) { *o = m.unbalanced; }},
    {"inertial_number", "- ((eps_dot_1 - eps_dot_3) d50 sqrt(rho/p))", 1,
     [](S, M m, double, double* o) { *o = m.inertial_number; }},
    {"inertial_number_axial", "- (eps_dot_1 d50 sqrt(rho/p): what shear.inertial_number sets)", 1,
     [](S, M m, double, double* o) { *o = m.inertial_number_axial; }},
    {"rotation", "degrees (the principal axes' turn off the cell axes, 1/2 asin(2 |tau| / (s1 - s3)))", 1,
     [](S, M m, double, double* o) { *o = principal_rotation_deg(m.stress); }},
    {"shear_ratio", "- (largest |shear stress| / p)", 1, [](S, M m, double, double* o) { *o = shear_ratio(m.stress); }},
    {"deformation", "- (F = H N H0^-1 since the test's start, row-major: xx xy xz yx yy yz zx zy zz)", 9,
     [](S s, M, double, double* o) {
       const Mat3 f = s.cell.deformation();
       for (int k = 0; k < 9; ++k) o[k] = f(k / 3, k % 3);
     }},
    {"strain_tensor", "- (logarithmic -ln sqrt(F F^T), compression positive; xx yy zz xy xz yz)", 6,
     [](S, M m, double, double* o) { six(m.strain_tensor, o); }},
    {"strain_rate_tensor", "1/s (-(L + L^T)/2, compression positive; xx yy zz xy xz yz)", 6,
     [](S, M m, double, double* o) { six(m.strain_rate_tensor, o); }},
    {"gamma", "- (engineering shear strains -(F_xy, F_xz, F_yz), compression positive)", 3,
     [](S, M m, double, double* o) { three(m.gamma, o); }},
    {"principal_strain", "- (of strain_tensor, descending)", 3,
     [](S, M m, double, double* o) { three(m.principal_strain, o); }},
    {"stress_directions", "- (unit directions of s1, s2, s3: x y z of each, row-major by principal value)", 9,
     [](S, M m, double, double* o) { nine_columns(m.stress_directions, o); }},
    {"strain_directions", "- (unit directions of the principal strains, as stress_directions)", 9,
     [](S, M m, double, double* o) { nine_columns(m.strain_directions, o); }},
    {"alpha", "degrees (sigma1's direction in the xz plane from x toward z, in (-90, 90])", 1,
     [](S, M m, double, double* o) { *o = m.alpha; }},
    {"noncoaxiality", "degrees (between the major principal directions of stress and strain rate, [0, 90])", 1,
     [](S, M m, double, double* o) { *o = m.noncoaxiality; }},
    {"cell_tilt", "m (xy xz yz of the lattice basis H, reduced by flips)", 3,
     [](S s, M, double, double* o) { three(s.cell.tilt, o); }},
    {"shear_strain_rate", "1/s (xy xz yz: the engineering rates -L_ab, compression positive)", 3,
     [](S s, M, double, double* o) { three(Vec3::Zero() - s.cell.shear_rate, o); }},
    {"wall_time", "s", 1, [](S, M, double wall, double* o) { *o = wall; }},
};

}  // namespace

std::span<const SeriesColumn> series_columns() { return k_columns; }

void append_row(ResultsFile& results, const State& state, const Measures& m, double wall) {
  double v[9];
  for (const SeriesColumn& c : k_columns) {
    c.value(state, m, wall, v);
    if (c.width == 1)
      results.append(c.name, v[0], c.units);
    else
      results.append(c.name, std::span<const double>(v, c.width), c.units);
  }
}

void check_finite(const State& state, const Measures& m) {
  const Particles& p = state.particles;
  for (std::size_t k = 0; k < p.size(); ++k) {
    const char* what = !p.position[k].allFinite()           ? "position"
                       : !p.velocity[k].allFinite()         ? "velocity"
                       : !p.angular_velocity[k].allFinite() ? "angular velocity"
                       : !p.force[k].allFinite()            ? "force"
                                                            : nullptr;
    if (what)
      throw SimulationError("step " + std::to_string(state.clock.step) + ": particle id " + std::to_string(p.id[k]) +
                            ": " + what +
                            " is not finite (the run went unstable: lower time.dt_fraction or time.safety, or the strain rate)");
  }
  if (!std::isfinite(m.inv.p) || !state.cell.length.allFinite())
    throw SimulationError("step " + std::to_string(state.clock.step) + ": cell stress or lengths are not finite");
}

}  // namespace sandcell::triaxial
