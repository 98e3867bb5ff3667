#pragma once
// Contact component: the persistent pair list (candidate pairs within the neighbour skin) and the
// per-pair history that a restart must carry. Each pair is listed once, with id_i < id_j, in a
// canonical order: by the array index of i, then (id_j, image); history is keyed by
// (id_i, id_j, image). Each pair owns its force slots, so the contact law writes
// without atomics and the per-particle gather sums in a fixed order.
// Each array: (shape) units; the system that writes it.
#include "components/types.hpp"

#include <vector>

namespace sandcell {

struct ContactPairs {
  std::vector<ParticleId> id_i, id_j;    // (m) -, id_i < id_j; written by the broadphase
  std::vector<Image> image;              // (m,3) -, j is taken at x_j + H n; written by the broadphase
  std::vector<std::uint32_t> i, j;       // (m) -, current array indices of id_i, id_j; broadphase / reorder
  Vec3 reference_length = Vec3::Zero();  // (3) m, cell lengths at the last build (zero: never built)
  Vec3 reference_tilt = Vec3::Zero();    // (3) m, cell tilts (xy, xz, yz) at the last build

  std::size_t size() const { return id_i.size(); }
};

struct ContactForces {
  std::vector<Vec3> force;     // (m,3) N, force on i (on j: minus it); written by the contact law
  std::vector<Vec3> torque_i;  // (m,3) N m, torque on i; written by the contact law and rolling
  std::vector<Vec3> torque_j;  // (m,3) N m, torque on j; written by the contact law and rolling
};

struct Contacts {
  ContactPairs pairs;
  ContactForces forces;
  std::vector<Vec3> tangential;  // (m,3) m (or N, incremental form): tangential history; contact law
  std::vector<Vec3> rolling;     // (m,3) N m, rolling moment history; rolling system. Empty when
                                 // the scene has no rolling resistance.
  bool has_rolling = false;      // whether `rolling` is allocated
  std::vector<double> tangential_radius;  // (m) m, contact radius at the last step (tangential law
                                          // mindlin_rescale); empty for the other laws
  bool has_tangential_radius = false;     // whether `tangential_radius` is allocated

  std::size_t size() const { return pairs.size(); }
};

}  // namespace sandcell
