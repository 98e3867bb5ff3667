#pragma once
// Basic value types shared by every component and system.
#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstdint>

namespace sandcell {

using Vec3 = Eigen::Vector3d;  // a 3-vector in SI units; 24 bytes, no alignment requirement
using Mat3 = Eigen::Matrix3d;

/// Stable particle identifier: assigned once, never reused, survives reordering of the arrays.
using ParticleId = std::uint32_t;

/// Integer periodic image n of a pair: the partner j is taken at x_j + H n.
using Image = std::array<std::int8_t, 3>;

}  // namespace sandcell
