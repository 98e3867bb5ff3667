#pragma once
// Particle component: structure of arrays, one entry per sphere, all of length size().
// Arrays may be reordered (spatial sorting) at sync points; `id` is the stable identity.
// Each array: (shape) units; the system that writes it during a step.
#include "components/types.hpp"

#include <vector>

namespace sandcell {

struct Particles {
  std::vector<ParticleId> id;            // (n) -; set at creation, never written by a system
  std::vector<Vec3> position;            // (n,3) m; drifted by integrate_initial, wrapped into [0, L_k) by
                                         // the broadphase at each list build (or by wrap, without contacts)
  std::vector<Vec3> velocity;            // (n,3) m/s, fluctuating part v~ (total = v~ + D x); integrate_*
  std::vector<Vec3> angular_velocity;    // (n,3) rad/s; written by integrate_*
  std::vector<Vec3> force;               // (n,3) N, sum of contact forces; written by the force gather
  std::vector<Vec3> torque;              // (n,3) N m, sum of contact torques; written by the force gather
  std::vector<double> radius;            // (n) m; constant
  std::vector<double> mass;              // (n) kg; constant
  std::vector<double> inv_inertia;       // (n) 1/(kg m^2), 1 / (2/5 m R^2); constant
  std::vector<std::uint32_t> material;   // (n) index into Model::materials; constant
  std::vector<Vec3> reference_position;  // (n,3) m, position at the last neighbour-list build; broadphase

  std::size_t size() const { return id.size(); }
};

}  // namespace sandcell
