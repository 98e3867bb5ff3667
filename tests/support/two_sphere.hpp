#pragma once
// Two equal spheres colliding in the middle of a large periodic cell, no gravity, no rotation at
// start: sphere 0 at c - (R + gap/2) e_x moving at (+v_n/2, 0, +v_t/2), sphere 1 mirrored. The
// scene of the contact-law tests and of experiments/2026-11-25-hooke-vs-liggghts (tests/tools/two_sphere.cpp).
#include "engine/model.hpp"
#include "engine/state.hpp"

#include <string>

namespace sandcell::test {

struct TwoSphere {
  double radius = 1e-3;      // m
  double density = 2650.0;   // kg/m^3
  double young = 70e9;       // Pa
  double poisson = 0.3;      // -
  double restitution = 0.5;  // -
  double friction = 0.5;     // -
  double v_n = 0.1;          // m/s, normal approach speed
  double v_t = 0.0;          // m/s, tangential relative speed
  double v_char = 0.1;       // m/s, hooke's characteristic velocity
  double dt = 1e-7;          // s
  double gap = 0.0;          // m, surface gap at start
  std::string normal = "hooke";
  TangentialModel tangential = TangentialModel::history;
};

inline Model two_sphere_model(const TwoSphere& s) {
  Model model;
  model.dt = s.dt;
  Material mat;
  mat.density = s.density;
  mat.young = s.young;
  mat.poisson = s.poisson;
  mat.restitution = s.restitution;
  mat.friction = s.friction;
  mat.rolling_friction = 0.0;
  model.materials.push_back(mat);
  model.contact.normal = s.normal;
  if (s.normal == "hooke") model.contact.parameters["characteristic_velocity"] = s.v_char;
  model.contact.rolling = RollingModel::none;
  model.contact.tangential = s.tangential;
  model.contact.skin = 0.2 * s.radius;
  return model;
}

/// The centre of the cell: positions are reported relative to it.
inline double two_sphere_centre(const TwoSphere& s) { return 20.0 * s.radius; }

inline State two_sphere_state(const Model& model, const TwoSphere& s) {
  State state;
  const double c = two_sphere_centre(s);
  state.cell.length = state.cell.length0 = Vec3::Constant(2.0 * c);
  const double x = s.radius + 0.5 * s.gap;
  add_sphere(state, model, 0, Vec3(c - x, c, c), s.radius, 0);
  add_sphere(state, model, 1, Vec3(c + x, c, c), s.radius, 0);
  state.particles.velocity[0] = Vec3(0.5 * s.v_n, 0.0, 0.5 * s.v_t);
  state.particles.velocity[1] = Vec3(-0.5 * s.v_n, 0.0, -0.5 * s.v_t);
  return state;
}

}  // namespace sandcell::test
