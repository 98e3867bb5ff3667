#pragma once
// The one registry of components and state fields.
//
// `Component` names the unit of access that systems declare in their read and write sets; the step
// graph orders systems from these declarations and the access check enforces them.
// The field visitors below list every array of the particle and contact components with its name,
// units and writer. Resizing, reordering, comparison (the determinism tests) and, later, HDF5 output
// and checkpoints all walk this one list, so a new field cannot be forgotten by one of them.
#include "components/contacts.hpp"
#include "components/particles.hpp"

#include <cstdint>
#include <span>
#include <string_view>

namespace sandcell {

enum class Component : std::uint8_t {
  particle_id,
  particle_position,
  particle_velocity,
  particle_angular_velocity,
  particle_force,
  particle_torque,
  particle_radius,
  particle_mass,
  particle_inv_inertia,
  particle_material,
  particle_reference,
  contact_pairs,
  contact_forces,
  contact_tangential,
  contact_rolling,
  cell,
  // Scratch components (rebuilt, never checkpointed).
  gather_index,
  pair_constants,
  stress,  // the homogenizer's measured stress, read by the servo in the same step
  halo,    // the owner partition's copies across its shares (systems/halo.hpp)
  stress_blocks,  // the contact pass's per-block sums of f (x) r, read by the homogenizer on servo steps
  count
};
inline constexpr std::size_t k_component_count = static_cast<std::size_t>(Component::count);
static_assert(k_component_count <= 64, "component masks are 64-bit");

std::string_view component_name(Component c);

/// Description of one state array, for generic walkers (resize, reorder, compare, I/O).
struct FieldInfo {
  std::string_view name;    // dataset name, e.g. "position"
  std::string_view units;   // SI units, "-" for dimensionless or identifiers
  std::string_view writer;  // the system that writes it during a step ("constant" if none)
  Component component;      // the access unit it belongs to
};

/// Calls fn(info, vector) for every particle array, in a fixed order.
template <class P, class Fn>
void for_each_particle_field(P& p, Fn&& fn) {
  fn(FieldInfo{"id", "-", "constant", Component::particle_id}, p.id);
  fn(FieldInfo{"position", "m", "integrate_initial, broadphase, wrap", Component::particle_position}, p.position);
  fn(FieldInfo{"velocity", "m/s", "integrate_*", Component::particle_velocity}, p.velocity);
  fn(FieldInfo{"angular_velocity", "rad/s", "integrate_*", Component::particle_angular_velocity}, p.angular_velocity);
  fn(FieldInfo{"force", "N", "force_gather", Component::particle_force}, p.force);
  fn(FieldInfo{"torque", "N m", "force_gather", Component::particle_torque}, p.torque);
  fn(FieldInfo{"radius", "m", "constant", Component::particle_radius}, p.radius);
  fn(FieldInfo{"mass", "kg", "constant", Component::particle_mass}, p.mass);
  fn(FieldInfo{"inv_inertia", "1/(kg m^2)", "constant", Component::particle_inv_inertia}, p.inv_inertia);
  fn(FieldInfo{"material", "-", "constant", Component::particle_material}, p.material);
  fn(FieldInfo{"reference_position", "m", "broadphase", Component::particle_reference}, p.reference_position);
}

/// The components of the per-contact histories below (for access declarations).
inline constexpr Component k_contact_history_components[] = {Component::contact_tangential, Component::contact_rolling};

/// Calls fn(info, vector) for every per-contact history the scene allocates, in a fixed order: the
/// arrays the contact laws keep per pair (systems/laws/), which a pair carries from one neighbour
/// list to the next.
template <class C, class Fn>
void for_each_contact_history(C& c, Fn&& fn) {
  fn(FieldInfo{"tangential", "m", "contact law", Component::contact_tangential}, c.tangential);
  if (c.has_rolling) fn(FieldInfo{"rolling", "N m", "rolling", Component::contact_rolling}, c.rolling);
  if (c.has_tangential_radius)
    fn(FieldInfo{"tangential_radius", "m", "contact law", Component::contact_tangential}, c.tangential_radius);
}

/// Calls fn(info, vector) for every contact array that the scene allocates, in a fixed order.
template <class C, class Fn>
void for_each_contact_field(C& c, Fn&& fn) {
  fn(FieldInfo{"id_i", "-", "broadphase", Component::contact_pairs}, c.pairs.id_i);
  fn(FieldInfo{"id_j", "-", "broadphase", Component::contact_pairs}, c.pairs.id_j);
  fn(FieldInfo{"image", "-", "broadphase", Component::contact_pairs}, c.pairs.image);
  fn(FieldInfo{"i", "-", "broadphase", Component::contact_pairs}, c.pairs.i);
  fn(FieldInfo{"j", "-", "broadphase", Component::contact_pairs}, c.pairs.j);
  fn(FieldInfo{"force", "N", "contact law", Component::contact_forces}, c.forces.force);
  fn(FieldInfo{"torque_i", "N m", "contact law", Component::contact_forces}, c.forces.torque_i);
  fn(FieldInfo{"torque_j", "N m", "contact law", Component::contact_forces}, c.forces.torque_j);
  for_each_contact_history(c, fn);
}

/// Resizes every particle array to n (new entries value-initialised).
void resize(Particles& p, std::size_t n);
/// Resizes every allocated contact array to m.
void resize(Contacts& c, std::size_t m);

/// Applies a permutation: new[k] = old[order[k]] for every particle array.
void reorder(Particles& p, std::span<const std::uint32_t> order);

/// Bitwise comparison of two particle sets through the registry. Returns the name of the first
/// differing field, or an empty view when all fields are bitwise identical.
std::string_view first_difference(const Particles& a, const Particles& b);
std::string_view first_difference(const Contacts& a, const Contacts& b);

}  // namespace sandcell
