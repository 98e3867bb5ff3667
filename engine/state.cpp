#include "engine/state.hpp"

#include "engine/assert.hpp"
#include "engine/fnv1a.hpp"

#include <numbers>
#include <string>

namespace sandcell {

std::size_t add_sphere(State& state, const Model& model, ParticleId id, const Vec3& position, double radius,
                       std::uint32_t material) {
  SANDCELL_CHECK(material < model.materials.size(), "material index " + std::to_string(material) +
                                                        " out of range (have " +
                                                        std::to_string(model.materials.size()) + ")");
  SANDCELL_CHECK(radius > 0.0, "radius must be > 0, got " + std::to_string(radius));
  Particles& p = state.particles;
  const std::size_t k = p.size();
  resize(p, k + 1);
  const double mass = model.materials[material].density * 4.0 / 3.0 * std::numbers::pi * radius * radius * radius;
  p.id[k] = id;
  p.position[k] = position;
  p.velocity[k].setZero();
  p.angular_velocity[k].setZero();
  p.force[k].setZero();
  p.torque[k].setZero();
  p.radius[k] = radius;
  p.mass[k] = mass;
  p.inv_inertia[k] = 1.0 / (0.4 * mass * radius * radius);
  p.material[k] = material;
  return k;
}

std::uint64_t particle_digest(const State& s) {
  Fnv1a f;
  f.array(s.particles.id);
  f.array(s.particles.position);
  f.array(s.particles.velocity);
  f.array(s.particles.angular_velocity);
  f.bytes(s.cell.length.data(), sizeof(double) * 3);
  if (!s.cell.plain()) {
    f.bytes(s.cell.tilt.data(), sizeof(double) * 3);
    f.bytes(s.cell.flip.data(), sizeof(double) * 3);
  }
  f.bytes(&s.clock.step, sizeof s.clock.step);
  f.bytes(&s.clock.time, sizeof s.clock.time);
  return f.h;
}

}  // namespace sandcell
