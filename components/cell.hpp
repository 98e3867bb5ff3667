#pragma once
// The periodic cell (docs/physics.md section 1): its edge vectors are the columns of an upper
// triangular H, as in LAMMPS's triclinic box,
//
//       | L1  xy  xz |        a = (L1, 0, 0), b = (xy, L2, 0), c = (xz, yz, L3),
//   H = |  0  L2  yz |        volume V = L1 L2 L3, an image n sits at H n,
//       |  0   0  L3 |
//
// and its velocity gradient L is upper triangular too (dH/dt = L H keeps H so): the diagonal
// `rate` (D_kk, as for an orthorhombic cell) and `shear_rate` = (L_xy, L_xz, L_yz). An upper
// triangular L is a symmetric stretching D plus the spin that keeps the cell's a edge on x and its
// b edge in the xy plane: L_xy = 2 D_xy, and so on (the rigid rotation removed, docs/physics.md).
// H is the lattice basis the images, the wrap and the bins use; the broadphase reduces its tilts
// to |xy| <= L1/2, |xz| <= L1/2, |yz| <= L2/2 at list builds (a flip: another basis of the same
// lattice, LAMMPS's box flip), counting the flips in `flip` so that the deformation since the
// reference, F = H N H0^-1 with N = unit upper triangular (flip), stays continuous.
// A cell with zero tilts and zero shear rate is orthorhombic: every system then takes the same
// arithmetic as before the cell could shear (bitwise the same results).
// Written by integrate_initial (lengths, tilts), the broadphase (flips) and the servo (rates).
#include "components/types.hpp"

namespace sandcell {

struct Cell {
  Vec3 length = Vec3::Ones();          // (3) m, diagonal of H (L1, L2, L3); written by integrate_initial
  Vec3 tilt = Vec3::Zero();            // (3) m, (xy, xz, yz) of H, the lattice basis (reduced at flips)
  Vec3 length0 = Vec3::Ones();         // (3) m, reference diagonal H0 (strains count from it)
  Vec3 tilt0 = Vec3::Zero();           // (3) m, reference tilts of H0
  Vec3 flip = Vec3::Zero();            // (3) -, integers (n_xy, n_xz, n_yz) of N: the deformation H N
  Vec3 rate = Vec3::Zero();            // (3) 1/s, L_kk = dL_k/dt / L_k; written by the servo or set by a stage
  Vec3 shear_rate = Vec3::Zero();      // (3) 1/s, (L_xy, L_xz, L_yz) of the velocity gradient
  Vec3 servo_integral = Vec3::Zero();  // (3) s, time integral of the servo's normalized stress error per
                                       // axis (the I of its PI law); written by the servo, reset per stage
  Vec3 shear_integral = Vec3::Zero();  // (3) s, the same for the shear components xy, xz, yz

  double volume() const { return length.prod(); }
  /// Whether the cell is orthorhombic and stays so this step: zero tilts and zero shear rate.
  bool orthorhombic() const { return tilt.isZero(0.0) && shear_rate.isZero(0.0); }
  /// Whether the cell, its reference, its flips and its shear servo are all those of an
  /// orthorhombic cell (what a file need not record).
  bool plain() const { return orthorhombic() && tilt0.isZero(0.0) && flip.isZero(0.0) && shear_integral.isZero(0.0); }
  /// The lattice basis H.
  Mat3 h() const { return upper(length, tilt); }
  /// The reference H0.
  Mat3 h0() const { return upper(length0, tilt0); }
  /// N, the unit upper triangular integer matrix of the flips: H N is the continuous deformation.
  Mat3 flips() const { return upper(Vec3::Ones(), flip); }
  /// F = H N H0^-1, the deformation gradient since the reference (docs/physics.md section 1).
  Mat3 deformation() const { return h() * flips() * h0().inverse(); }
  /// The velocity gradient L (tension positive).
  Mat3 velocity_gradient() const { return upper(rate, shear_rate); }
  /// Distances between opposite faces, V / |b x c|, V / |c x a|, V / |a x b| (= L for an orthorhombic cell).
  Vec3 widths() const {
    if (tilt.isZero(0.0)) return length;
    const Mat3 m = h();
    const Vec3 a = m.col(0), b = m.col(1), c = m.col(2);
    const double v = volume();
    return Vec3(v / b.cross(c).norm(), v / c.cross(a).norm(), v / a.cross(b).norm());
  }
  double min_width() const { return widths().minCoeff(); }

  static Mat3 upper(const Vec3& diagonal, const Vec3& t) {
    Mat3 m;
    m << diagonal[0], t[0], t[1], 0.0, diagonal[1], t[2], 0.0, 0.0, diagonal[2];
    return m;
  }
};

/// The shear components in the order of tilt, shear_rate and the servo's shear settings: their
/// names, and the (row, column) of the stress or strain tensor each is.
inline constexpr const char* k_shear_names[3] = {"xy", "xz", "yz"};
inline constexpr int k_shear_row[3] = {0, 0, 1}, k_shear_col[3] = {1, 2, 2};

/// H n for an orthorhombic cell: the shift of a periodic image n, m.
inline Vec3 image_offset(const Image& n, const Vec3& length) {
  return Vec3(n[0] * length[0], n[1] * length[1], n[2] * length[2]);
}

/// H n for any cell. With zero tilts it is bitwise image_offset(n, length): each tilt term adds a
/// signed zero, which leaves any sum unchanged.
inline Vec3 image_offset(const Image& n, const Cell& cell) {
  const Vec3& l = cell.length;
  const Vec3& t = cell.tilt;
  return Vec3(n[0] * l[0] + n[1] * t[0] + n[2] * t[1], n[1] * l[1] + n[2] * t[2], n[2] * l[2]);
}

/// Reduced (fractional) coordinates s = H^-1 x of the upper triangular basis (x = H s).
inline Vec3 reduced(const Vec3& x, const Vec3& length, const Vec3& tilt) {
  const double s2 = x[2] / length[2];
  const double s1 = (x[1] - tilt[2] * s2) / length[1];
  const double s0 = (x[0] - tilt[0] * s1 - tilt[1] * s2) / length[0];
  return Vec3(s0, s1, s2);
}

/// x = H s.
inline Vec3 unreduced(const Vec3& s, const Vec3& length, const Vec3& tilt) {
  return Vec3(length[0] * s[0] + tilt[0] * s[1] + tilt[1] * s[2], length[1] * s[1] + tilt[2] * s[2], length[2] * s[2]);
}

}  // namespace sandcell
