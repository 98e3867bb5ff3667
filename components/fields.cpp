#include "components/fields.hpp"

#include <cstring>
#include <vector>

namespace sandcell {

std::string_view component_name(Component c) {
  switch (c) {
    case Component::particle_id: return "particle_id";
    case Component::particle_position: return "particle_position";
    case Component::particle_velocity: return "particle_velocity";
    case Component::particle_angular_velocity: return "particle_angular_velocity";
    case Component::particle_force: return "particle_force";
    case Component::particle_torque: return "particle_torque";
    case Component::particle_radius: return "particle_radius";
    case Component::particle_mass: return "particle_mass";
    case Component::particle_inv_inertia: return "particle_inv_inertia";
    case Component::particle_material: return "particle_material";
    case Component::particle_reference: return "particle_reference";
    case Component::contact_pairs: return "contact_pairs";
    case Component::contact_forces: return "contact_forces";
    case Component::contact_tangential: return "contact_tangential";
    case Component::contact_rolling: return "contact_rolling";
    case Component::cell: return "cell";
    case Component::gather_index: return "gather_index";
    case Component::pair_constants: return "pair_constants";
    case Component::halo: return "halo";
    case Component::stress: return "stress";
    case Component::stress_blocks: return "stress_blocks";
    case Component::count: break;
  }
  return "unknown";
}

void resize(Particles& p, std::size_t n) {
  for_each_particle_field(p, [n](const FieldInfo&, auto& v) { v.resize(n); });
}

void resize(Contacts& c, std::size_t m) {
  for_each_contact_field(c, [m](const FieldInfo&, auto& v) { v.resize(m); });
}

void reorder(Particles& p, std::span<const std::uint32_t> order) {
  for_each_particle_field(p, [order](const FieldInfo&, auto& v) {
    auto old = v;
    for (std::size_t k = 0; k < order.size(); ++k) v[k] = old[order[k]];
  });
}

namespace {
// Byte-wise equality: distinguishes -0.0 from +0.0 and compares NaN payloads, as a bitwise
// determinism check must.
template <class T>
bool bitwise_equal(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

template <class Walk, class S>
std::string_view first_difference_impl(Walk walk, const S& a, const S& b) {
  // Collect b's arrays in registry order, then walk a and compare pairwise.
  std::vector<const void*> bs;
  walk(b, [&](const FieldInfo&, const auto& v) { bs.push_back(&v); });
  std::string_view diff;
  std::size_t k = 0;
  walk(a, [&](const FieldInfo& info, const auto& v) {
    using V = std::remove_cvref_t<decltype(v)>;
    if (diff.empty() && (k >= bs.size() || !bitwise_equal(v, *static_cast<const V*>(bs[k])))) diff = info.name;
    ++k;
  });
  if (diff.empty() && k != bs.size()) diff = "(allocated field set)";
  return diff;
}
}  // namespace

std::string_view first_difference(const Particles& a, const Particles& b) {
  return first_difference_impl([](const Particles& p, auto&& fn) { for_each_particle_field(p, fn); }, a, b);
}

std::string_view first_difference(const Contacts& a, const Contacts& b) {
  if (a.has_rolling != b.has_rolling) return "rolling (allocated in one only)";
  if (a.has_tangential_radius != b.has_tangential_radius) return "tangential_radius (allocated in one only)";
  return first_difference_impl([](const Contacts& c, auto&& fn) { for_each_contact_field(c, fn); }, a, b);
}

}  // namespace sandcell
