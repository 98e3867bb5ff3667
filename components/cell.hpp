#pragma once
// The periodic cell: orthorhombic, H = diag(L1, L2, L3), volume V = L1 L2 L3. Its velocity gradient
// is D = diag(rate), rate_k = (dL_k/dt) / L_k (tension positive, 1/s). Written by integrate_initial
// (lengths) and by the servo (rates).
#include "components/types.hpp"

namespace sandcell {

struct Cell {
  Vec3 length = Vec3::Ones();          // (3) m, current edge lengths L_k; written by integrate_initial
  Vec3 length0 = Vec3::Ones();         // (3) m, reference lengths for strains eps_k = -ln(L_k / L0_k)
  Vec3 rate = Vec3::Zero();            // (3) 1/s, D_kk = dL_k/dt / L_k; written by the servo or set by a stage
  Vec3 servo_integral = Vec3::Zero();  // (3) s, time integral of the servo's normalized stress error per
                                       // axis (the I of its PI law); written by the servo, reset per stage

  double volume() const { return length.prod(); }
  Mat3 h() const { return length.asDiagonal(); }
  Mat3 velocity_gradient() const { return rate.asDiagonal(); }
  double min_width() const { return length.minCoeff(); }
};

/// H n for an orthorhombic cell: the shift of a periodic image n, m.
inline Vec3 image_offset(const Image& n, const Vec3& length) {
  return Vec3(n[0] * length[0], n[1] * length[1], n[2] * length[2]);
}

}  // namespace sandcell
