#pragma once
// Material constants, indexed by particles.material. Constant during a run (part of the Model).
namespace sandcell {

struct Material {
  double density = 2650.0;        // kg/m^3
  double young = 70e9;            // Pa, Young's modulus E
  double poisson = 0.3;           // -, Poisson's ratio nu
  double restitution = 0.5;       // -, normal coefficient of restitution e in (0, 1]
  double friction = 0.5;          // -, Coulomb coefficient mu
  double rolling_friction = 0.1;  // -, rolling resistance coefficient mu_r

  /// Shear modulus G = E / (2 (1 + nu)), Pa.
  double shear() const { return young / (2.0 * (1.0 + poisson)); }
};

}  // namespace sandcell
