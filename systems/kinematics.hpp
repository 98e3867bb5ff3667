#pragma once
// Tensor kinematic measures of the cell and of stress and strain tensors: pure functions, no
// state, used by measure() (systems/homogenizer.hpp) and bound in Python.
//
// Conventions (docs/physics.md sections 1 and 5): soil convention, compression positive, for every
// strain and strain rate returned here; the cell's deformation gradient F = H N H0^-1
// (Cell::deformation) and velocity gradient L (Cell::velocity_gradient) are the engine's own,
// tension positive. Angles are in degrees.
//
// Why separate functions and not a part of measure(): the analysis of a rotation or simple-shear
// test (alpha, non-coaxiality between a stress and a strain increment of two rows) needs them on
// tensors measure() never sees together; one implementation serves both.
//
// An orthorhombic cell's F is diagonal: then log_strain and cell_strain take the diagonal path,
// -ln(F_kk) per axis, with no eigen-decomposition, so the measures of a cell that never sheared keep
// the bits they had before the cell could shear.
#include "components/cell.hpp"

namespace sandcell {

/// Principal values and directions of a symmetric 3x3 tensor.
struct Principal {
  Vec3 values = Vec3::Zero();          // descending: values[0] >= values[1] >= values[2]
  Mat3 directions = Mat3::Identity();  // column k: unit direction of values[k], its largest-magnitude
                                       // component positive (the first such component on a tie)
};

/// The principal values (descending) and unit directions of sym (symmetrized first, (A + A^T)/2,
/// which leaves a symmetric input unchanged). A diagonal tensor is taken exactly: its diagonal
/// sorted, ties in axis order, directions the unit axes. Otherwise Eigen's self-adjoint solver
/// (Householder tridiagonalization and implicit QL: values to ~1e-16 of the largest |value|).
/// Directions of equal values are any orthonormal basis of their eigenspace.
Principal principal(const Mat3& sym);

/// The logarithmic (Hencky) strain of a deformation gradient F (det F > 0), compression positive:
///   eps = -ln V,  V = sqrt(F F^T)  (the left stretch: F = V R, R a rotation).
/// From the eigen-decomposition F F^T = Q diag(mu_k) Q^T: eps = -Q diag(ln(mu_k) / 2) Q^T. The
/// solver works on F F^T - I = G + G^T + G G^T, G = F - I, and takes log1p of its eigenvalues, so a
/// small strain keeps its relative precision (F F^T itself would round 1 + g^2 to 1 below g ~ 1e-8).
/// A diagonal F is taken exactly: eps = diag(-ln F_kk).
/// Frame: eps(F R) = eps(F) for any rotation R (the reference rotated: V unchanged);
/// eps(R F) = R eps(F) R^T (the current configuration rotated).
Mat3 log_strain(const Mat3& f);

/// Whether the cell's deformation since its reference is diagonal (no tilt now or in the
/// reference, no flip): then F = diag(L_k / L0_k).
inline bool diagonal_deformation(const Cell& cell) {
  return cell.tilt.isZero(0.0) && cell.tilt0.isZero(0.0) && cell.flip.isZero(0.0);
}

/// The cell's logarithmic strain since its reference, compression positive: diag(-ln(L_k / L0_k))
/// for a diagonal deformation (bitwise Measures::strain), else log_strain(cell.deformation()).
Mat3 cell_strain(const Cell& cell);

/// The cell's deviatoric strain eps_q = sqrt(2)/3 sqrt((e1-e2)^2 + (e2-e3)^2 + (e3-e1)^2), e_k the
/// axes' strains -ln(L_k / L0_k) for a diagonal deformation, else the principal values of
/// cell_strain. Measures::eps_q is this value bitwise; the app stops a test on it
/// (shear.max_deviatoric_strain) and tests critical state over a window of it.
double deviatoric_strain(const Cell& cell);

/// The strain rate tensor of a velocity gradient L (tension positive), compression positive:
/// -D = -(L + L^T)/2. Its diagonal is -L_kk exactly; for the cell's upper triangular L its
/// off-diagonal is -L_ab / 2 (the engineering rate gamma_dot_ab = -L_ab, halved).
Mat3 strain_rate_tensor(const Mat3& l);

/// The angle, degrees in [0, 54.74], between the major principal direction of sym and the nearest
/// of the axes x, y, z: atan2(|v_perp|, |v_k|), v_k the direction's largest component (atan2, not
/// acos, keeps small angles exact). For a turn by a <= 45 degrees in the sigma1-sigma3 plane it
/// equals the watchdog's principal_rotation_deg (systems/path_watch.hpp), which is taken from the
/// shear stresses and reads 0 below a minimum deviator; this one is defined for any tensor whose
/// largest principal value is distinct.
double axes_rotation_deg(const Mat3& sym);

/// The rotation path's alpha: the angle, degrees in (-90, 90], of the major principal direction of
/// the xz block of sym, from x toward z:
///   alpha = atan2(2 S_xz, S_xx - S_zz) / 2
/// (exact for rotated_stress(p, b, q, alpha) of systems/stress_paths.hpp, whose sigma2 stays on y).
/// 0 for an isotropic xz block.
double alpha_deg(const Mat3& sym);

/// The angle, degrees in [0, 90], between the major principal directions of a stress and of a
/// strain increment (or strain rate), both compression positive: atan2(|a x b|, |a . b|). 0 when
/// either tensor is isotropic (all three principal values equal, e.g. zero); where a largest value
/// is repeated (s1 = s2) its direction is any in a plane, and so is the angle.
double noncoaxiality_deg(const Mat3& stress, const Mat3& strain_increment);

}  // namespace sandcell
