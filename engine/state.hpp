#pragma once
// The State: everything a checkpoint must hold to continue a run bit for bit.
// Systems reach components through read<C>() / write<C>(), which check the running system's
// declared access sets (engine/access.hpp). Setup code, I/O and tests use the members directly.
#include "components/cell.hpp"
#include "components/contacts.hpp"
#include "components/fields.hpp"
#include "components/particles.hpp"
#include "engine/access.hpp"
#include "engine/model.hpp"

#include <cstdint>

namespace sandcell {

template <Component C>
struct StateField;

struct Clock {
  std::uint64_t step = 0;  // steps completed
  double time = 0.0;       // s, simulated time
  double dt = 0.0;         // s, the step in effect under an adaptive rule (Model::time_step), else 0
};

class State;
/// FNV-1a (engine/fnv1a.hpp) over the particles' ids, positions, velocities and angular velocities
/// in array order, the cell's lengths (and a shearing cell's tilts and flips) and the clock's step
/// and time: equal digests mean bitwise equal particle states. The results files' state_digest
/// column (`triaxial verify` compares it row by row).
std::uint64_t particle_digest(const State& state);

class State {
 public:
  Particles particles;
  Contacts contacts;
  Cell cell;
  Clock clock;

  template <Component C>
  const auto& read() const {
    check_access(C, false);
    return StateField<C>::get(*this);
  }
  template <Component C>
  auto& write() {
    check_access(C, true);
    return StateField<C>::get(*this);
  }
};

#define SANDCELL_STATE_FIELD(COMPONENT, MEMBER) \
  template <>                                   \
  struct StateField<Component::COMPONENT> {     \
    template <class S>                          \
    static auto& get(S& s) {                    \
      return s.MEMBER;                          \
    }                                           \
  };

SANDCELL_STATE_FIELD(particle_id, particles.id)
SANDCELL_STATE_FIELD(particle_position, particles.position)
SANDCELL_STATE_FIELD(particle_velocity, particles.velocity)
SANDCELL_STATE_FIELD(particle_angular_velocity, particles.angular_velocity)
SANDCELL_STATE_FIELD(particle_force, particles.force)
SANDCELL_STATE_FIELD(particle_torque, particles.torque)
SANDCELL_STATE_FIELD(particle_radius, particles.radius)
SANDCELL_STATE_FIELD(particle_mass, particles.mass)
SANDCELL_STATE_FIELD(particle_inv_inertia, particles.inv_inertia)
SANDCELL_STATE_FIELD(particle_material, particles.material)
SANDCELL_STATE_FIELD(particle_reference, particles.reference_position)
SANDCELL_STATE_FIELD(contact_pairs, contacts.pairs)
SANDCELL_STATE_FIELD(contact_forces, contacts.forces)
SANDCELL_STATE_FIELD(contact_tangential, contacts.tangential)
SANDCELL_STATE_FIELD(contact_rolling, contacts.rolling)
SANDCELL_STATE_FIELD(cell, cell)
#undef SANDCELL_STATE_FIELD

/// Appends one sphere with the given id, position, radius and material (mass and inertia from the
/// material density), at rest. Returns its array index.
std::size_t add_sphere(State& state, const Model& model, ParticleId id, const Vec3& position, double radius,
                       std::uint32_t material);

}  // namespace sandcell
