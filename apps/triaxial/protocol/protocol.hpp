#pragma once
// The triaxial protocol: what the app (and the Python module, sandcell.Protocol) derives from a
// config before anything runs, and the models of its two stages. One place for the rules that
// make a run: the time steps and the servo's time unit t_s from the smallest sphere's Rayleigh
// time, the derived servo gains and integral time, the preparation's and the shear's models, the
// state a test starts from and its stress-path watchdog (docs/physics.md sections 4-6).
#include "protocol/config.hpp"

#include "engine/model.hpp"
#include "engine/packing.hpp"
#include "engine/state.hpp"
#include "systems/path_watch.hpp"
#include "systems/servo.hpp"

#include <string>
#include <vector>

namespace sandcell::triaxial {

/// A config with everything derived from it and from its sample's sizes.
struct Protocol {
  Config config;
  Packing packing;  // from sample.file (from_file), else empty: the cloud is generated per preparation
  bool from_file = false;
  std::vector<double> diameters;    // m, the sample's (the file's, or those [sample] generates)
  double r_min = 0.0, r_max = 0.0;  // m
  double d50 = 0.0;                 // m, mass-weighted median diameter (the inertial number's)
  double servo_time = 0.0;          // s, the servo's time unit: max(dt, 0.2 Rayleigh time), see derived_gain
  double prepare_dt = 0.0;          // s, time step of the preparations (prepare.dt_fraction, else the shear's)
  double prepare_servo_time = 0.0;  // s, max(prepare_dt, 0.2 Rayleigh time)
  Model base;                       // dt, material, contact settings of the shear stage
  std::vector<double> p0;           // distinct preparation stresses, in config order (ascending with prepare.chain)

  /// The p0 whose sample the preparation for p0 starts from (prepare.chain: the next lower p0), or 0
  /// when it starts from the cloud.
  double chained_from(double p0) const;
};

/// Derives the protocol of a parsed config: reads sample.file (refusing coincident spheres) or the
/// sizes [sample] generates, then the time steps and servo time units. Throws ConfigError.
Protocol make_protocol(Config config);

/// Checks the servo settings of every stage (sandcell::validate); throws ConfigError naming the config.
void validate_servos(const Protocol& protocol);

/// The servo gain derived when the config leaves it 0, 1/s: alpha (p/E*)^(2/3) / t_s,
/// E* = E / (2 (1 - nu^2)) (docs/physics.md section 6).
double derived_gain(double alpha, double p, const Material& material, double servo_time);
/// Every value a test's shear stage derives from its config (dt, the time step's rule, skin, the
/// servo's gain, integral time and units, the seed), one `key = value` line each: the run record of
/// its results file (attribute `settings`).
std::string resolved_settings(const Protocol& plan, const TestSpec& test);

/// The two stages whose servo the protocol derives.
enum class Stage { prepare, shear };

/// The servo settings derived for a stage at stress p with time unit t_s (docs/physics.md section 6):
/// gain = alpha (p/E*)^(2/3) / t_s, alpha 0.05 for the preparation (a P law: integral_time 0) and 0.1
/// for the shear (integral_time 1000 t_s). The app's stages and Python scripts take them from here.
struct DerivedServo {
  double gain;           // 1/s
  double integral_time;  // s, 0: none
};
DerivedServo derived_servo(Stage stage, double p, const Material& material, double servo_time);

/// The servo's time unit t_s = max(dt, 0.2 Rayleigh time of the smallest sphere), s.
double servo_time_unit(double dt, double r_min, const Material& material);

/// The preparation's model: isotropic stress control to p0 with the preparation's frictions and step.
Model prepare_model(const Protocol& protocol, double p0);

/// The axial rate of a test at p = p0, 1/s: shear.strain_rate, or what shear.inertial_number sets.
double axial_rate(const Protocol& protocol, double p0);

/// The shear stage's model of a test: its stress path, targets and servo (none on the strain path).
Model shear_model(const Protocol& protocol, const TestSpec& test);

/// The stress-path watchdog of a test ([watch]; systems/path_watch.hpp), its checks from the ramp's end.
PathWatch make_path_watch(const Protocol& protocol, const TestSpec& test);

/// The prepared sample made the start of a test: clock, reference lengths and servo state reset,
/// the first rates set (none on the axial axis while a ramp is due).
void start_test(const Protocol& protocol, const TestSpec& test, State& state);

/// The end of a preparation: the strains of the tests count from the prepared sample.
void finish_preparation(State& state);

/// The cyclic path of a cyclic test's model (its memory shared with every copy of the model, e.g.
/// the World's), or nullptr for the other paths.
const CyclicPath* cyclic_path(const Model& model);

/// "p0_500kPa": the tag of a p0 in file names.
std::string p0_tag(double p0);

}  // namespace sandcell::triaxial
