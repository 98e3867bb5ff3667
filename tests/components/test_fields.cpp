// The field registry: complete, and driving resize / reorder / bitwise comparison.
#include "components/fields.hpp"
#include "support/scenes.hpp"

#include <doctest/doctest.h>

#include <cmath>

using namespace sandcell;

TEST_CASE("the registry lists every particle and contact array") {
  // Every member of these components is a std::vector; if a field is added to the struct but not
  // to the registry, the counts below disagree and this test fails.
  std::size_t particle_fields = 0;
  Particles p;
  for_each_particle_field(p, [&](const FieldInfo&, auto&) { ++particle_fields; });
  CHECK(sizeof(Particles) == particle_fields * sizeof(std::vector<double>));

  Contacts c;
  c.has_rolling = true;
  std::size_t contact_fields = 0;
  for_each_contact_field(c, [&](const FieldInfo&, auto&) { ++contact_fields; });
  // ContactPairs also holds the reference cell lengths and tilts of the last build (two Vec3, not arrays).
  CHECK(sizeof(ContactPairs) - 2 * sizeof(Vec3) + sizeof(ContactForces) + 2 * sizeof(std::vector<Vec3>) ==
        contact_fields * sizeof(std::vector<double>));
  c.has_rolling = false;
  std::size_t without_rolling = 0;
  for_each_contact_field(c, [&](const FieldInfo& info, auto&) {
    ++without_rolling;
    CHECK(info.name != "rolling");
  });
  CHECK(without_rolling == contact_fields - 1);
}

TEST_CASE("reorder permutes every field together and first_difference sees a single changed bit") {
  Model model;
  model.materials.push_back(Material{});
  State s = test::random_gas(model, 50, 0.1, 1e-3, 2e-3, 1.0, 10.0, 3);
  std::vector<std::uint32_t> order(50);
  for (std::uint32_t k = 0; k < 50; ++k) order[k] = (k * 17) % 50;  // 17 coprime with 50: a permutation
  Particles p = s.particles;
  reorder(p, order);
  for (std::size_t k = 0; k < 50; ++k) {
    CHECK(p.id[k] == s.particles.id[order[k]]);
    CHECK(p.position[k] == s.particles.position[order[k]]);
    CHECK(p.mass[k] == s.particles.mass[order[k]]);
  }
  CHECK(first_difference(s.particles, s.particles).empty());
  CHECK(first_difference(p, s.particles) == "id");

  Particles q = s.particles;
  q.angular_velocity[13][2] = std::nextafter(q.angular_velocity[13][2], 1e300);
  CHECK(first_difference(q, s.particles) == "angular_velocity");
  // -0.0 == +0.0 numerically, but a bitwise determinism check must tell them apart.
  Particles z = s.particles;
  z.force[0][0] = -0.0;
  CHECK(first_difference(z, s.particles) == "force");
}
